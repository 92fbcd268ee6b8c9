// How a subscribed topic's messages reach the clients: one TopicFeed per topic (reading its
// frames, encoding each once: on the event loop, or on a thread of its own where the kernel has
// no io_uring futex waits), one Subscription per client and channel (a latest-wins slot), one
// Mailbox per client (what wakes the event loop's writer of the client's connection).
#pragma once

#include <kj/async-unix.h>
#include <kj/async.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "horus/bridge/forwarder.hpp"
#include "horus/bridge/frame_source.hpp"
#include "horus/bridge/topic_watch.hpp"
#include "horus/raw_topic.hpp"
#include "horus/topic_registry.hpp"
#include "horus/view/codecs.hpp"

namespace horus::view {

/// What a view's messages are stamped with: LiveViewOptions::clock (a scheduler's simulated
/// time, a recording's), in nanoseconds since the epoch; empty: CLOCK_REALTIME.
using ViewClock = std::function<std::int64_t()>;

/// One message of a topic, encoded once and shared by every subscriber it is offered to: framed
/// as the Message Data of one subscription id, which every client whose subscription has that id
/// (each client picks its own ids; most number theirs alike) sends as it is, with no copy.
struct EncodedMessage {
  /// When the view read it (CLOCK_REALTIME, ns): the Message Data's receive timestamp.
  std::uint64_t receive_time_ns = 0;
  /// The subscription id `framed` names.
  std::uint32_t framed_for = 0;
  /// The Message Data (protocol.hpp's message_data()): its header, then the payload.
  std::vector<std::byte> framed;

  std::span<const std::byte> payload() const noexcept;
};

using bridge::TopicWait;

/// The event loop where the kernel offers io_uring futex waits, unless HORUS_VIEW_NO_IO_URING=1
/// asks for the threads (to test them, and to compare the two). The status says which.
TopicWait topic_wait();

/// A client's wake-up: the feeds and the event loop itself say there is something to send; the
/// client's writer on the event loop waits for it. Its mutex also guards the pending messages of
/// the client's subscriptions: the writer looks at them and arms its wait under the lock, so a
/// message offered after it looked always wakes it.
class Mailbox {
 public:
  /// From a feed's thread, with mutex() not held.
  void wake();
  /// On the event loop (the writer's own messages, a feed that waits in the loop): a plain kj
  /// fulfiller, no lock and no system call.
  void wake_here();
  /// On the event loop, with mutex() held: resolves at the next wake_here(), and at the next
  /// wake() when `from_threads` (a subscription is fed by a thread).
  kj::Promise<void> armed(bool from_threads);
  std::mutex& mutex() noexcept { return mutex_; }

 private:
  std::mutex mutex_;
  kj::Own<kj::CrossThreadPromiseFulfiller<void>> waiting_;
  /// The event loop's.
  kj::Own<kj::PromiseFulfiller<void>> waiting_here_;
};

/// What a subscription to a frames channel ("/horus/frames", "/horus/frames_static",
/// frames_feed.hpp) holds besides a topic's: its messages are one transform each, so it keeps the
/// newest message of each frame rather than one in all (a dropped update of a frame is fine, a
/// frame that never arrives is not).
struct FrameSlots {
  /// Whether the client may read a child frame (its policy's "@frames/CHILD"); empty: every
  /// frame. Asked on the feed's thread and, for a new subscription, on the event loop.
  std::function<bool(const std::string& child)> readable;
  /// The static channel's: a message replaced by a newer one of its frame is not counted as
  /// dropped (the static set is sent whole again, nothing of it is lost).
  bool is_static = false;
  // Under the mailbox's mutex: the message waiting for each frame, and the frame sent last (the
  // next one after it goes first, so that a fast frame never starves a slow one).
  std::map<std::string, std::shared_ptr<const EncodedMessage>> pending;
  std::string last_sent;
};

/// A client's subscription to a channel: at most one message waits in it (one per frame for a
/// frames channel); a newer one replaces it (counted as dropped).
struct Subscription {
  Subscription(std::uint32_t subscription_id, std::uint32_t channel_id, std::string topic_name,
               std::shared_ptr<Mailbox> client_mailbox, std::chrono::nanoseconds interval,
               std::atomic<std::uint64_t>& dropped_in_all)
      : id(subscription_id),
        channel(channel_id),
        topic(std::move(topic_name)),
        mailbox(std::move(client_mailbox)),
        min_interval(interval),
        total_dropped(dropped_in_all) {}

