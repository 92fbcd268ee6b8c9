// Per-node message counters (NodeMetrics::messages_sent / messages_received): the scheduler
// points the thread at the running node's counters around each callback, and a topic adds one
// per message it sends or receives there. Outside callbacks nothing is counted.
#pragma once

#include <atomic>
#include <cstdint>

namespace horus::detail {

/// One node's counters: a single writer (the thread running the node), relaxed readers.
struct MessageCounts {
  std::atomic<std::uint64_t> sent{0};
  std::atomic<std::uint64_t> received{0};
};

/// The counters of the node whose callback runs on this thread, or nullptr.
inline thread_local MessageCounts* current_message_counts = nullptr;

/// A plain increment (load and store, no read-modify-write): the only writer is this thread.
inline void bump(std::atomic<std::uint64_t>& counter) noexcept {
  counter.store(counter.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}
inline void count_sent() noexcept {
  if (MessageCounts* counts = current_message_counts) bump(counts->sent);
}
inline void count_received() noexcept {
  if (MessageCounts* counts = current_message_counts) bump(counts->received);
}

}  // namespace horus::detail
