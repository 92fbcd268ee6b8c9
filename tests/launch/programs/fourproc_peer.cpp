// The C++ side of the four-process launch (tests/launch/test_launch_demo.py, fourproc.yaml):
//   fourproc_peer talk    publishes a CmdVel on "fourproc.cmd" at 50 Hz, linear = 1, 2, 3, ...
//   fourproc_peer serve   answers the service Compute with a + b
// Each prints "fourproc ROLE started at NS" (CLOCK_MONOTONIC, as Python's time.monotonic_ns()),
// so the test sees the start order, and runs until SIGINT or SIGTERM, as a launched process does.
#include <horus/horus.hpp>
#include <horus/msg/cmd_vel.hpp>
#include <horus/service.hpp>
#include <service_test/compute.hpp>

#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <string_view>

using namespace horus::literals;

namespace {

class Talker : public horus::Node {
 public:
  Talker() : cmd_("fourproc.cmd") {}
  std::string_view name() const override { return "fourproc_talker"; }
  void tick() override {
    ++sent_;
    cmd_.send(horus::msg::CmdVel::with_timestamp(static_cast<float>(sent_), 0.0f,
                                                 static_cast<std::uint64_t>(horus::now().count())));
  }

 private:
  horus::Topic<horus::msg::CmdVel> cmd_;
  std::uint64_t sent_ = 0;
};

class Adder : public horus::Node {
 public:
  std::string_view name() const override { return "fourproc_adder"; }
  // The server lives from init() to shutdown(), so its log lines carry this node's name.
  void init() override {
    server_.emplace(horus::ServiceServerBuilder<service_test::Compute>()
                        .on_request([](const service_test::ComputeRequest& request) {
                          return service_test::ComputeResponse{request.a + request.b, 0};
                        })
                        .build());
  }
  void tick() override {}
  void shutdown() override { server_.reset(); }

 private:
  std::optional<horus::ServiceServer<service_test::Compute>> server_;
};

}  // namespace

int main(int argc, char** argv) {
  const std::string_view role = argc == 2 ? argv[1] : "";
  if (role != "talk" && role != "serve") {
    std::fprintf(stderr, "usage: fourproc_peer talk|serve\n");
    return 2;
  }
  try {
    horus::Scheduler sched{
        horus::SchedulerConfig{}.name(role == "talk" ? "fourproc_talker" : "fourproc_adder")};
    if (role == "talk")
      sched.add(std::make_unique<Talker>()).rate(50_hz).build();
    else
      sched.add(std::make_unique<Adder>()).rate(10_hz).build();
    std::printf("fourproc %s started at %lld\n", role == "talk" ? "talker" : "adder",
                static_cast<long long>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                           std::chrono::steady_clock::now().time_since_epoch())
                                           .count()));
    std::fflush(stdout);
    return sched.run();
  } catch (const horus::Error& error) {
    std::fprintf(stderr, "fourproc_peer %s: %s\n", argv[1], error.what());
    return 1;
  }
}
