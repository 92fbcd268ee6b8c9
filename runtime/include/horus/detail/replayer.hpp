// detail::Replayer: a recording fed back into its topics by a deterministic scheduler, cycle by
// cycle (SchedulerConfig::replay, docs/recording.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

namespace horus {
class RecordingReader;
}  // namespace horus

namespace horus::detail {

class TopicEndpoint;
class PoolFrames;

class Replayer {
 public:
  /// Reads `path` and opens each recorded topic except "/horus/ticks" and those in `skip` (the
  /// nodes' own outputs) in `namespace_name` (empty: the current one). Throws horus::Error naming
  /// the topic and both fingerprints when a topic carries another type than it was recorded
  /// with, and naming the file when it cannot be read.
  Replayer(const std::filesystem::path& path, const std::string& namespace_name,
           const std::set<std::string>& skip);
  ~Replayer();
  Replayer(const Replayer&) = delete;
  Replayer& operator=(const Replayer&) = delete;

  /// Publishes, in recorded order, every message the recording received before its scheduler
  /// began cycle `cycle` (every message left, once the recorded cycles are exhausted).
  void deliver_before_cycle(std::uint64_t cycle);
  std::size_t topic_count() const noexcept { return topics_.size(); }
  /// Messages published so far.
  std::size_t delivered() const noexcept { return next_; }

 private:
  struct Message {
    std::uint64_t log_time;
    TopicEndpoint* topic;
    PoolFrames* frames;  // for a pool-backed topic: makes the recorded frame again
    std::vector<std::uint8_t> data;
  };

  std::vector<std::unique_ptr<TopicEndpoint>> topics_;
  std::vector<std::unique_ptr<PoolFrames>> frames_;
  std::vector<Message> messages_;  // by log time, recorded order within one time
  std::size_t next_ = 0;
  /// The recorded start (CLOCK_REALTIME ns) of each recorded cycle's first tick.
  std::map<std::uint64_t, std::uint64_t> cycle_starts_;
};

}  // namespace horus::detail
