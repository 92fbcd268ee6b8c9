// detail::Replayer: a recording fed back into its topics by a deterministic scheduler, cycle by
// cycle (SchedulerConfig::replay, docs/recording.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "horus/recording.hpp"

namespace horus {
class PoolFrames;
}  // namespace horus

namespace horus::detail {

class TopicEndpoint;

/// The parameter values each node started with in the recording at `path` (its "/horus/params"
/// starting values), by node and parameter, as MessagePack VALUE bytes: what a replay's stores
/// start from. Throws horus::Error naming the file when it cannot be read.
std::map<std::string, std::map<std::string, std::string>> recorded_starting_params(
    const std::filesystem::path& path);

class Replayer {
 public:
  /// Reads `path` and opens each recorded topic except "/horus/ticks", "/horus/params", the
  /// frame channels, service topics and those in `skip` (the nodes' own outputs) in
  /// `namespace_name` (empty: the current one), whose frame tree gets the recorded frames of
  /// other processes (deliver_before_cycle; the nodes set their own frames again). Throws
  /// horus::Error naming the topic and both fingerprints when a topic carries another type than
  /// it was recorded with, and naming the file when it cannot be read; then it has opened none.
  Replayer(const std::filesystem::path& path, const std::string& namespace_name,
           const std::set<std::string>& skip);
  ~Replayer();
  Replayer(const Replayer&) = delete;
  Replayer& operator=(const Replayer&) = delete;

  /// Sets the recorded transforms of frames that other processes than the recording one set,
  /// and then publishes, in recorded order, the messages no recorded reader received, that are
  /// due before the scheduler begins cycle `cycle` (all of them left, once the recorded cycles
  /// are exhausted).
  void deliver_before_cycle(std::uint64_t cycle);
  /// Called just before each tick of node `node` (where the live run took its tick's `received`
  /// counts): publishes what the recorded tick of the same number of that node had been handed
  /// on its topics and has not been published yet. So the n-th tick of a node gets what its n-th
  /// tick got live, whichever cycle either fell in.
  void deliver_before_tick(std::string_view node);
  /// The same without counting a tick: an event-driven node's next tick is decided by what
  /// reached its topic.
  void deliver_ahead_of_tick(std::string_view node) { deliver_for_next_tick(node); }
  /// Called once just before each tick of node `node`: hands `apply` the recorded changes of its
  /// parameters due before this tick, in recorded order. A change recorded before cycle C is due
  /// before the node's tick of the same number as its first recorded tick in cycle C or later
  /// (after its last recorded tick when none followed): the same tick of the node sees it,
  /// whichever cycle either run reached. Changes recorded without a cycle (`horus-record -a`,
  /// from the store alone) are not replayed.
  void apply_params_before_tick(std::string_view node,
                                const std::function<void(const RecordedParamChange&)>& apply);
  std::size_t topic_count() const noexcept { return topics_.size(); }
  /// Messages published so far.
  std::size_t delivered() const noexcept { return delivered_; }

 private:
  struct Message {
    TopicEndpoint* topic;
    PoolFrames* frames;  // for a pool-backed topic: makes the recorded frame again
    std::vector<std::uint8_t> data;
    bool sent = false;
  };
  /// A node that read recorded topics: which messages are due before which of its ticks.
  struct Reader {
    std::vector<std::pair<std::uint64_t, std::size_t>> due;  // (its tick number, message)
    std::size_t next = 0;
    std::uint64_t ticks = 0;  // its ticks in this replay so far
  };

  Reader* deliver_for_next_tick(std::string_view node);
  void send(std::size_t message);
  void set_frame(const RecordedFrameChange& change);

  std::vector<std::unique_ptr<TopicEndpoint>> topics_;
  std::vector<std::unique_ptr<PoolFrames>> frames_;
  std::vector<Message> messages_;  // in recorded order
  /// The messages no recorded reader received, by the cycle they are due in.
  std::vector<std::pair<std::uint64_t, std::size_t>> unread_;
  std::size_t next_unread_ = 0;
  std::map<std::string, Reader, std::less<>> readers_;
  /// A node's recorded parameter changes, by the number of the tick they are due before.
  struct ParamChanges {
    std::vector<std::pair<std::uint64_t, RecordedParamChange>> due;
    std::size_t next = 0;
    std::uint64_t ticks = 0;  // its ticks in this replay so far
  };
  std::map<std::string, ParamChanges, std::less<>> param_changes_;
  /// The recorded transforms of frames other processes set, by the cycle they are due before.
  std::vector<std::pair<std::uint64_t, RecordedFrameChange>> frames_due_;
  std::size_t next_frame_ = 0;
  std::string namespace_;
  std::unique_ptr<FrameTree> frame_tree_;  // opened at the first transform set
  std::set<std::string> refused_frames_;   // warned about once
  std::size_t delivered_ = 0;
  bool has_ticks_ = false;
  std::uint64_t last_cycle_ = 0;  // the last recorded cycle, if any
};

}  // namespace horus::detail
