// The namespace's frame tree as two channels, "/horus/frames" (dynamic transforms) and
// "/horus/frames_static" (the static set), each message one foxglove.FrameTransform as
// horus::frame_transform_json() writes it, so that Foxglove's 3D panel places every frame (the
// names and records a recording's export uses too). One horus::TransformFeed follows the tree for
// every subscriber, each transform encoded once and offered to the subscriptions whose client may
// read its frame.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "horus/bridge/forwarder.hpp"
#include "horus/frames.hpp"
#include "horus/transform_feed.hpp"
#include "topic_feed.hpp"

namespace horus::view {

inline constexpr std::string_view kFramesTopic = "/horus/frames";
inline constexpr std::string_view kStaticFramesTopic = "/horus/frames_static";

/// A frame's name in a policy ("alice read @frames/base_*"), as the remote link names it.
std::string frame_policy_name(std::string_view child);

/// The frames channels' schema: Foxglove's FrameTransform as JSON Schema, messages in json.
ChannelSchema frame_transform_schema();

/// Reads the tree for every client subscribed to a frames channel, on a thread of its own: the
/// tree's change counter is a futex word of its file, not a topic an io_uring TopicWatch can
/// wait on, so it is waited on with FrameTree::wait_for_change there and handed to the event loop
/// as a topic's reader thread does. Made, used and destroyed on the event loop's thread.
class FramesFeed final : public bridge::Forwarder {
 public:
  /// `tree` outlives the feed; `first`, a subscription whose `frames` is set, is served the
  /// tree as it is by the feed's first batch.
  FramesFeed(const FrameTree& tree, ViewClock clock, std::shared_ptr<Subscription> first);
  ~FramesFeed() noexcept override;

  /// Adds a subscription whose `frames` is set, and offers it the tree as it is now: the newest
  /// transform of every dynamic frame, or the whole static set (a viewer that joins late still
  /// places the static frames).
  void add(std::shared_ptr<Subscription> subscription);
  void remove(const Subscription* subscription);
  bool unsubscribed() const;

 private:
  void loop();
  /// Offers `batch` to `receivers`, each transform encoded once, only to those that may read it.
  void deliver(const TransformBatch& batch,
               const std::vector<std::shared_ptr<Subscription>>& receivers) const;

  const FrameTree& tree_;
  ViewClock clock_;
  /// The thread's.
  TransformFeed feed_;
  std::uint64_t lost_seen_ = 0;
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Subscription>> subscriptions_;
  /// Whether the thread took its first batch's receivers: a subscription added before is served
  /// by that batch, one added after is offered the tree by add() itself.
  bool handed_out_ = false;
};

}  // namespace horus::view
