// The log ring's slot protocol, its shared-memory file and read_log().
#include "log_ring.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <optional>

#include "horus/detail/shm_access.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/error.hpp"
#include "horus/internal/errno_text.hpp"
#include "horus/internal/namespace_objects.hpp"

namespace horus::detail {
namespace {

constexpr std::size_t kSharedCapacity = 4096;  // 2 MiB per namespace

constexpr const char* kLogsFolder = "@logs";

std::string logs_directory() { return shm_root() + "/" + kLogsFolder; }

/// The checked folder of the log rings (this user's, never writable by others), or a descriptor
/// of -1 when it is missing and not `create`d.
FileDescriptor open_logs_folder(bool create) {
  const std::string root = shm_root();
  const FileDescriptor root_folder =
      open_trusted_directory(AT_FDCWD, root, root, 0600, true, false, create);
  if (root_folder.get() < 0) return FileDescriptor();
  return open_trusted_directory(root_folder.get(), kLogsFolder, logs_directory(), 0600, false,
                                false, create);
}

std::string ring_name(std::string_view namespace_name) {
  std::string name = namespace_name.empty() ? current_namespace() : std::string(namespace_name);
  validate_segment_name("namespace", name);
  return name;
}

}  // namespace

void LogRing::format(void* memory, std::size_t capacity) noexcept {
  auto* header = static_cast<LogRingHeader*>(memory);
  header->version = kLogVersion;
  header->slot_size = sizeof(LogSlot);
  header->capacity = capacity;
  header->next_ticket.store(0, std::memory_order_relaxed);
  header->dropped.store(0, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  header->magic = kLogMagic;
}

std::string LogRing::validate(const void* memory, std::size_t size) {
  if (size < sizeof(LogRingHeader)) return "shorter than a log ring header";
  const auto* header = static_cast<const LogRingHeader*>(memory);
  if (header->magic != kLogMagic) return "not a horus log ring (bad magic)";
  if (header->version != kLogVersion) {
    return "log ring version " + std::to_string(header->version) + ", this build reads " +
           std::to_string(kLogVersion);
  }
  if (header->slot_size != sizeof(LogSlot)) return "unexpected slot size";
  const std::uint64_t capacity = header->capacity;
  if (capacity == 0 || (capacity & (capacity - 1)) != 0 || capacity > (1U << 24)) {
    return "capacity is not a power of two";
  }
  if (size != bytes_for(capacity)) return "file size does not match its capacity";
  return {};
}

bool LogRing::push(const LogEntry& entry) noexcept {
  const std::uint64_t ticket = header_->next_ticket.fetch_add(1, std::memory_order_relaxed);
  LogSlot& slot = slots_[ticket & mask_];
  std::uint64_t current = slot.seq.load(std::memory_order_acquire);
  // A writer of an earlier lap still in the slot (or, after a long preemption, a later lap
  // already there): waiting could block a real-time thread, so this line is given up.
  if ((current & 1) != 0 || current > 2 * ticket ||
      !slot.seq.compare_exchange_strong(current, 2 * ticket + 1, std::memory_order_acq_rel)) {
    header_->dropped.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  std::array<std::uint64_t, kLogEntryWords> words;
  std::memcpy(words.data(), &entry, sizeof(entry));
  // Each word's release store publishes the odd seq before it: a reader that sees a new word also
  // sees the slot as being written (no fences, which ThreadSanitizer cannot model).
  for (std::size_t i = 0; i < kLogEntryWords; ++i) {
    slot.words[i].store(words[i], std::memory_order_release);
  }
  slot.seq.store(2 * ticket + 2, std::memory_order_release);
  return true;
}

LogRing::Read LogRing::read(std::uint64_t ticket, LogEntry& out) const noexcept {
  const LogSlot& slot = slots_[ticket & mask_];
  const std::uint64_t before = slot.seq.load(std::memory_order_acquire);
  if (before > 2 * ticket + 2) return Read::Lost;
  if (before != 2 * ticket + 2) return Read::Pending;
  std::array<std::uint64_t, kLogEntryWords> words;
  for (std::size_t i = 0; i < kLogEntryWords; ++i) {
    words[i] = slot.words[i].load(std::memory_order_acquire);
  }
  if (slot.seq.load(std::memory_order_relaxed) != before) return Read::Lost;
  std::memcpy(static_cast<void*>(&out), words.data(), sizeof(out));
  // Another process wrote these sizes: never trust them past the arrays.
  out.source_size = std::min<std::uint8_t>(out.source_size, kMaxLogSource);
  out.text_size = std::min<std::uint16_t>(out.text_size, kMaxLogText);
  return Read::Ready;
}

std::string shared_log_ring_path(std::string_view namespace_name) {
  return logs_directory() + "/" + ring_name(namespace_name);
}

namespace {

/// A new ring made unnamed (O_TMPFILE), formatted and locked shared before it gets its name, so
/// that nobody ever sees it half done and no cleaner can take it; nothing when another process
/// named its own first.
std::optional<LogRing> create_shared_log_ring(int folder, const std::string& name,
                                              const std::string& path) {
  const FileDescriptor fd(::openat(folder, ".", O_TMPFILE | O_RDWR | O_CLOEXEC, 0600));
  if (fd.get() < 0) {
    throw Error("cannot create the log ring " + path + ": " + errno_text(errno));
  }
  const std::size_t size = LogRing::bytes_for(kSharedCapacity);
  if (::ftruncate(fd.get(), static_cast<off_t>(size)) != 0) {
    throw Error("cannot size the log ring " + path + ": " + errno_text(errno));
  }
  void* memory = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED, fd.get(), 0);
  if (memory == MAP_FAILED) {
    throw Error("cannot map the log ring " + path + ": " + errno_text(errno));
  }
  LogRing::format(memory, kSharedCapacity);
  // Nobody else can reach an unnamed file: neither lock nor link can be raced here.
  ::flock(fd.get(), LOCK_SH);
  const std::string self = "/proc/self/fd/" + std::to_string(fd.get());
  if (::linkat(AT_FDCWD, self.c_str(), folder, name.c_str(), AT_SYMLINK_FOLLOW) != 0) {
    const int error = errno;
    ::munmap(memory, size);
    if (error == EEXIST) return std::nullopt;
    throw Error("cannot name the log ring " + path + ": " + errno_text(error));
  }
  return LogRing(memory);
}

}  // namespace

LogRing open_shared_log_ring(std::string_view namespace_name) {
  const std::string name = ring_name(namespace_name);
  const std::string path = shared_log_ring_path(namespace_name);
  const FileDescriptor folder = open_logs_folder(true);
  // Every writer keeps a shared lock on the ring while its mapping lives (the mapping holds the
  // open file description, and so the lock, past close and until the process exits): cleaners
  // leave the ring alone meanwhile (internal/namespace_objects.hpp). Nobody holds the exclusive
  // lock but a cleaner, and only for as long as it takes to unlink.
  for (;;) {
    struct stat named {};
    if (::fstatat(folder.get(), name.c_str(), &named, AT_SYMLINK_NOFOLLOW) != 0 &&
        errno == ENOENT) {
      if (std::optional<LogRing> ring = create_shared_log_ring(folder.get(), name, path)) {
        return *ring;
      }
      continue;  // another process named its ring first: use that one
    }
    std::optional<FileDescriptor> fd;
    try {
      fd.emplace(open_trusted_file(folder.get(), name, path, O_RDWR, 0, false));
    } catch (const Error&) {
      if (::fstatat(folder.get(), name.c_str(), &named, AT_SYMLINK_NOFOLLOW) != 0 &&
          errno == ENOENT) {
        continue;  // a cleaner removed it between the look and the open
      }
      throw;
    }
    if (::flock(fd->get(), LOCK_SH) != 0) {
      throw Error("cannot lock the log ring " + path + ": " + errno_text(errno));
    }
    if (!still_linked(fd->get())) continue;  // a cleaner removed it before we locked
    struct stat info {};
    if (::fstat(fd->get(), &info) != 0) {
      throw Error("cannot stat the log ring " + path + ": " + errno_text(errno));
    }
    const auto size = static_cast<std::size_t>(info.st_size);
    void* memory = size == 0
                       ? MAP_FAILED
                       : ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED, fd->get(), 0);
    if (memory == MAP_FAILED) {
      throw Error("cannot map the log ring " + path + ": " +
                  (size == 0 ? std::string("it is empty") : errno_text(errno)));
    }
    if (const std::string why = LogRing::validate(memory, size); !why.empty()) {
      ::munmap(memory, size);
      throw Error("log ring " + path + ": " + why);
    }
    return LogRing(memory);
  }
}

std::optional<NamespaceObjectInfo> log_ring_object(std::string_view namespace_name) {
  const std::string name = ring_name(namespace_name);
  const FileDescriptor folder = open_logs_folder(false);
  struct stat present {};
  if (folder.get() < 0 ||
      ::fstatat(folder.get(), name.c_str(), &present, AT_SYMLINK_NOFOLLOW) != 0) {
    return std::nullopt;
  }
  NamespaceObjectInfo info;
  info.kind = kLogsFolder;
  info.path = shared_log_ring_path(namespace_name);
  info.size = static_cast<std::size_t>(present.st_size);
  const FileDescriptor fd = open_trusted_file(folder.get(), name, info.path, O_RDONLY, 0, false);
  info.in_use = ::flock(fd.get(), LOCK_EX | LOCK_NB) != 0;
  return info;
}

bool remove_log_ring(std::string_view namespace_name, bool force) {
  const std::string name = ring_name(namespace_name);
  const FileDescriptor folder = open_logs_folder(false);
  if (folder.get() < 0) return false;
  if (force) return ::unlinkat(folder.get(), name.c_str(), 0) == 0;
  std::optional<FileDescriptor> fd;
  try {
    fd.emplace(open_trusted_file(folder.get(), name, shared_log_ring_path(namespace_name), O_RDONLY,
                                 0, false));
  } catch (const Error&) {
    return false;  // none, or not this user's to judge
  }
  // Held until the descriptor closes: a writer opening the ring meanwhile waits, then sees it
  // unlinked and makes a new one.
  return ::flock(fd->get(), LOCK_EX | LOCK_NB) == 0 && still_linked(fd->get()) &&
         ::unlinkat(folder.get(), name.c_str(), 0) == 0;
}

std::size_t format_log_entry(const LogEntry& entry, char* out, std::size_t size) noexcept {
  using namespace std::chrono;
  const sys_time<nanoseconds> when{nanoseconds(entry.wall_time_ns)};
  const sys_days day = floor<days>(when);
  const year_month_day date{day};
  const hh_mm_ss<milliseconds> time{floor<milliseconds>(when - day)};
  const std::string_view level =
      to_string(static_cast<LogLevel>(std::min<std::uint8_t>(entry.level, 3)));
  const std::string_view source = entry.source_size > 0 ? entry.source_text() : "-";
  const int n = std::snprintf(
      out, size, "%04d-%02u-%02uT%02d:%02d:%02d.%03dZ %.*s %.*s: %.*s",
      static_cast<int>(date.year()), static_cast<unsigned>(date.month()),
      static_cast<unsigned>(date.day()), static_cast<int>(time.hours().count()),
      static_cast<int>(time.minutes().count()), static_cast<int>(time.seconds().count()),
      static_cast<int>(time.subseconds().count()), static_cast<int>(level.size()), level.data(),
      static_cast<int>(source.size()), source.data(), static_cast<int>(entry.message().size()),
      entry.message().data());
  if (n < 0) return 0;
  return std::min(static_cast<std::size_t>(n), size - 1);
}

}  // namespace horus::detail

