#include "frames_feed.hpp"

#include <algorithm>
#include <cstddef>
#include <span>

#include "protocol.hpp"

namespace horus::view {

std::string frame_policy_name(std::string_view child) { return "@frames/" + std::string(child); }

ChannelSchema frame_transform_schema() {
  return ChannelSchema{"json", std::string(kFrameTransformSchemaName), "jsonschema",
                       std::string(frame_transform_json_schema()), false};
}

namespace {

/// `transform` as its Message Data for `subscription_id`, stamped now on the view's clock.
std::shared_ptr<const EncodedMessage> encode(const StampedTransform& transform,
                                             std::uint32_t subscription_id,
                                             const ViewClock& clock) {
  const std::string record = frame_transform_json(transform);
  auto message = std::make_shared<EncodedMessage>();
  message->receive_time_ns = view_time_ns(clock);
  message->framed_for = subscription_id;
  message_data(subscription_id, message->receive_time_ns,
               std::as_bytes(std::span<const char>(record.data(), record.size())), message->framed);
  return message;
}

/// Offers each of `transforms` to those of `receivers` on the channel (`is_static`) that may read
/// its frame, encoded once for them all.
void offer_all(const std::vector<StampedTransform>& transforms, bool is_static,
               const std::vector<std::shared_ptr<Subscription>>& receivers,
               const ViewClock& clock) {
  for (const StampedTransform& transform : transforms) {
    std::shared_ptr<const EncodedMessage> message;
    for (const auto& subscription : receivers) {
      const FrameSlots& slots = *subscription->frames;
      if (slots.is_static != is_static) continue;
      if (slots.readable && !slots.readable(transform.child)) continue;
      if (!message) message = encode(transform, subscription->id, clock);
      subscription->offer_frame(transform.child, message);
    }
  }
}

}  // namespace

FramesFeed::FramesFeed(const FrameTree& tree, ViewClock clock, std::shared_ptr<Subscription> first)
    : Forwarder("horus-view: frames", nullptr),
      tree_(tree),
      clock_(std::move(clock)),
      feed_(tree),
      subscriptions_{std::move(first)} {
  start([this] { loop(); });
}

// The thread reads feed_ and the subscriptions: it ends before they go.
FramesFeed::~FramesFeed() noexcept { stop(); }

void FramesFeed::add(std::shared_ptr<Subscription> subscription) {
  {
    const std::lock_guard lock(mutex_);
    subscriptions_.push_back(subscription);
    // The thread's first batch, the whole tree, is still to be handed out: it reaches this
    // subscription too.
    if (!handed_out_) return;
  }
  // Looked at after the thread was given it: a change the thread's feed collected before the
  // subscription joined is in this state already, one after reaches it through the thread.
  TransformFeed now(tree_);
  const TransformBatch state = now.poll();
  deliver(state, {subscription});
}

void FramesFeed::remove(const Subscription* subscription) {
  const std::lock_guard lock(mutex_);
  subscriptions_.erase(std::remove_if(subscriptions_.begin(), subscriptions_.end(),
                                      [&](const auto& one) { return one.get() == subscription; }),
                       subscriptions_.end());
}

bool FramesFeed::unsubscribed() const {
  const std::lock_guard lock(mutex_);
  return subscriptions_.empty();
}

void FramesFeed::loop() {
  std::vector<std::shared_ptr<Subscription>> receivers;
  while (!stopping()) {
    const TransformBatch batch = feed_.next(kPoll);
    {
      const std::lock_guard lock(mutex_);
      handed_out_ = true;
      if (!batch.empty()) receivers = subscriptions_;
    }
    if (batch.empty()) continue;
    deliver(batch, receivers);
    // Entries a writer overwrote before the feed read them count as dropped, as a topic's do.
    if (const std::uint64_t lost = feed_.lost() - lost_seen_; lost != 0) {
      lost_seen_ = feed_.lost();
      for (const auto& subscription : receivers) {
        if (!subscription->frames->is_static) subscription->offer(nullptr, lost);
      }
    }
    receivers.clear();
  }
}

void FramesFeed::deliver(const TransformBatch& batch,
                         const std::vector<std::shared_ptr<Subscription>>& receivers) const {
  offer_all(batch.dynamic, false, receivers, clock_);
  if (batch.statics) offer_all(*batch.statics, true, receivers, clock_);
}

}  // namespace horus::view
