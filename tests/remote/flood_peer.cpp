// A peer that floods the robot with calls (tests/remote/test_resilience.py): authenticated with
// the laptop's certificate, it sends Session.topics calls as fast as it can, never waiting for
// the answers, until killed.
//
//   horus_remote_flood_peer PORT CERTS
#include <cstdio>
#include <string>

#include "link.hpp"

namespace {

class Ignore final : public kj::TaskSet::ErrorHandler {
 public:
  void taskFailed(kj::Exception&&) override {}
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: horus_remote_flood_peer PORT CERTS\n");
    return 2;
  }
  auto io = kj::setupAsyncIo();
  const auto credentials = horus::bridge::load_tls_credentials(argv[2], "laptop");
  auto tls = horus::bridge::tls_context(credentials, io.provider->getTimer(),
                                        horus::remote::kHandshakeTimeout);
  auto address = io.provider->getNetwork()
                     .parseAddress(std::string("127.0.0.1:") + argv[1])
                     .wait(io.waitScope);
  auto stream = tls->wrapClient(address->connect().wait(io.waitScope), "robot").wait(io.waitScope);
  capnp::TwoPartyClient client(*stream);
  auto session = client.bootstrap().castAs<horus::remote::wire::Session>();
  Ignore ignore;
  std::printf("flooding\n");
  std::fflush(stdout);
  for (;;) {
    kj::TaskSet answers(ignore);
    for (int i = 0; i < 10000; ++i) answers.add(session.topicsRequest().send().ignoreResult());
    // Lets the connection write what it can; the answers are dropped with the task set.
    io.provider->getTimer().afterDelay(10 * kj::MILLISECONDS).wait(io.waitScope);
  }
}
