// Per-node message counters (NodeMetrics::messages_sent / messages_received): the scheduler
// points the thread at the running node's counters around each callback, and a topic adds one
// per message it sends or receives there. Outside callbacks nothing is counted.
//
// With a blackbox or a session recording, the counters also note which topics the current tick
// touched, how many messages each carried and how far each handle read (TickTopics), for the
// blackbox's per-tick record and the recording's tick records.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

namespace horus::detail {

/// One topic a tick touched: its name (truncated, NUL-terminated) and its messages.
struct TopicTouch {
  char name[32];
  std::uint32_t sent;
  std::uint32_t received;
  /// The ticket after the last message received: where the handle stood on its ring then.
  std::uint64_t taken;
};

/// The topics one tick touched, in the order it first touched them. Fixed size: a tick never
/// allocates for it; messages on topics beyond kMax are only counted in `other_messages`.
struct TickTopics {
  static constexpr std::size_t kMax = 8;

  std::array<const void*, kMax> handles{};  // which handle each entry counts
  std::array<TopicTouch, kMax> touches{};
  std::uint32_t count = 0;
  std::uint32_t other_messages = 0;

  void clear() noexcept {
    count = 0;
    other_messages = 0;
  }

  /// The entry of the topic handle `handle` (named `name`), made on its first message this tick.
  TopicTouch* touch(const void* handle, std::string_view name) noexcept {
    for (std::uint32_t i = 0; i < count; ++i) {
      if (handles[i] == handle) return &touches[i];
    }
    if (count == kMax) {
      ++other_messages;
      return nullptr;
    }
    // The name is copied now: a handle made and dropped inside the tick is gone by its end.
    TopicTouch& entry = touches[count];
    const std::size_t n = std::min(name.size(), sizeof(entry.name) - 1);
    std::memcpy(entry.name, name.data(), n);
    entry.name[n] = '\0';
    entry.sent = 0;
    entry.received = 0;
    entry.taken = 0;
    handles[count++] = handle;
    return &entry;
  }
};

/// One node's counters: a single writer (the thread running the node), relaxed readers.
struct MessageCounts {
  std::atomic<std::uint64_t> sent{0};
  std::atomic<std::uint64_t> received{0};
  /// Set by the scheduler when it keeps a blackbox or records the session; then `topics` holds
  /// the current tick's topics (only the thread running the node touches either).
  bool track_topics = false;
  TickTopics topics;
};

/// The counters of the node whose callback runs on this thread, or nullptr.
inline thread_local MessageCounts* current_message_counts = nullptr;

/// A plain increment (load and store, no read-modify-write): the only writer is this thread.
inline void bump(std::atomic<std::uint64_t>& counter) noexcept {
  counter.store(counter.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}
/// A message the topic handle `handle`, named `name`, sent.
inline void count_sent(const void* handle, std::string_view name) noexcept {
  if (MessageCounts* counts = current_message_counts) {
    bump(counts->sent);
    if (counts->track_topics) {
      if (TopicTouch* touch = counts->topics.touch(handle, name)) ++touch->sent;
    }
  }
}
/// A message the topic handle `handle`, named `name`, received, whose next ticket is `next`.
inline void count_received(const void* handle, std::string_view name, std::uint64_t next) noexcept {
  if (MessageCounts* counts = current_message_counts) {
    bump(counts->received);
    if (counts->track_topics) {
      if (TopicTouch* touch = counts->topics.touch(handle, name)) {
        ++touch->received;
        touch->taken = next;
      }
    }
  }
}

}  // namespace horus::detail
