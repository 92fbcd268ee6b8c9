#include "topic_feed.hpp"

#include <time.h>

#include <algorithm>
#include <atomic>

#include "horus/error.hpp"
#include "protocol.hpp"

namespace horus::view {

TopicWait topic_wait() {
  static const TopicWait wait = bridge::choose_topic_wait("HORUS_VIEW_NO_IO_URING");
  return wait;
}

std::span<const std::byte> EncodedMessage::payload() const noexcept {
  return std::span<const std::byte>(framed).subspan(kMessageDataHeader);
}

void Mailbox::wake() {
  const std::lock_guard lock(mutex_);
  if (waiting_) {
    waiting_->fulfill();
    waiting_ = nullptr;
  }
}

void Mailbox::wake_here() {
  if (waiting_here_) {
    waiting_here_->fulfill();
    waiting_here_ = nullptr;
  }
}

kj::Promise<void> Mailbox::armed(bool from_threads) {
  // Replaces the fulfillers of a wait the writer gave up (its timer came first).
  auto here = kj::newPromiseAndFulfiller<void>();
  waiting_here_ = kj::mv(here.fulfiller);
  if (!from_threads) {
    waiting_ = nullptr;
    return kj::mv(here.promise);
  }
  // A cross-thread fulfiller costs a lock and a write to the loop's eventfd when fulfilled: only
  // armed while a thread may need it.
  auto paf = kj::newPromiseAndCrossThreadFulfiller<void>();
  waiting_ = kj::mv(paf.fulfiller);
  return here.promise.exclusiveJoin(kj::mv(paf.promise));
}

void Subscription::offer(std::shared_ptr<const EncodedMessage> message, std::uint64_t lost) {
  const bool offered = message != nullptr;
  std::uint64_t drops = lost;
  {
    const std::lock_guard lock(mailbox->mutex());
    if (message) {
      drops += pending ? 1 : 0;
      pending = std::move(message);
    }
    dropped += drops;
  }
  if (drops != 0) total_dropped.fetch_add(drops, std::memory_order_relaxed);
  if (!offered) return;
  if (fed_by_thread) {
    mailbox->wake();
  } else {
    mailbox->wake_here();
  }
}

void Subscription::offer_frame(const std::string& child,
                               std::shared_ptr<const EncodedMessage> message) {
  bool replaced = false;
  {
    const std::lock_guard lock(mailbox->mutex());
    auto& slot = frames->pending[child];
    replaced = slot != nullptr && !frames->is_static;
    slot = std::move(message);
    if (replaced) ++dropped;
  }
  if (replaced) total_dropped.fetch_add(1, std::memory_order_relaxed);
  if (fed_by_thread) {
    mailbox->wake();
  } else {
    mailbox->wake_here();
  }
}

bool Subscription::has_pending() const noexcept {
  return frames ? !frames->pending.empty() : pending != nullptr;
}

std::shared_ptr<const EncodedMessage> Subscription::take_pending() {
  if (!frames) return std::move(pending);
  auto next = frames->pending.upper_bound(frames->last_sent);
  if (next == frames->pending.end()) next = frames->pending.begin();
  frames->last_sent = next->first;
  auto message = std::move(next->second);
  frames->pending.erase(next);
  return message;
}

TopicFeed::TopicFeed(std::unique_ptr<bridge::FrameSource> source,
                     std::unique_ptr<MessageCodec> codec, const std::string& topic, ViewClock clock,
                     kj::UnixEventPort& event_port)
    : Forwarder("horus-view: topic '" + topic + "'", nullptr),
      source_(std::move(source)),
      codec_(std::move(codec)),
      clock_(std::move(clock)) {
  if (topic_wait() == TopicWait::EventLoop) {
    try {
      watch_ = std::make_unique<bridge::TopicWatch>(source_->topic());
    } catch (const Error& error) {
      say(std::string(error.what()) + "; a reader thread waits on it instead");
    }
  }
  if (on_thread()) {
    start([this] { loop(); });
    return;
  }
  observer_.emplace(event_port, watch_->fd(), kj::UnixEventPort::FdObserver::OBSERVE_READ);
  // evalLater: the first read runs from the loop, after the subscription that made the feed.
  auto reading = kj::evalLater([this] { return watch_topic(); });
  watching_ = reading.eagerlyEvaluate([this](kj::Exception&& exception) {
    // A bug: the topic is no longer read, which the log says.
    say(std::string("stopped reading: ") + exception.getDescription().cStr());
  });
}

// A thread reads source_ and codec_: it ends before they go.
TopicFeed::~TopicFeed() noexcept { stop(); }

void TopicFeed::add(std::shared_ptr<Subscription> subscription) {
  {
    const std::lock_guard lock(mutex_);
    joined_.push_back(std::move(subscription));
  }
  // The event loop's feed is the loop's own: the newcomer is served now.
  if (!on_thread()) welcome_joined();
}

void TopicFeed::remove(const Subscription* subscription) {
  const std::lock_guard lock(mutex_);
  for (auto* list : {&subscriptions_, &joined_}) {
    list->erase(std::remove_if(list->begin(), list->end(),
                               [&](const auto& one) { return one.get() == subscription; }),
                list->end());
  }
}

bool TopicFeed::unsubscribed() const {
  const std::lock_guard lock(mutex_);
  return subscriptions_.empty() && joined_.empty();
}

std::shared_ptr<const EncodedMessage> TopicFeed::encode(std::span<const std::byte> frame,
                                                        std::uint32_t subscription_id) {
  // A message no subscription or connection holds any more is written again, its buffer's
  // capacity reused: only this reader hands messages out, so one it alone holds stays its own.
  std::shared_ptr<EncodedMessage> message;
  for (auto& kept : recycled_) {
    if (kept.use_count() == 1) {
      // Pairs with the release of the last other holder's reference: its reads came first.
      std::atomic_thread_fence(std::memory_order_acquire);
      message = kept;
      break;
    }
  }
  if (!message) {
    message = std::make_shared<EncodedMessage>();
    if (recycled_.size() < kRecycled) recycled_.push_back(message);
  }
  message->receive_time_ns = view_time_ns(clock_);
  try {
    codec_->encode(frame, payload_);
  } catch (const CodecError& error) {
    failed(error.what(), "the message is not sent");
    return nullptr;
  }
  message->framed_for = subscription_id;
  message_data(subscription_id, message->receive_time_ns, payload_, message->framed);
  return message;
}

void TopicFeed::loop() {
  while (!stopping()) {
    welcome_joined();
    // The one wait on the topic of a reader thread (the event loop's is watch_topic()'s).
    const auto frame = source_->next(kPoll);
    if (frame) deliver(*frame);
  }
}

kj::Promise<void> TopicFeed::watch_topic() {
  watch_->complete();
  bool took_all = take_waiting();
  // arm() refuses while a message is there: one came since take_waiting() looked.
  while (took_all && !watch_->arm()) took_all = take_waiting();
  if (!took_all) {
    // Lets the writers go first; the topic is read again right after.
    return kj::evalLater([this] { return watch_topic(); });
  }
  return observer_->whenBecomesReadable().then([this] { return watch_topic(); });
}

bool TopicFeed::take_waiting() {
  for (std::size_t taken = 0; taken < source_->topic().capacity(); ++taken) {
    const auto frame = source_->try_next();
    if (!frame) return true;
    deliver(*frame);
  }
  return false;
}

void TopicFeed::welcome_joined() {
  // Copied out under the lock, offered without it: a client's mailbox lock is never taken
  // under this one.
  {
    const std::lock_guard lock(mutex_);
    if (joined_.empty()) return;
    receivers_.swap(joined_);
  }
  if (const auto newest = source_->latest()) {
    if (auto message = encode(newest->bytes, receivers_.front()->id)) {
      for (const auto& subscription : receivers_) subscription->offer(message, 0);
    }
  }
  {
    const std::lock_guard lock(mutex_);
    subscriptions_.insert(subscriptions_.end(), receivers_.begin(), receivers_.end());
  }
  receivers_.clear();
}

void TopicFeed::deliver(const bridge::Frame& frame) {
  {
    const std::lock_guard lock(mutex_);
    receivers_ = subscriptions_;
  }
  // Framed for the first subscription's id: the others with that id send it as it is.
  auto message = encode(frame.bytes, receivers_.empty() ? 0 : receivers_.front()->id);
  for (const auto& subscription : receivers_) {
    if (message) {
      subscription->offer(message, frame.lost);
    } else {
      subscription->offer(nullptr, frame.lost + 1);
    }
  }
  receivers_.clear();
  if (message) count_carried();
}

std::uint64_t realtime_ns() noexcept {
  timespec now{};
  ::clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::uint64_t>(now.tv_sec) * 1'000'000'000u +
         static_cast<std::uint64_t>(now.tv_nsec);
}

std::uint64_t view_time_ns(const ViewClock& clock) {
  return clock ? static_cast<std::uint64_t>(std::max<std::int64_t>(clock(), 0)) : realtime_ns();
}

}  // namespace horus::view