  /// Offers `message` (from the feed's thread or loop), counting `lost` messages the feed never
  /// read and the one it replaces as dropped, and wakes the client. A null message (one the codec
  /// refused) only counts `lost`.
  void offer(std::shared_ptr<const EncodedMessage> message, std::uint64_t lost);
  /// A frames channel's offer of `child`'s newest transform (`frames` is set).
  void offer_frame(const std::string& child, std::shared_ptr<const EncodedMessage> message);
  /// Under mailbox->mutex(): whether a message waits, and the next one to send (taken out).
  bool has_pending() const noexcept;
  std::shared_ptr<const EncodedMessage> take_pending();

  const std::uint32_t id;
  const std::uint32_t channel;
  const std::string topic;
  const std::shared_ptr<Mailbox> mailbox;
  /// The client's maxRateHz as a period (0: every message).
  const std::chrono::nanoseconds min_interval;
  /// The server's count of drops over every subscription (outlives the subscription).
  std::atomic<std::uint64_t>& total_dropped;
  /// Set before the feed is given the subscription: its offers come from a thread.
  bool fed_by_thread = false;
  /// Set for a frames channel's subscription, before the feed is given it.
  std::unique_ptr<FrameSlots> frames;

  // Under mailbox->mutex():
  std::shared_ptr<const EncodedMessage> pending;
  std::uint64_t dropped = 0;
  std::uint64_t sent = 0;
  // The event loop's:
  std::chrono::steady_clock::time_point last_sent{};
  /// The Message Data being sent or sent last, of a message framed for another id: one buffer
  /// per subscription keeps the capacity of its channel's messages (an image's stays an
  /// image's).
  std::vector<std::byte> framed;
};

/// Reads one topic for every client subscribed to it: made, used and destroyed on the event
/// loop's thread, it waits on the topic in that loop (topic_wait()), or else on a thread of its
/// own; the two share everything but the wait. A new subscriber is first offered the newest
/// message the topic holds, so a topic published rarely shows at once.
class TopicFeed final : public bridge::Forwarder {
 public:
  /// `event_port`: the loop's, which watches the topic when topic_wait() says so.
  TopicFeed(std::unique_ptr<bridge::FrameSource> source, std::unique_ptr<MessageCodec> codec,
            const std::string& topic, ViewClock clock, kj::UnixEventPort& event_port);
  ~TopicFeed() noexcept override;

  /// Whether the messages come from a thread (set Subscription::fed_by_thread before add()).
  bool on_thread() const noexcept { return watch_ == nullptr; }
  void add(std::shared_ptr<Subscription> subscription);
  void remove(const Subscription* subscription);
  bool unsubscribed() const;
  /// Frames the codec refused (each also a line on stderr).
  std::uint64_t refused() const noexcept { return failures(); }

 private:
  /// The reader thread's loop.
  void loop();
  /// The event loop's: reads what is there, then waits for the watch's descriptor.
  kj::Promise<void> watch_topic();
  /// Delivers the frames waiting now; false when it stopped at the topic's capacity with more
  /// possibly there (the loop lets others run first).
  bool take_waiting();
  /// Offers the topic's newest message to the subscriptions added since the last look.
  void welcome_joined();
  /// Encodes `frame` and offers it to every subscription.
  void deliver(const bridge::Frame& frame);
  /// The frame encoded into a new message framed for `subscription_id`, or nullptr when the
  /// codec refused it.
  std::shared_ptr<const EncodedMessage> encode(std::span<const std::byte> frame,
                                               std::uint32_t subscription_id);

  std::unique_ptr<bridge::FrameSource> source_;
  std::unique_ptr<MessageCodec> codec_;
  ViewClock clock_;
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Subscription>> subscriptions_;
  /// Added since the thread last looked: offered the topic's newest message first.
  std::vector<std::shared_ptr<Subscription>> joined_;
  /// Messages encoded before, written again once nobody else holds them (the reader's own).
  static constexpr std::size_t kRecycled = 8;
  std::vector<std::shared_ptr<EncodedMessage>> recycled_;
  /// The codec's payload, before it is framed (the reader's; its capacity kept).
  std::vector<std::byte> payload_;
  /// The subscriptions a message is offered to, copied out under the lock (the reader's).
  std::vector<std::shared_ptr<Subscription>> receivers_;
  /// The event loop's wait; null where a thread reads. Destroyed in this order: the wait, the
  /// descriptor's observer, the watch, then the source it watches.
  std::unique_ptr<bridge::TopicWatch> watch_;
  std::optional<kj::UnixEventPort::FdObserver> observer_;
  kj::Promise<void> watching_ = nullptr;
};

/// CLOCK_REALTIME in nanoseconds.
std::uint64_t realtime_ns() noexcept;

/// The clock of Message Data and Time messages, LiveViewOptions::clock's or CLOCK_REALTIME.
std::uint64_t view_time_ns(const ViewClock& clock);

}  // namespace horus::view
