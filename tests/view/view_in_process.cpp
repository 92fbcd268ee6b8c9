// A scheduler serving its own namespace (SchedulerConfig::view()) while a node publishes CmdVel
// on "cmd_vel" at 50 Hz, until SIGTERM: `view_in_process PORT` (0: any free one). Built twice by
// tests/view/CMakeLists.txt, linked with horus::view (which prints `live view: ws://...`) and
// without it (whose scheduler refuses to be made); test_view_in_process.py runs both.
#include <cstdio>
#include <memory>
#include <string>

#include <horus/horus.hpp>
#include <horus/msg/cmd_vel.hpp>

using namespace horus::literals;

namespace {

class Commander : public horus::Node {
 public:
  Commander() : cmd_vel_("cmd_vel") {}
  std::string_view name() const override { return "commander"; }
  void tick() override {
    ++count_;
    cmd_vel_.send(horus::msg::CmdVel{.stamp_nanos = count_, .linear = 1.5f, .angular = -0.25f});
  }

 private:
  horus::Topic<horus::msg::CmdVel> cmd_vel_;
  std::uint64_t count_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s PORT\n", argv[0]);
    return 2;
  }
  try {
    horus::Scheduler scheduler{horus::SchedulerConfig{}.tick_rate(50_hz).view(
        {.port = static_cast<std::uint16_t>(std::stoi(argv[1]))})};
    scheduler.add(std::make_unique<Commander>()).build();
    return scheduler.run();
  } catch (const horus::Error& error) {
    std::fprintf(stderr, "view_in_process: %s\n", error.what());
    return 1;
  }
}
