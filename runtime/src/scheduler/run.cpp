#include "horus/run.hpp"

namespace horus {

int run(std::vector<RunNode> nodes, SchedulerConfig config,
        std::optional<std::chrono::nanoseconds> duration) {
  Scheduler scheduler(std::move(config));
  for (const RunNode& entry : nodes) scheduler.add(entry);
  return duration ? scheduler.run_for(*duration) : scheduler.run();
}

}  // namespace horus
