// The log ring: a bounded, lock-free, multi-writer ring of fixed-size log lines. The same layout
// serves the process's queue to its stderr writer (on the heap) and the namespace's ring in shared
// memory that read_log() and `horus log` read (a file under $HORUS_SHM_DIR/@logs).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "horus/log.hpp"

namespace horus::detail {

/// One line as stored: trivially copyable, 504 bytes, so that a slot is 512 with its seq word.
struct LogEntry {
  std::int64_t wall_time_ns;
  std::uint32_t pid;
  std::uint8_t level;
  std::uint8_t source_size;
  std::uint16_t text_size;
  char source[kMaxLogSource];
  char text[kMaxLogText];

  std::string_view source_text() const noexcept { return {source, source_size}; }
  std::string_view message() const noexcept { return {text, text_size}; }
};
static_assert(sizeof(LogEntry) == 504);

inline constexpr std::size_t kLogEntryWords = sizeof(LogEntry) / sizeof(std::uint64_t);

/// A seqlock: 0 never written, 2t+1 while ticket t is written, 2t+2 once it holds ticket t. The
/// entry lives in atomic words so that writers and readers in any process are race-free.
struct LogSlot {
  std::atomic<std::uint64_t> seq;
  std::array<std::atomic<std::uint64_t>, kLogEntryWords> words;
};
static_assert(sizeof(LogSlot) == 512);

inline constexpr std::array<char, 8> kLogMagic = {'H', 'O', 'R', 'U', 'S', 'L', 'O', 'G'};
inline constexpr std::uint32_t kLogVersion = 1;

struct LogRingHeader {
  std::array<char, 8> magic;
  std::uint32_t version;
  std::uint32_t slot_size;
  std::uint64_t capacity;  // a power of two
  std::atomic<std::uint64_t> next_ticket;
  std::atomic<std::uint64_t> dropped;
  std::uint64_t reserved[3];
};
static_assert(sizeof(LogRingHeader) == 64);

/// A view of a header followed by `capacity` slots (the caller owns the memory).
class LogRing {
 public:
  enum class Read : std::uint8_t { Ready, Pending, Lost };

  LogRing() = default;
  explicit LogRing(void* memory) noexcept
      : header_(static_cast<LogRingHeader*>(memory)),
        slots_(reinterpret_cast<LogSlot*>(static_cast<std::byte*>(memory) + sizeof(LogRingHeader))),
        mask_(header_->capacity - 1) {}

  static std::size_t bytes_for(std::size_t capacity) noexcept {
    return sizeof(LogRingHeader) + capacity * sizeof(LogSlot);
  }
  /// Formats zeroed memory as an empty ring; the magic is written last.
  static void format(void* memory, std::size_t capacity) noexcept;
  /// Why `memory` of `size` bytes is not a ring this build can use, or "" when it is.
  static std::string validate(const void* memory, std::size_t size);

  bool valid() const noexcept { return header_ != nullptr; }
  std::uint64_t capacity() const noexcept { return mask_ + 1; }
  std::uint64_t next_ticket() const noexcept {
    return header_->next_ticket.load(std::memory_order_acquire);
  }
  std::uint64_t dropped() const noexcept {
    return header_->dropped.load(std::memory_order_relaxed);
  }

  /// Places the entry without waiting; false (and counted) when its slot was still being written.
  bool push(const LogEntry& entry) noexcept;
  /// Ticket `ticket`'s entry: Ready, Pending (not written yet, or being written), or Lost
  /// (overwritten by a later lap, or abandoned by its writer).
  Read read(std::uint64_t ticket, LogEntry& out) const noexcept;

 private:
  LogRingHeader* header_ = nullptr;
  LogSlot* slots_ = nullptr;
  std::uint64_t mask_ = 0;
};

/// The namespace's ring in shared memory, created when missing ("" namespace: the current one).
/// Throws horus::Error saying why it cannot be opened. Mapped for the life of the process.
LogRing open_shared_log_ring(std::string_view namespace_name);

/// Path of a namespace's ring.
std::string shared_log_ring_path(std::string_view namespace_name);

/// Writes "<time> <LEVEL> <source>: <message>" into `out` (NUL-terminated, cut to fit); returns
/// the length. No allocation: the stderr writer uses it too.
std::size_t format_log_entry(const LogEntry& entry, char* out, std::size_t size) noexcept;

}  // namespace horus::detail
