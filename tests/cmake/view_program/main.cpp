// Runs a scheduler that serves its namespace live on any free loopback port (its `live view:
// ws://...` line on stdout) while a node publishes CmdVel, until SIGTERM.
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
  void tick() override { cmd_vel_.send(horus::msg::CmdVel{.linear = 0.5f, .angular = 0.0f}); }

 private:
  horus::Topic<horus::msg::CmdVel> cmd_vel_;
};

}  // namespace

int main() {
  try {
    horus::Scheduler scheduler{
        horus::SchedulerConfig{}.name("view_program").tick_rate(20_hz).view({.port = 0})};
    scheduler.add(std::make_unique<Commander>()).build();
    return scheduler.run();
  } catch (const horus::Error& error) {
    std::fprintf(stderr, "error: %s\n", error.what());
    return 2;
  }
}
