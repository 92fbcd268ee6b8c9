#include "horus/blackbox.hpp"
#include "horus/internal/errno_text.hpp"

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
constexpr std::uint32_t kVersion = 2;

// File layout (little-endian, native): header, then `capacity` event slots of {seq, event}, then
// `tick_capacity` tick slots of {seq, tick}. A slot's seq is its record's 1-based sequence
// number in its ring, 0 for a slot never written or caught mid-write.
struct FileHeader {
  std::array<char, 8> magic;
  std::uint32_t version;
  std::uint32_t record_size;
  std::uint64_t capacity;
  std::uint64_t head;
  std::uint32_t tick_record_size;
  std::uint32_t reserved;
  std::uint64_t tick_capacity;
  std::uint64_t tick_head;
};
static_assert(sizeof(FileHeader) == 56);

template <class Record>
struct FileSlot {
  std::uint64_t seq;
  Record record;
};
static_assert(sizeof(FileSlot<BlackboxEvent>) == 136);
static_assert(sizeof(FileSlot<BlackboxTick>) == 392);

// A seqlock per slot, with the payload in atomic words so that concurrent writers and readers
// are race-free under the memory model (and ThreadSanitizer), without any lock.
template <class Record>
struct SeqSlot {
  static constexpr std::size_t kWords = sizeof(Record) / sizeof(std::uint64_t);
  std::atomic<std::uint64_t> seq{0};
  std::array<std::atomic<std::uint64_t>, kWords> words{};
};
static_assert(sizeof(std::atomic<std::uint64_t>) == sizeof(std::uint64_t));

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

struct Blackbox::Slot : SeqSlot<BlackboxEvent> {};
struct Blackbox::TickSlot : SeqSlot<BlackboxTick> {};

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

std::string_view BlackboxTopic::topic_name() const noexcept {
  return {name, strnlen(name, sizeof(name))};
}

std::string_view BlackboxTick::node_name() const noexcept {
  return {node, strnlen(node, sizeof(node))};
}

Blackbox::Blackbox(std::size_t event_capacity, std::size_t tick_capacity)
    : capacity_(event_capacity), tick_capacity_(tick_capacity) {
  if (event_capacity == 0) {
    throw Error("horus::Blackbox: capacity must be at least one event");
  }
  slots_ = std::make_unique<Slot[]>(event_capacity);
  if (tick_capacity > 0) tick_slots_ = std::make_unique<TickSlot[]>(tick_capacity);
}

Blackbox::~Blackbox() = default;

Blackbox::Capacity Blackbox::capacity_for_mb(std::size_t megabytes) noexcept {
  const std::size_t bytes = megabytes * 1024 * 1024;
  const std::size_t events = std::max<std::size_t>(bytes / 8 / sizeof(FileSlot<BlackboxEvent>), 1);
  return {events, (bytes - bytes / 8) / sizeof(FileSlot<BlackboxTick>)};
}

namespace {

template <class Record, class Slot>
void write_slot(Slot& slot, std::uint64_t index, const Record& record) noexcept {
  std::array<std::uint64_t, SeqSlot<Record>::kWords> words;
  std::memcpy(words.data(), &record, sizeof(record));
  // No fences (ThreadSanitizer cannot model them): each word's release store publishes the
  // seq = 0 before it, so a reader that sees a new word also sees the slot as being written.
  slot.seq.store(0, std::memory_order_relaxed);
  for (std::size_t i = 0; i < words.size(); ++i) {
    slot.words[i].store(words[i], std::memory_order_release);
  }
  slot.seq.store(index + 1, std::memory_order_release);
}

// Reads `slot` consistently, or returns seq 0 when it is being written.
template <class Record, class Slot>
FileSlot<Record> read_slot(const Slot& slot) noexcept {
  FileSlot<Record> out{};
  const std::uint64_t before = slot.seq.load(std::memory_order_acquire);
  std::array<std::uint64_t, SeqSlot<Record>::kWords> words;
  for (std::size_t i = 0; i < words.size(); ++i) {
    words[i] = slot.words[i].load(std::memory_order_acquire);
  }
  const std::uint64_t after = slot.seq.load(std::memory_order_relaxed);
  if (before != 0 && before == after) {
    out.seq = before;
    std::memcpy(static_cast<void*>(&out.record), words.data(), sizeof(out.record));
  }
  return out;
}

template <class Record, class Slot>
std::vector<Record> snapshot_of(const Slot* slots, std::size_t capacity) {
  std::vector<FileSlot<Record>> kept;
  kept.reserve(capacity);
  for (std::size_t i = 0; i < capacity; ++i) {
    FileSlot<Record> s = read_slot<Record>(slots[i]);
    if (s.seq != 0) kept.push_back(s);
  }
  std::sort(kept.begin(), kept.end(), [](const auto& a, const auto& b) { return a.seq < b.seq; });
  std::vector<Record> records;
  records.reserve(kept.size());
  for (const auto& s : kept) records.push_back(s.record);
  return records;
}

// Slot by slot through a small stack buffer: no allocation, so this also serves crash handlers.
template <class Record, class Slot>
bool write_slots(int fd, const Slot* slots, std::size_t capacity) noexcept {
  std::array<FileSlot<Record>, 16> buffer;
  std::size_t filled = 0;
  for (std::size_t i = 0; i < capacity; ++i) {
    buffer[filled++] = read_slot<Record>(slots[i]);
    if (filled == buffer.size() || i + 1 == capacity) {
      if (!write_all(fd, buffer.data(), filled * sizeof(FileSlot<Record>))) return false;
      filled = 0;
    }
  }
  return true;
}

}  // namespace

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
  const std::uint64_t index = head_.fetch_add(1, std::memory_order_relaxed);
  write_slot(slots_[index % capacity_], index, event);
}

