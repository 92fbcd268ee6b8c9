// A C++ client of dds_test.Scale for the bridge's service tests (test_bridge_service.py):
//
//   horus_dds_service_peer call   waits up to 30 s for a server, calls Scale(3, 2.5) and prints
//                                 "answer PRODUCT NOTE", or "error KIND MESSAGE"
//   horus_dds_service_peer once   calls Scale(1, 2) at once (2 s timeout) and prints the same
//   horus_dds_service_peer kinds  waits for a server, then (20 s timeouts) calls Scale(1, 99),
//                                 Scale(1, -1) (3 s later: the server is done with the first)
//                                 and Scale(1, 2) (0.5 s later), printing each result (with
//                                 test_bridge_service.py's SERVER_WITH_KINDS: a remote Timeout,
//                                 an answer that stops the server, a remote NoServer)
//   horus_dds_service_peer serve  serves Scale as peer_scripts.scale_server does (a factor of 0
//                                 fails), printing "ready", until SIGINT or SIGTERM
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <string>
#include <thread>

#include <dds_test/scale.hpp>
#include <horus/service.hpp>

namespace {

using namespace std::chrono_literals;

void print(const horus::ServiceResult<dds_test::ScaleResponse>& answer) {
  if (answer) {
    std::printf("answer %g %s\n", answer->product, answer->note.c_str());
  } else {
    std::printf("error %s %s\n", std::string(horus::to_string(answer.error().kind())).c_str(),
                answer.error().message().c_str());
  }
  std::fflush(stdout);
}

int call(bool wait) {
  horus::ServiceClient<dds_test::Scale> client;
  if (wait && !client.wait_for_server(30s)) {
    std::fprintf(stderr, "no server came\n");
    return 1;
  }
  print(wait ? client.call(dds_test::ScaleRequest{3.0, 2.5}, 20s)
             : client.call(dds_test::ScaleRequest{1.0, 2.0}, 2s));
  return 0;
}

int kinds() {
  horus::ServiceClient<dds_test::Scale> client;
  if (!client.wait_for_server(30s)) {
    std::fprintf(stderr, "no server came\n");
    return 1;
  }
  for (const double factor : {99.0, -1.0, 2.0}) {
    print(client.call(dds_test::ScaleRequest{1.0, factor}, 20s));
    if (factor == 99.0) {
      std::this_thread::sleep_for(3s);
    } else if (factor == -1.0) {
      std::this_thread::sleep_for(500ms);
    }
  }
  return 0;
}

std::atomic<bool> stopping{false};

int serve() {
  auto server =
      horus::ServiceServerBuilder<dds_test::Scale>()
          .on_request([](const dds_test::ScaleRequest& request)
                          -> horus::HandlerResult<dds_test::ScaleResponse> {
            if (request.factor == 0) {
              return std::string("a factor of 0");
            }
            char note[64];
            std::snprintf(note, sizeof note, "%g times %g", request.value, request.factor);
            return dds_test::ScaleResponse{request.value * request.factor, note};
          })
          .build();
  std::signal(SIGINT, [](int) { stopping.store(true); });
  std::signal(SIGTERM, [](int) { stopping.store(true); });
  std::printf("ready\n");
  std::fflush(stdout);
  while (!stopping.load()) {
    std::this_thread::sleep_for(50ms);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string role = argc == 2 ? argv[1] : "";
  if (role == "call" || role == "once") {
    return call(role == "call");
  }
  if (role == "kinds") {
    return kinds();
  }
  if (role == "serve") {
    return serve();
  }
  std::fprintf(stderr, "usage: %s call | once | kinds | serve\n", argv[0]);
  return 2;
}
