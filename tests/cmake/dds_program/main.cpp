// Runs a scheduler with a Network for one tick: the DDS bridge starts in this process (its first
// line on stdout) and stops with the scheduler. `dds_program DOMAIN`.
#include <cstdio>
#include <memory>
#include <string>

#include <horus/horus.hpp>

namespace {

class OneTick : public horus::Node {
 public:
  std::string_view name() const override { return "one_tick"; }
  void tick() override { request_stop(); }
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DOMAIN\n", argv[0]);
    return 2;
  }
  try {
    horus::Scheduler scheduler{
        horus::SchedulerConfig{}
            .name("dds_program")
            .network({.export_ = {"dds_program_nothing"}, .domain = std::stoi(argv[1])})};
    scheduler.add(std::make_shared<OneTick>()).build();
    const int status = scheduler.run();
    std::printf("run returned %d\n", status);
    return status;
  } catch (const horus::Error& error) {
    std::fprintf(stderr, "error: %s\n", error.what());
    return 2;
  }
}
