// TransformFeed: a frame tree's changes for the carriers of frames (horus/transform_feed.hpp).
#include "horus/transform_feed.hpp"

#include <utility>

namespace horus {

TransformFeed::TransformFeed(const FrameTree& tree, Carried carried, TransformFeedOptions options)
    : tree_(&tree), carried_(std::move(carried)), options_(options) {}

TransformBatch TransformFeed::next(std::chrono::nanoseconds wait) {
  const std::uint32_t count = tree_->change_count();
  if (!first_ && count == change_count_) tree_->wait_for_change(change_count_, wait);
  return poll();
}

TransformBatch TransformFeed::poll() {
  // Read the counter before the tree: a write after this read shows in the next call's count.
  const std::uint32_t count = tree_->change_count();
  if (!first_ && count == change_count_) return {};
  change_count_ = count;
  return collect();
}

void TransformFeed::restart() noexcept { first_ = true; }

TransformBatch TransformFeed::collect() {
  std::vector<FrameInfo> frames = tree_->frames(false);
  const auto is_carried = [&](const FrameInfo& info) {
    return !info.parent.empty() && (!carried_ || carried_(info.name));
  };
  // A dynamic frame starts (its newest entry alone) in the first batch, when it appears, and
  // when it starts being carried.
  const auto starts = [&](std::size_t i) {
    return first_ || i >= seen_.size() || !seen_[i].carried || seen_[i].is_static;
  };
  // Whether authorities live is read from /proc: only when asked, and only when a written
  // dynamic frame starts.
  bool liveness_read = false;
  if (options_.skip_dead_authorities) {
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const FrameInfo& info = frames[i];
      const bool written = i >= seen_.size() || info.updates != seen_[i].updates || first_;
      if (!info.is_static && written && starts(i) && is_carried(info)) {
        frames = tree_->frames(true);
        liveness_read = true;
        break;
      }
    }
  }
  TransformBatch batch;
  bool statics_changed = first_;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const FrameInfo& info = frames[i];
    const bool starting = starts(i);
    if (i == seen_.size()) seen_.push_back({info.name});
    Seen& seen = seen_[i];
    const bool carried = is_carried(info);
    // A frame's carriage can change (a bridge's own imports stop being carried): a frame that
    // stops counts as a change of the static set when it was a carried static one.
    if (seen.carried != carried || seen.is_static != info.is_static) {
      statics_changed =
          statics_changed || (seen.carried && seen.is_static) || (carried && info.is_static);
    }
    const bool updated = info.updates != seen.updates;
    if (carried && info.is_static && (updated || first_)) statics_changed = true;
    // Static frames are carried whoever set them.
    const bool dead_writer = liveness_read && starting && !info.is_static &&
                             info.authority_pid != 0 && !info.authority_alive;
    if (carried && !info.is_static && (updated || first_) && info.updates > 0 && !dead_writer) {
      // The first batch gives only the newest entry: a late joiner wants where frames are now.
      const std::uint64_t since = starting ? info.updates - 1 : seen.updates;
      FrameUpdates updates = tree_->history_since(info.name, since);
      if (!first_ && seen.carried && !seen.is_static) lost_ += updates.lost;
      for (StampedTransform& entry : updates.entries) batch.dynamic.push_back(std::move(entry));
      seen.updates = updates.next;
    } else {
      seen.updates = info.updates;
    }
    // A dead writer's frame is not started: it starts when a live process writes it.
    seen.carried = carried && !dead_writer;
    seen.is_static = info.is_static;
  }
  if (statics_changed) {
    std::vector<StampedTransform> statics;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      if (!seen_[i].carried || !seen_[i].is_static) continue;
      std::vector<StampedTransform> entry = tree_->history(frames[i].name);
      // A frame that became dynamic since frames() read it may give its newest entry here; the
      // next batch sees it dynamic and sends the set again without it.
      if (!entry.empty()) statics.push_back(std::move(entry.back()));
    }
    if (!statics.empty() || !first_) batch.statics = std::move(statics);
  }
  first_ = false;
  return batch;
}

}  // namespace horus
