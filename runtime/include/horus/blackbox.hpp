// horus::Blackbox: the scheduler's flight recorder, a fixed-size in-memory ring of events
// (start/stop, node errors, deadline misses, health changes) that is written to a file on a crash
// or on request, and read back by read_blackbox() and the `horus-blackbox` command.
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

/// A lock-free ring of the last `capacity` events. record() may be called from any thread,
/// including real-time ones; snapshot() and write_to() from any other.
class Blackbox {
 public:
  explicit Blackbox(std::size_t capacity);
  ~Blackbox();
  Blackbox(const Blackbox&) = delete;
  Blackbox& operator=(const Blackbox&) = delete;

  /// Capacity in events for a ring of `megabytes` MiB.
  static std::size_t capacity_for_mb(std::size_t megabytes) noexcept;

  std::size_t capacity() const noexcept { return capacity_; }
  /// Events recorded so far (older ones beyond capacity have been overwritten).
  std::uint64_t recorded() const noexcept { return head_.load(std::memory_order_relaxed); }

  void record(BlackboxEventKind kind, std::string_view node, std::uint64_t tick,
              std::int64_t value = 0, std::string_view detail = {}) noexcept;

  /// The retained events, oldest first.
  std::vector<BlackboxEvent> snapshot() const;

  /// Writes the ring to `path` (replacing it). Throws horus::Error when the file cannot be written.
  void write_to(const std::filesystem::path& path) const;

  /// Async-signal-safe variant for crash handlers: only open/write/close. False on failure.
  bool write_to_fd(int fd) const noexcept;

 private:
  struct Slot;
  std::size_t capacity_;
  std::unique_ptr<Slot[]> slots_;
  std::atomic<std::uint64_t> head_{0};
};

/// Reads a file written by Blackbox::write_to (or a crash dump), oldest event first.
/// Throws horus::Error naming the file when it is missing, truncated or not a blackbox file.
std::vector<BlackboxEvent> read_blackbox(const std::filesystem::path& path);

/// One line per event: time, tick, kind, node, value and detail.
std::string format_blackbox_event(const BlackboxEvent& event);

}  // namespace horus
