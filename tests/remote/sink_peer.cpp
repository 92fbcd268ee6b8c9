// A third-party peer of the robot (tests/remote/test_link.py), reading a stream as remote.capnp
// documents it: authenticated with the laptop's certificate, it subscribes to a POD topic with
// a Sink of its own and prints, for each message, its `sequence`, the sender's `dropped` and the
// message's first 8 bytes as a u64 (a CmdVel's stamp). Each message takes it DELAY_MS to take:
// a slow peer, whose stream of at most QUEUE messages behind drops the oldest. With DUMP, the
// first message's data is written to that file (whole once it exists).
//
//   horus_remote_sink_peer PORT CERTS TOPIC QUEUE DELAY_MS [DUMP]
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <utility>

#include "link.hpp"

namespace {

class PrintingSink final : public horus::remote::wire::Sink::Server {
 public:
  PrintingSink(kj::Timer& timer, kj::Duration delay, std::string dump)
      : timer_(timer), delay_(delay), dump_(std::move(dump)) {}

 protected:
  kj::Promise<void> message(MessageContext context) override {
    const auto params = context.getParams();
    const capnp::Data::Reader data = params.getData();
    if (!dump_.empty()) {
      const std::string partial = dump_ + ".partial";
      std::ofstream(partial, std::ios::binary)
          .write(reinterpret_cast<const char*>(data.begin()),
                 static_cast<std::streamsize>(data.size()));
      std::rename(partial.c_str(), dump_.c_str());
      dump_.clear();
    }
    std::uint64_t first = 0;
    std::memcpy(&first, data.begin(), std::min(sizeof first, data.size()));
    std::printf("%llu %llu %llu\n", static_cast<unsigned long long>(params.getSequence()),
                static_cast<unsigned long long>(params.getDropped()),
                static_cast<unsigned long long>(first));
    std::fflush(stdout);
    return timer_.afterDelay(delay_);
  }

 private:
  kj::Timer& timer_;
  kj::Duration delay_;
  std::string dump_;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 6 && argc != 7) {
    std::fprintf(stderr, "usage: horus_remote_sink_peer PORT CERTS TOPIC QUEUE DELAY_MS [DUMP]\n");
    return 2;
  }
  const std::string topic = argv[3];
  auto io = kj::setupAsyncIo();
  kj::Timer& timer = io.provider->getTimer();
  const auto credentials = horus::bridge::load_tls_credentials(argv[2], "laptop");
  auto tls = horus::bridge::tls_context(credentials, timer, horus::remote::kHandshakeTimeout);
  auto address = io.provider->getNetwork()
                     .parseAddress(std::string("127.0.0.1:") + argv[1])
                     .wait(io.waitScope);
  auto stream = tls->wrapClient(address->connect().wait(io.waitScope), "robot").wait(io.waitScope);
  capnp::TwoPartyClient client(*stream);
  auto session = client.bootstrap().castAs<horus::remote::wire::Session>();
  auto listed = session.topicsRequest().send().wait(io.waitScope);
  for (const auto info : listed.getTopics()) {
    if (info.getName() != topic.c_str()) continue;
    auto request = session.subscribeRequest();
    request.setTopic(info.getName());
    request.setType(info.getType());
    request.setFingerprint(info.getFingerprint());
    request.setQueue(static_cast<std::uint32_t>(std::atoi(argv[4])));
    request.setSink(kj::heap<PrintingSink>(timer, std::atoi(argv[5]) * kj::MILLISECONDS,
                                           argc == 7 ? argv[6] : ""));
    // The stream lasts as long as the subscription is held: until killed.
    request.send()
        .then([](capnp::Response<horus::remote::wire::Session::SubscribeResults>&& subscribed) {
          return kj::Promise<void>(kj::NEVER_DONE).attach(subscribed.getSubscription());
        })
        .wait(io.waitScope);
  }
  std::fprintf(stderr, "no topic %s on the robot\n", topic.c_str());
  return 1;
}
