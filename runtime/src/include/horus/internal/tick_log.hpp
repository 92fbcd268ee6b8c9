// detail::TickLog: the ticks of one node on their way from the thread that runs it to a
// recorder's thread. A single-producer single-consumer ring: the tick path stores one entry and
// publishes it with one release store (no lock, no allocation, no syscall); when the recorder
// has fallen a whole ring behind, the tick is counted as dropped instead.
//
// Each entry also carries, for the topics the node subscribes to (up to kWatched of them), how
// many tickets each ring had handed out when the tick started (a message of ticket t was there
// for the node to receive in the first tick whose count exceeds t) and how far the node's own
// handles had read by its end (a message published by another thread while the tick ran, and
// taken by it, is in that tick's reach too). A deterministic replay delivers each recorded
// message before the first tick either count places it in (docs/recording.md), which a stamp
// taken by the recorder (late by however far it lags) cannot tell.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string_view>
#include <tuple>
#include <utility>

#include "horus/detail/message_count.hpp"
#include "horus/detail/ring.hpp"

namespace horus::detail {

enum class TickOutcome : std::uint8_t { Ok, Error, DeadlineMiss };

struct TickEntry {
  std::uint64_t tick;     // the scheduler's cycle when the node ticked
  std::int64_t start_ns;  // CLOCK_MONOTONIC
  std::int64_t duration_ns;
  TickOutcome outcome;
  /// How many of `received` are set: TickLog::watch() calls made before the tick started.
  std::uint8_t watched = 0;
  /// Tickets handed out on the i-th watched topic when the tick started.
  std::array<std::uint64_t, 8> received{};
  /// The ticket after the last message the node took from the i-th watched topic in this tick;
  /// 0 when it took none.
  std::array<std::uint64_t, 8> taken{};
};

class TickLog {
 public:
  static constexpr std::size_t kCapacity = 4096;
  static constexpr std::size_t kWatched = std::tuple_size_v<decltype(TickEntry::received)>;

  /// Consumer: from the next tick on, entries carry `ring`'s tickets as received[i] and how far
  /// the node's handles named `topic` read as taken[i], i the number of earlier calls (`owner`
  /// keeps the ring mapped as long as this log). False when kWatched rings are watched already.
  bool watch(std::string_view topic, const RingView& ring, std::shared_ptr<const void> owner) {
    const std::size_t index = watched_count_.load(std::memory_order_relaxed);
    if (index == kWatched) return false;
    watched_[index] = Watched{&ring, std::move(owner), {}};
    // Truncated as TickTopics names it, to be found among the tick's topics by that name.
    const std::size_t n = std::min(topic.size(), sizeof(watched_[index].name) - 1);
    std::memcpy(watched_[index].name, topic.data(), n);
    watched_count_.store(index + 1, std::memory_order_release);
    return true;
  }

  /// Producer, as the node's tick starts: what the watched rings have handed out so far.
  void note_start() noexcept {
    if (!active_.load(std::memory_order_relaxed)) return;
    const std::size_t count = watched_count_.load(std::memory_order_acquire);
    for (std::size_t i = 0; i < count; ++i) start_received_[i] = ring_written(*watched_[i].ring);
    start_watched_ = static_cast<std::uint8_t>(count);
  }

  /// Producer: the thread running the node (one at a time; the scheduler hands a node between
  /// threads only through a thread start or join). The entry takes the counts of note_start()
  /// and, from `topics` (what the tick's handles did), how far the node read each topic.
  void push(const TickEntry& entry, const TickTopics& topics) noexcept {
    if (!active_.load(std::memory_order_relaxed)) return;
    const std::uint64_t head = head_.load(std::memory_order_relaxed);
    const std::uint8_t watched = std::exchange(start_watched_, 0);
    if (head - tail_.load(std::memory_order_acquire) >= kCapacity) {
      dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      return;
    }
    TickEntry& stored = entries_[head % kCapacity];
    stored = entry;
    stored.watched = watched;
    std::copy_n(start_received_.begin(), watched, stored.received.begin());
    for (std::size_t i = 0; i < watched; ++i) {
      stored.taken[i] = 0;
      for (std::uint32_t t = 0; t < topics.count; ++t) {
        if (std::strcmp(topics.touches[t].name, watched_[i].name) == 0)
          stored.taken[i] = std::max(stored.taken[i], topics.touches[t].taken);
      }
    }
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
  struct Watched {
    const RingView* ring = nullptr;
    std::shared_ptr<const void> owner;
    char name[sizeof(TopicTouch::name)];
  };

  std::array<TickEntry, kCapacity> entries_{};
  // What the tick path touches, on the producer's lines; what only the consumer (and watch(),
  // rarely) writes, on the consumer's.
  alignas(64) std::atomic<std::uint64_t> head_{0};
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<std::size_t> watched_count_{0};
  std::array<std::uint64_t, kWatched>
      start_received_{};  // the producer's, between note_start and push
  std::uint8_t start_watched_ = 0;
  std::atomic<bool> active_{true};
  alignas(64) std::atomic<std::uint64_t> tail_{0};
  std::array<Watched, kWatched> watched_{};
};

}  // namespace horus::detail