void Blackbox::record_tick(std::string_view node, std::uint64_t tick, std::int64_t duration_ns,
                           const detail::TickTopics& topics) noexcept {
  if (tick_capacity_ == 0) return;
  BlackboxTick record;
  record.wall_time_ns = wall_now_ns() - duration_ns;
  record.tick = tick;
  record.duration_ns = duration_ns;
  record.topic_count = topics.count;
  record.other_messages = topics.other_messages;
  copy_text(record.node, sizeof(record.node), node);
  for (std::uint32_t i = 0; i < topics.count; ++i) {
    static_assert(sizeof(record.topics[i].name) == sizeof(topics.touches[i].name));
    std::memcpy(record.topics[i].name, topics.touches[i].name, sizeof(record.topics[i].name));
    record.topics[i].sent = topics.touches[i].sent;
    record.topics[i].received = topics.touches[i].received;
  }
  const std::uint64_t index = tick_head_.fetch_add(1, std::memory_order_relaxed);
  write_slot(tick_slots_[index % tick_capacity_], index, record);
}

std::vector<BlackboxEvent> Blackbox::snapshot() const {
  return snapshot_of<BlackboxEvent>(slots_.get(), capacity_);
}

std::vector<BlackboxTick> Blackbox::tick_snapshot() const {
  return snapshot_of<BlackboxTick>(tick_slots_.get(), tick_capacity_);
}

