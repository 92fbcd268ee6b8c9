// A C++ client of dds_test.Scale for the bridge's service tests (test_bridge_service.py):
//
//   horus_dds_service_peer call   waits up to 30 s for a server, calls Scale(3, 2.5) and prints
//                                 "answer PRODUCT NOTE", or "error KIND MESSAGE"
//   horus_dds_service_peer once   calls Scale(1, 2) at once (2 s timeout) and prints the same
#include <chrono>
#include <cstdio>
#include <string>

#include <dds_test/scale.hpp>
#include <horus/service.hpp>

namespace {

using namespace std::chrono_literals;

int call(bool wait) {
  horus::ServiceClient<dds_test::Scale> client;
  if (wait && !client.wait_for_server(30s)) {
    std::fprintf(stderr, "no server came\n");
    return 1;
  }
  const auto answer = wait ? client.call(dds_test::ScaleRequest{3.0, 2.5}, 20s)
                           : client.call(dds_test::ScaleRequest{1.0, 2.0}, 2s);
  if (answer) {
    std::printf("answer %g %s\n", answer->product, answer->note.c_str());
  } else {
    std::printf("error %s %s\n", std::string(horus::to_string(answer.error().kind())).c_str(),
                answer.error().message().c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string role = argc == 2 ? argv[1] : "";
  if (role == "call" || role == "once") {
    return call(role == "call");
  }
  std::fprintf(stderr, "usage: %s call | once\n", argv[0]);
  return 2;
}
