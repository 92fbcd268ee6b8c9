// horus::Blackbox: the scheduler's flight recorder, fixed-size in-memory rings of events
// (start/stop, node errors, deadline misses, health changes) and of ticks (which node ran, when,
// for how long, the messages it sent and received on each topic), written to a file on a crash
// or on request, and read back by read_blackbox(), read_blackbox_ticks() and `horus blackbox`.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "horus/detail/message_count.hpp"

namespace horus {

enum class BlackboxEventKind : std::uint32_t {
  SchedulerStart = 1,
  SchedulerStop,
  StopRequested,  // detail: why (signal, Miss::Stop, fatal failure, max_deadline_misses, stop())
  NodeInit,
  NodeInitFailed,  // detail: the exception's message
  NodeError,       // an exception escaped tick(); detail: its message
  NodeRestart,     // value: restart number
  NodeShutdown,
  NodeShutdownFailed,  // threw or exceeded 3 s; detail: why
  NodeRemoved,
  DeadlineMiss,   // value: lateness past the deadline (ns)
  BudgetOverrun,  // value: tick duration (ns)
  HealthChange,   // value: new NodeHealthState; detail: its name
  SafeStateEntered,
  WatchdogExpired,  // value: how many timeouts the tick had lasted
  Degradation,      // detail: an RT feature that could not be had
};

std::string_view to_string(BlackboxEventKind kind) noexcept;

/// One recorded event: 128 bytes, trivially copyable, so recording never allocates.
struct BlackboxEvent {
  std::int64_t wall_time_ns = 0;  // since the Unix epoch
  std::uint64_t tick = 0;  // the node's tick index (the scheduler's cycle for its own events)
  BlackboxEventKind kind{};
  std::uint32_t reserved = 0;
  std::int64_t value = 0;
  char node[32] = {};    // NUL-terminated, truncated
  char detail[64] = {};  // NUL-terminated, truncated

  std::string_view node_name() const noexcept;
  std::string_view detail_text() const noexcept;
};
static_assert(sizeof(BlackboxEvent) == 128);

/// One topic a tick touched, and its messages in that tick.
struct BlackboxTopic {
  char name[32] = {};  // NUL-terminated, truncated
  std::uint32_t sent = 0;
  std::uint32_t received = 0;

  std::string_view topic_name() const noexcept;
};

/// One tick of one node: 384 bytes, trivially copyable, so recording never allocates.
struct BlackboxTick {
  std::int64_t wall_time_ns = 0;  // when the tick started, since the Unix epoch
  std::uint64_t tick = 0;         // the node's tick index
  std::int64_t duration_ns = 0;
  std::uint32_t topic_count = 0;     // entries of `topics` in use, in the order first touched
  std::uint32_t other_messages = 0;  // messages on topics beyond those
  char node[32] = {};                // NUL-terminated, truncated
  BlackboxTopic topics[detail::TickTopics::kMax] = {};

  std::string_view node_name() const noexcept;
};
static_assert(sizeof(BlackboxTick) == 384);

/// Lock-free rings of the last `event_capacity` events and `tick_capacity` ticks. record() and
/// record_tick() may be called from any thread, including real-time ones (no lock, allocation or
/// system call); snapshots and write_to() from any other.
class Blackbox {
 public:
  explicit Blackbox(std::size_t event_capacity, std::size_t tick_capacity = 0);
  ~Blackbox();
  Blackbox(const Blackbox&) = delete;
  Blackbox& operator=(const Blackbox&) = delete;

  struct Capacity {
    std::size_t events;
    std::size_t ticks;
  };
  /// What `megabytes` MiB hold: an eighth for events, the rest for ticks (seed 001's "last N MB
  /// of tick data").
  static Capacity capacity_for_mb(std::size_t megabytes) noexcept;

  std::size_t capacity() const noexcept { return capacity_; }
  std::size_t tick_capacity() const noexcept { return tick_capacity_; }
  /// Events recorded so far (older ones beyond capacity have been overwritten).
  std::uint64_t recorded() const noexcept { return head_.load(std::memory_order_relaxed); }
  /// Ticks recorded so far (older ones beyond tick_capacity have been overwritten).
  std::uint64_t ticks_recorded() const noexcept {
    return tick_head_.load(std::memory_order_relaxed);
  }

  void record(BlackboxEventKind kind, std::string_view node, std::uint64_t tick,
              std::int64_t value = 0, std::string_view detail = {}) noexcept;

  /// A tick of `node` that just ended after `duration_ns`, with the topics it touched. Nothing
  /// when the blackbox keeps no ticks.
  void record_tick(std::string_view node, std::uint64_t tick, std::int64_t duration_ns,
                   const detail::TickTopics& topics) noexcept;

  /// The retained events, oldest first.
  std::vector<BlackboxEvent> snapshot() const;
  /// The retained ticks, oldest first.
  std::vector<BlackboxTick> tick_snapshot() const;

  /// Writes the ring to `path` (replacing it). Throws horus::Error when the file cannot be written.
  void write_to(const std::filesystem::path& path) const;

  /// Async-signal-safe variant for crash handlers: only open/write/close. False on failure.
  bool write_to_fd(int fd) const noexcept;

 private:
  struct Slot;
  struct TickSlot;
  std::size_t capacity_;
  std::size_t tick_capacity_;
  std::unique_ptr<Slot[]> slots_;
  std::unique_ptr<TickSlot[]> tick_slots_;
  std::atomic<std::uint64_t> head_{0};
  std::atomic<std::uint64_t> tick_head_{0};
};

/// Reads a file written by Blackbox::write_to (or a crash dump), oldest event first.
/// Throws horus::Error naming the file when it is missing, truncated or not a blackbox file.
std::vector<BlackboxEvent> read_blackbox(const std::filesystem::path& path);
/// The ticks of such a file, oldest first; throws as read_blackbox() does.
std::vector<BlackboxTick> read_blackbox_ticks(const std::filesystem::path& path);

/// One line per event: time, tick, kind, node, value and detail.
std::string format_blackbox_event(const BlackboxEvent& event);
/// One line per tick: start time, node, tick index, duration (us) and "topic sent/received"
/// for each topic it touched.
std::string format_blackbox_tick(const BlackboxTick& tick);

}  // namespace horus