namespace horus {

std::string format_log_line(const LogRecord& record) {
  detail::LogEntry entry{};
  entry.wall_time_ns = record.wall_time_ns;
  entry.pid = record.pid;
  entry.level = static_cast<std::uint8_t>(record.level);
  entry.source_size = static_cast<std::uint8_t>(std::min(record.source.size(), kMaxLogSource));
  std::memcpy(entry.source, record.source.data(), entry.source_size);
  entry.text_size = static_cast<std::uint16_t>(std::min(record.message.size(), kMaxLogText));
  std::memcpy(entry.text, record.message.data(), entry.text_size);
  char line[640];
  return {line, detail::format_log_entry(entry, line, sizeof(line))};
}

LogSnapshot read_log(std::string_view namespace_name) {
  const std::string path = detail::shared_log_ring_path(namespace_name);
  const std::string name = detail::ring_name(namespace_name);
  LogSnapshot snapshot;
  const detail::FileDescriptor folder = detail::open_logs_folder(false);
  struct stat present {};
  if (folder.get() < 0 ||
      (::fstatat(folder.get(), name.c_str(), &present, AT_SYMLINK_NOFOLLOW) != 0 &&
       errno == ENOENT)) {
    return snapshot;
  }
  const detail::FileDescriptor fd =
      detail::open_trusted_file(folder.get(), name, path, O_RDONLY, 0600, false);
  struct stat info {};
  if (::fstat(fd.get(), &info) != 0) {
    throw Error("cannot stat the log ring " + path + ": " + detail::errno_text(errno));
  }
  const auto size = static_cast<std::size_t>(info.st_size);
  if (size == 0) return snapshot;
  void* memory = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, fd.get(), 0);
  if (memory == MAP_FAILED) {
    throw Error("cannot map the log ring " + path + ": " + detail::errno_text(errno));
  }
  struct Unmap {
    void* memory;
    std::size_t size;
    ~Unmap() { ::munmap(memory, size); }
  } unmap{memory, size};
  if (const std::string why = detail::LogRing::validate(memory, size); !why.empty()) {
    throw Error("log ring " + path + ": " + why);
  }
  const detail::LogRing ring(memory);
  const std::uint64_t next = ring.next_ticket();
  snapshot.written = next;
  snapshot.dropped = ring.dropped();
  const std::uint64_t first = next > ring.capacity() ? next - ring.capacity() : 0;
  detail::LogEntry entry{};
  for (std::uint64_t ticket = first; ticket < next; ++ticket) {
    if (ring.read(ticket, entry) != detail::LogRing::Read::Ready) continue;
    LogRecord record;
    record.sequence = ticket;
    record.wall_time_ns = entry.wall_time_ns;
    record.pid = entry.pid;
    record.level = static_cast<LogLevel>(std::min<std::uint8_t>(entry.level, 3));
    record.source = std::string(entry.source_text());
    record.message = std::string(entry.message());
    snapshot.records.push_back(std::move(record));
  }
  return snapshot;
}

}  // namespace horus
