// A frame tree's changes as everything that carries frames out of the process takes them (the DDS
// bridge's /tf and /tf_static, the remote link, the live view, recordings): the new dynamic
// entries since the last call, oldest first per frame, and the whole static set whenever it
// changed. It follows the tree by its change counter, asleep between writes, and copies only the
// entries it has not given yet.
//
//   horus::FrameTree tree;
//   horus::TransformFeed feed(tree, [](std::string_view child) { return child != "goal"; });
//   for (;;) {
//     horus::TransformBatch batch = feed.next(std::chrono::milliseconds(100));
//     if (batch.statics) send_static_set(*batch.statics);
//     for (const horus::StampedTransform& t : batch.dynamic) send(t);
//   }
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "horus/frames.hpp"

namespace horus {

/// What changed in a tree since the feed's previous batch.
struct TransformBatch {
  /// Dynamic entries written since, each frame's oldest first, frames in the order they were
  /// first named. The first batch holds each carried dynamic frame's newest entry only.
  std::vector<StampedTransform> dynamic;
  /// Every carried static transform, when the set changed since (one was set, replaced, or
  /// became dynamic; a carried frame's static set may become empty). The first batch has it
  /// whenever the tree holds a carried static frame.
  std::optional<std::vector<StampedTransform>> statics;

  bool empty() const noexcept { return dynamic.empty() && !statics; }
};

struct TransformFeedOptions {
  /// Whether a frame's first batch (the feed's first, or the first since the frame appeared)
  /// leaves out a dynamic frame whose authority no longer runs: a carrier that set frames from
  /// elsewhere and died left them behind, and its successor must not send them out as if they
  /// were this machine's. Its newest entries follow once a live process takes the frame over.
  bool skip_dead_authorities = false;
};

class TransformFeed {
 public:
  /// Whether the feed carries a child frame's transforms (a bridge's patterns, less the frames
  /// it set itself from elsewhere); asked for each changed frame on each call.
  using Carried = std::function<bool(std::string_view child)>;

  /// Follows `tree`, which must outlive the feed. An empty `carried` carries every frame.
  explicit TransformFeed(const FrameTree& tree, Carried carried = {},
                         TransformFeedOptions options = {});

  /// Sleeps until the tree changes or `wait` passes, then returns what changed since the
  /// previous call (empty when nothing did, or when only frames it does not carry did).
  TransformBatch next(std::chrono::nanoseconds wait);
  /// What changed since the previous call, without waiting.
  TransformBatch poll();
  /// Makes the next batch a first one again (newest entries and the whole static set): for a
  /// late joiner, such as a new subscriber or a reconnected peer.
  void restart() noexcept;

  /// Entries the feed missed because a frame's writer lapped its history between two calls.
  std::uint64_t lost() const noexcept { return lost_; }

 private:
  struct Seen {
    std::string name;
    std::uint64_t updates = 0;
    bool is_static = false;
    bool carried = false;
  };

  TransformBatch collect();

  const FrameTree* tree_;
  Carried carried_;
  TransformFeedOptions options_;
  std::uint32_t change_count_ = 0;
  std::vector<Seen> seen_;
  bool first_ = true;
  std::uint64_t lost_ = 0;
};

/// Foxglove's FrameTransform: how recordings (channel "/horus/frames") and the live view show
/// frames, so Foxglove's 3D panel places every one. The schema's name and JSON Schema, one
/// transform as its JSON record, and the record read back (nullopt, with `why`, when it is not
/// one frame_transform_json() could have written).
inline constexpr std::string_view kFrameTransformSchemaName = "foxglove.FrameTransform";
std::string_view frame_transform_json_schema() noexcept;
std::string frame_transform_json(const StampedTransform& transform);
std::optional<StampedTransform> frame_transform_from_json(std::string_view record,
                                                          std::string* why = nullptr);

}  // namespace horus