bool Blackbox::write_to_fd(int fd) const noexcept {
  const FileHeader header{kMagic,
                          kVersion,
                          sizeof(BlackboxEvent),
                          capacity_,
                          head_.load(std::memory_order_acquire),
                          sizeof(BlackboxTick),
                          0,
                          tick_capacity_,
                          tick_head_.load(std::memory_order_acquire)};
  return write_all(fd, &header, sizeof(header)) &&
         write_slots<BlackboxEvent>(fd, slots_.get(), capacity_) &&
         write_slots<BlackboxTick>(fd, tick_slots_.get(), tick_capacity_);
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

namespace {

// The records of one ring of the file, oldest first: only the last `capacity` sequence numbers,
// as older ones were overwritten mid-dump.
template <class Record>
std::vector<Record> ring_of(std::ifstream& in, const std::filesystem::path& path,
                            std::uint64_t capacity, std::uint64_t head) {
  std::vector<FileSlot<Record>> slots(capacity);
  if (!in.read(reinterpret_cast<char*>(slots.data()),
               static_cast<std::streamsize>(slots.size() * sizeof(FileSlot<Record>)))) {
    throw Error("blackbox file '" + path.string() + "' is truncated");
  }
  const std::uint64_t oldest = head > capacity ? head - capacity + 1 : 1;
  std::erase_if(slots, [&](const auto& s) { return s.seq == 0 || s.seq < oldest || s.seq > head; });
  std::sort(slots.begin(), slots.end(), [](const auto& a, const auto& b) { return a.seq < b.seq; });
  std::vector<Record> records;
  records.reserve(slots.size());
  for (const auto& s : slots) records.push_back(s.record);
  return records;
}

struct FileContents {
  std::vector<BlackboxEvent> events;
  std::vector<BlackboxTick> ticks;
};

FileContents read_file(const std::filesystem::path& path) {
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
  if (header.version != kVersion || header.record_size != sizeof(BlackboxEvent) ||
      header.tick_record_size != sizeof(BlackboxTick)) {
    throw Error("blackbox file '" + path.string() + "' has version " +
                std::to_string(header.version) + " / record size " +
                std::to_string(header.record_size) + "; this reader understands version " +
                std::to_string(kVersion) + " / " + std::to_string(sizeof(BlackboxEvent)));
  }
  std::error_code ec;
  const auto file_size = std::filesystem::file_size(path, ec);
  const std::uint64_t room = ec ? 0 : file_size - sizeof(header);
  if (ec || header.capacity > room / sizeof(FileSlot<BlackboxEvent>) ||
      header.tick_capacity > room / sizeof(FileSlot<BlackboxTick>) ||
      room != header.capacity * sizeof(FileSlot<BlackboxEvent>) +
                  header.tick_capacity * sizeof(FileSlot<BlackboxTick>)) {
    throw Error("blackbox file '" + path.string() + "' is truncated or corrupt: header says " +
                std::to_string(header.capacity) + " event and " +
                std::to_string(header.tick_capacity) + " tick slots");
  }
  FileContents contents;
  contents.events = ring_of<BlackboxEvent>(in, path, header.capacity, header.head);
  contents.ticks = ring_of<BlackboxTick>(in, path, header.tick_capacity, header.tick_head);
  for (BlackboxEvent& e : contents.events) {
    e.node[sizeof(e.node) - 1] = '\0';
    e.detail[sizeof(e.detail) - 1] = '\0';
  }
  for (BlackboxTick& t : contents.ticks) {
    t.node[sizeof(t.node) - 1] = '\0';
    t.topic_count = std::min<std::uint32_t>(t.topic_count, detail::TickTopics::kMax);
    for (BlackboxTopic& topic : t.topics) topic.name[sizeof(topic.name) - 1] = '\0';
  }
  return contents;
}

std::string utc_text(std::int64_t wall_time_ns) {
  const std::time_t secs = static_cast<std::time_t>(wall_time_ns / 1'000'000'000);
  const long micros = static_cast<long>((wall_time_ns % 1'000'000'000) / 1000);
  std::tm utc{};
  gmtime_r(&secs, &utc);
  char when[32];
  std::strftime(when, sizeof(when), "%Y-%m-%dT%H:%M:%S", &utc);
  char text[48];
  std::snprintf(text, sizeof(text), "%s.%06ldZ", when, micros);
  return text;
}

}  // namespace

std::vector<BlackboxEvent> read_blackbox(const std::filesystem::path& path) {
  return read_file(path).events;
}

std::vector<BlackboxTick> read_blackbox_ticks(const std::filesystem::path& path) {
  return read_file(path).ticks;
}

std::string format_blackbox_event(const BlackboxEvent& event) {
  char line[256];
  std::snprintf(line, sizeof(line), "%s  %-13" PRIu64 " %-18s %-16s %-12" PRId64 " %s",
                utc_text(event.wall_time_ns).c_str(), event.tick,
                std::string(to_string(event.kind)).c_str(), std::string(event.node_name()).c_str(),
                event.value, std::string(event.detail_text()).c_str());
  return line;
}

std::string format_blackbox_tick(const BlackboxTick& tick) {
  char head[160];
  std::snprintf(head, sizeof(head), "%s  %-16s %-13" PRIu64 " %12.1f  ",
                utc_text(tick.wall_time_ns).c_str(), std::string(tick.node_name()).c_str(),
                tick.tick, static_cast<double>(tick.duration_ns) / 1000.0);
  std::string line = head;
  for (std::uint32_t i = 0; i < tick.topic_count; ++i) {
    const BlackboxTopic& topic = tick.topics[i];
    if (i > 0) line += ", ";
    line += topic.topic_name();
    line += ' ';
    line += std::to_string(topic.sent);
    line += '/';
    line += std::to_string(topic.received);
  }
  if (tick.other_messages > 0) {
    line += (tick.topic_count > 0 ? ", " : "");
    line += "+" + std::to_string(tick.other_messages) + " messages on further topics";
  }
  if (tick.topic_count == 0 && tick.other_messages == 0) line += "-";
  return line;
}

}  // namespace horus
