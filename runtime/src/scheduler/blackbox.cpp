#include "horus/blackbox.hpp"
#include "horus/detail/errno_text.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>

#include "horus/error.hpp"

namespace horus {
namespace {

constexpr std::array<char, 8> kMagic = {'H', 'O', 'R', 'U', 'S', 'B', 'B', '1'};
constexpr std::uint32_t kVersion = 1;
constexpr std::size_t kWords = sizeof(BlackboxEvent) / sizeof(std::uint64_t);

// File layout (little-endian, native): header, then `capacity` slots of {seq, event}. A slot's seq
// is its event's 1-based sequence number, 0 for a slot never written or caught mid-write.
struct FileHeader {
  std::array<char, 8> magic;
  std::uint32_t version;
  std::uint32_t record_size;
  std::uint64_t capacity;
  std::uint64_t head;
};
static_assert(sizeof(FileHeader) == 32);

struct FileSlot {
  std::uint64_t seq;
  BlackboxEvent event;
};
static_assert(sizeof(FileSlot) == 136);

void copy_text(char* out, std::size_t size, std::string_view text) noexcept {
  const std::size_t n = std::min(size - 1, text.size());
  std::memcpy(out, text.data(), n);
  std::memset(out + n, 0, size - n);
}

std::int64_t wall_now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

bool write_all(int fd, const void* data, std::size_t size) noexcept {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

// A seqlock per slot, with the payload in atomic words so that concurrent writers and readers
// are race-free under the memory model (and ThreadSanitizer), without any lock.
struct Blackbox::Slot {
  std::atomic<std::uint64_t> seq{0};
  std::array<std::atomic<std::uint64_t>, kWords> words{};
};
static_assert(sizeof(std::atomic<std::uint64_t>) == sizeof(std::uint64_t));

std::string_view BlackboxEvent::node_name() const noexcept {
  return {node, strnlen(node, sizeof(node))};
}

std::string_view BlackboxEvent::detail_text() const noexcept {
  return {detail, strnlen(detail, sizeof(detail))};
}

std::string_view to_string(BlackboxEventKind kind) noexcept {
  switch (kind) {
    case BlackboxEventKind::SchedulerStart:
      return "SchedulerStart";
    case BlackboxEventKind::SchedulerStop:
      return "SchedulerStop";
    case BlackboxEventKind::StopRequested:
      return "StopRequested";
    case BlackboxEventKind::NodeInit:
      return "NodeInit";
    case BlackboxEventKind::NodeInitFailed:
      return "NodeInitFailed";
    case BlackboxEventKind::NodeError:
      return "NodeError";
    case BlackboxEventKind::NodeRestart:
      return "NodeRestart";
    case BlackboxEventKind::NodeShutdown:
      return "NodeShutdown";
    case BlackboxEventKind::NodeShutdownFailed:
      return "NodeShutdownFailed";
    case BlackboxEventKind::NodeRemoved:
      return "NodeRemoved";
    case BlackboxEventKind::DeadlineMiss:
      return "DeadlineMiss";
    case BlackboxEventKind::BudgetOverrun:
      return "BudgetOverrun";
    case BlackboxEventKind::HealthChange:
      return "HealthChange";
    case BlackboxEventKind::SafeStateEntered:
      return "SafeStateEntered";
    case BlackboxEventKind::WatchdogExpired:
      return "WatchdogExpired";
    case BlackboxEventKind::Degradation:
      return "Degradation";
  }
  return "Unknown";
}

Blackbox::Blackbox(std::size_t capacity) : capacity_(capacity) {
  if (capacity == 0) {
    throw Error("horus::Blackbox: capacity must be at least one event");
  }
  slots_ = std::make_unique<Slot[]>(capacity);
}

Blackbox::~Blackbox() = default;

std::size_t Blackbox::capacity_for_mb(std::size_t megabytes) noexcept {
  return megabytes * 1024 * 1024 / sizeof(FileSlot);
}

void Blackbox::record(BlackboxEventKind kind, std::string_view node, std::uint64_t tick,
                      std::int64_t value, std::string_view detail) noexcept {
  BlackboxEvent event;
  event.wall_time_ns = wall_now_ns();
  event.tick = tick;
  event.kind = kind;
  event.value = value;
  copy_text(event.node, sizeof(event.node), node);
  // One line: a multi-line detail (a Python traceback) keeps its headline, and each event stays
  // one row of horus-blackbox's table.
  copy_text(event.detail, sizeof(event.detail), detail.substr(0, detail.find('\n')));
  std::array<std::uint64_t, kWords> words;
  std::memcpy(words.data(), &event, sizeof(event));

  const std::uint64_t index = head_.fetch_add(1, std::memory_order_relaxed);
  Slot& slot = slots_[index % capacity_];
  // No fences (ThreadSanitizer cannot model them): each word's release store publishes the
  // seq = 0 before it, so a reader that sees a new word also sees the slot as being written.
  slot.seq.store(0, std::memory_order_relaxed);
  for (std::size_t i = 0; i < kWords; ++i) {
    slot.words[i].store(words[i], std::memory_order_release);
  }
  slot.seq.store(index + 1, std::memory_order_release);
}

namespace {

// Reads slot `slot` consistently, or returns seq 0 when it is being written.
template <class SlotT>
FileSlot read_slot(const SlotT& slot) noexcept {
  FileSlot out{};
  const std::uint64_t before = slot.seq.load(std::memory_order_acquire);
  std::array<std::uint64_t, kWords> words;
  for (std::size_t i = 0; i < kWords; ++i) {
    words[i] = slot.words[i].load(std::memory_order_acquire);
  }
  const std::uint64_t after = slot.seq.load(std::memory_order_relaxed);
  if (before != 0 && before == after) {
    out.seq = before;
    std::memcpy(static_cast<void*>(&out.event), words.data(), sizeof(out.event));
  }
  return out;
}

}  // namespace

std::vector<BlackboxEvent> Blackbox::snapshot() const {
  std::vector<FileSlot> slots;
  slots.reserve(capacity_);
  for (std::size_t i = 0; i < capacity_; ++i) {
    FileSlot s = read_slot(slots_[i]);
    if (s.seq != 0) slots.push_back(s);
  }
  std::sort(slots.begin(), slots.end(),
            [](const FileSlot& a, const FileSlot& b) { return a.seq < b.seq; });
  std::vector<BlackboxEvent> events;
  events.reserve(slots.size());
  for (const FileSlot& s : slots) events.push_back(s.event);
  return events;
}

bool Blackbox::write_to_fd(int fd) const noexcept {
  FileHeader header{kMagic, kVersion, sizeof(BlackboxEvent), capacity_,
                    head_.load(std::memory_order_acquire)};
  if (!write_all(fd, &header, sizeof(header))) return false;
  // Slot by slot through a small stack buffer: no allocation, so this also serves crash handlers.
  std::array<FileSlot, 32> buffer;
  std::size_t filled = 0;
  for (std::size_t i = 0; i < capacity_; ++i) {
    buffer[filled++] = read_slot(slots_[i]);
    if (filled == buffer.size() || i + 1 == capacity_) {
      if (!write_all(fd, buffer.data(), filled * sizeof(FileSlot))) return false;
      filled = 0;
    }
  }
  return true;
}

void Blackbox::write_to(const std::filesystem::path& path) const {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    throw Error("horus::Blackbox: cannot open '" + path.string() +
                "' for writing: " + detail::errno_text(errno));
  }
  const bool ok = write_to_fd(fd);
  const bool closed = ::close(fd) == 0;
  if (!ok || !closed) {
    throw Error("horus::Blackbox: failed writing '" + path.string() +
                "': " + detail::errno_text(errno));
  }
}

std::vector<BlackboxEvent> read_blackbox(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw Error("blackbox file '" + path.string() + "' cannot be opened");
  }
  FileHeader header{};
  if (!in.read(reinterpret_cast<char*>(&header), sizeof(header))) {
    throw Error("blackbox file '" + path.string() + "' is truncated: no header");
  }
  if (header.magic != kMagic) {
    throw Error("'" + path.string() + "' is not a horus blackbox file (bad magic)");
  }
  if (header.version != kVersion || header.record_size != sizeof(BlackboxEvent)) {
    throw Error("blackbox file '" + path.string() + "' has version " +
                std::to_string(header.version) + " / record size " +
                std::to_string(header.record_size) + "; this reader understands version " +
                std::to_string(kVersion) + " / " + std::to_string(sizeof(BlackboxEvent)));
  }
  std::error_code ec;
  const auto file_size = std::filesystem::file_size(path, ec);
  if (ec || header.capacity > (file_size - sizeof(header)) / sizeof(FileSlot) ||
      file_size != sizeof(header) + header.capacity * sizeof(FileSlot)) {
    throw Error("blackbox file '" + path.string() + "' is truncated or corrupt: header says " +
                std::to_string(header.capacity) + " slots");
  }
  std::vector<FileSlot> slots(header.capacity);
  if (!in.read(reinterpret_cast<char*>(slots.data()),
               static_cast<std::streamsize>(slots.size() * sizeof(FileSlot)))) {
    throw Error("blackbox file '" + path.string() + "' is truncated");
  }
  // Keep only the last `capacity` sequence numbers: older ones were overwritten mid-dump.
  const std::uint64_t oldest =
      header.head > header.capacity ? header.head - header.capacity + 1 : 1;
  std::erase_if(slots, [&](const FileSlot& s) {
    return s.seq == 0 || s.seq < oldest || s.seq > header.head;
  });
  std::sort(slots.begin(), slots.end(),
            [](const FileSlot& a, const FileSlot& b) { return a.seq < b.seq; });
  std::vector<BlackboxEvent> events;
  events.reserve(slots.size());
  for (const FileSlot& s : slots) {
    BlackboxEvent e = s.event;
    e.node[sizeof(e.node) - 1] = '\0';
    e.detail[sizeof(e.detail) - 1] = '\0';
    events.push_back(e);
  }
  return events;
}

std::string format_blackbox_event(const BlackboxEvent& event) {
  const std::time_t secs = static_cast<std::time_t>(event.wall_time_ns / 1'000'000'000);
  const long micros = static_cast<long>((event.wall_time_ns % 1'000'000'000) / 1000);
  std::tm utc{};
  gmtime_r(&secs, &utc);
  char when[32];
  std::strftime(when, sizeof(when), "%Y-%m-%dT%H:%M:%S", &utc);
  char line[256];
  std::snprintf(line, sizeof(line), "%s.%06ldZ  %-13" PRIu64 " %-18s %-16s %-12" PRId64 " %s", when,
                micros, event.tick, std::string(to_string(event.kind)).c_str(),
                std::string(event.node_name()).c_str(), event.value,
                std::string(event.detail_text()).c_str());
  return line;
}

}  // namespace horus
