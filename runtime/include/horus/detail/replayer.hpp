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
#include <utility>
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

  /// Publishes, in recorded order, every message due before the scheduler begins cycle `cycle`
  /// (every message left, once the recorded cycles are exhausted).
  void deliver_before_cycle(std::uint64_t cycle);
  /// Publishes the messages due before node `node` ticks in cycle `cycle`: those that a node
  /// reading them first received in this cycle at or before the recorded tick of `node`.
  void deliver_before_tick(std::uint64_t cycle, const std::string& node);
  std::size_t topic_count() const noexcept { return topics_.size(); }
  /// Messages published so far.
  std::size_t delivered() const noexcept { return next_; }

 private:
  /// When a message is due: before the recorded tick that started at `start_ns` in `cycle` (the
  /// first tick of a node subscribed to its topic that could receive it), or, with start_ns 0,
  /// before `cycle` begins.
  struct Due {
    std::uint64_t cycle = 0;
    std::uint64_t start_ns = 0;
    auto operator<=>(const Due&) const = default;
  };
  struct Message {
    Due due;
    TopicEndpoint* topic;
    PoolFrames* frames;  // for a pool-backed topic: makes the recorded frame again
    std::vector<std::uint8_t> data;
  };

  void deliver_until(Due due);

  std::vector<std::unique_ptr<TopicEndpoint>> topics_;
  std::vector<std::unique_ptr<PoolFrames>> frames_;
  std::vector<Message> messages_;  // by when due, recorded order within one time
  std::size_t next_ = 0;
  /// The recorded start (CLOCK_REALTIME ns) of each node's tick, by cycle and node.
  std::map<std::pair<std::uint64_t, std::string>, std::uint64_t> tick_starts_;
  std::uint64_t last_cycle_ = 0;  // the last recorded cycle, if any (tick_starts_)
};

}  // namespace horus::detail
