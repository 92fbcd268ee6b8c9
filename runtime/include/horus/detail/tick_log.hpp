// detail::TickLog: the ticks of one node on their way from the thread that runs it to a
// recorder's thread. A single-producer single-consumer ring: the tick path stores one entry and
// publishes it with one release store (no lock, no allocation, no syscall); when the recorder
// has fallen a whole ring behind, the tick is counted as dropped instead.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>

namespace horus::detail {

enum class TickOutcome : std::uint8_t { Ok, Error, DeadlineMiss };

struct TickEntry {
  std::uint64_t tick;     // the scheduler's cycle when the node ticked
  std::int64_t start_ns;  // CLOCK_MONOTONIC
  std::int64_t duration_ns;
  TickOutcome outcome;
};

class TickLog {
 public:
  static constexpr std::size_t kCapacity = 4096;

  /// Producer: the thread running the node (one at a time; the scheduler hands a node between
  /// threads only through a thread start or join).
  void push(const TickEntry& entry) noexcept {
    if (!active_.load(std::memory_order_relaxed)) return;
    const std::uint64_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) >= kCapacity) {
      dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      return;
    }
    entries_[head % kCapacity] = entry;
    head_.store(head + 1, std::memory_order_release);
  }

  /// Consumer: hands every waiting entry to `take`; how many.
  template <class Take>
  std::size_t drain(Take&& take) {
    const std::uint64_t head = head_.load(std::memory_order_acquire);
    std::uint64_t tail = tail_.load(std::memory_order_relaxed);
    const std::uint64_t first = tail;
    for (; tail != head; ++tail) {
      take(entries_[tail % kCapacity]);
      tail_.store(tail + 1, std::memory_order_release);
    }
    return static_cast<std::size_t>(head - first);
  }

  /// Ticks not logged because the ring was full.
  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }
  /// Stops logging (the recording ended); later pushes do nothing.
  void close() noexcept { active_.store(false, std::memory_order_relaxed); }

 private:
  std::array<TickEntry, kCapacity> entries_{};
  alignas(64) std::atomic<std::uint64_t> head_{0};
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<bool> active_{true};
  alignas(64) std::atomic<std::uint64_t> tail_{0};
};

}  // namespace horus::detail
