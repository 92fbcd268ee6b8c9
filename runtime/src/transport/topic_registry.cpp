// Reading segments for tools: validated like any opener, mapped read-only, under a shared lock.
#include "horus/topic_registry.hpp"
#include "horus/detail/errno_text.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "horus/detail/created_segments.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/error.hpp"

namespace horus {

namespace {

using detail::ControlBlock;
using detail::kControlSize;
using detail::LayoutHeader;

std::vector<std::string> segment_names(const std::string& directory) {
  std::vector<std::string> names;
  DIR* dir = ::opendir(directory.c_str());
  if (dir == nullptr) {
    if (errno == ENOENT) {
      return names;
    }
    throw Error("cannot list topic directory " + directory + ": " + detail::errno_text(errno));
  }
  // This DIR stream is local to the call, which is all readdir needs to be safe.
  while (const dirent* entry = ::readdir(dir)) {  // NOLINT(concurrency-mt-unsafe)
    const std::string_view name = entry->d_name;
    if (name != "." && name != "..") {
      names.emplace_back(name);
    }
  }
  ::closedir(dir);
  std::sort(names.begin(), names.end());
  return names;
}

class LockedFile {
 public:
  LockedFile(const std::string& path, int flags, int lock)
      : fd_(::open(path.c_str(), flags | O_CLOEXEC | O_NOFOLLOW)) {
    if (fd_ >= 0) {
      while (::flock(fd_, lock) != 0 && errno == EINTR) {
      }
    }
  }
  LockedFile(const LockedFile&) = delete;
  LockedFile& operator=(const LockedFile&) = delete;
  ~LockedFile() {
    if (fd_ >= 0) {
      ::flock(fd_, LOCK_UN);
      ::close(fd_);
    }
  }
  int fd() const { return fd_; }

 private:
  int fd_;
};

void inspect(const std::string& path, TopicInfo& info) {
  const LockedFile file(path, O_RDONLY, LOCK_SH);
  struct stat status {};
  if (file.fd() < 0 || ::fstat(file.fd(), &status) != 0) {
    info.error = std::string("cannot open: ") + detail::errno_text(errno);
    return;
  }
  if (!S_ISREG(status.st_mode)) {
    info.error = "not a regular file";
    return;
  }
  const auto size = static_cast<std::uint64_t>(status.st_size);
  if (size < kControlSize) {
    info.error = "truncated: " + std::to_string(size) + " bytes";
    return;
  }
  void* base = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, file.fd(), 0);
  if (base == MAP_FAILED) {
    info.error = std::string("cannot map: ") + detail::errno_text(errno);
    return;
  }
  const auto* bytes = static_cast<const std::byte*>(base);
  const auto& control = *reinterpret_cast<const ControlBlock*>(bytes);
  info.error = detail::validate_control(control);
  if (info.error.empty()) {
    info.single_publisher = control.ring.single_publisher.load(std::memory_order_acquire) == 1;
    info.message_count = detail::ring_written(control.ring);
    for (const detail::UserEntry& user : control.users) {
      const std::uint32_t roles = user.roles.load(std::memory_order_relaxed);
      if (detail::identity_alive(user.process.load(std::memory_order_acquire))) {
        info.publishers += (roles & detail::kRolePublisher) != 0 ? 1 : 0;
        info.subscribers += (roles & detail::kRoleSubscriber) != 0 ? 1 : 0;
      }
    }
  }
  if (info.error.empty() && control.layout_ready.load(std::memory_order_acquire) == 1) {
    LayoutHeader header{};
    if (size < kControlSize + sizeof header) {
      info.error = "truncated: " + std::to_string(size) + " bytes";
    } else {
      std::memcpy(&header, bytes + kControlSize, sizeof header);
      info.error = detail::validate_layout(header, size);
    }
    if (info.error.empty()) {
      info.type_name.assign(header.type_name, header.type_name_size);
      info.fingerprint = header.fingerprint;
      info.schema.assign(reinterpret_cast<const char*>(bytes + header.schema_offset),
                         header.schema_size);
      info.is_pod = header.is_pod != 0;
      info.capacity = header.capacity;
      info.max_message_size = header.payload_capacity;
      const std::uint64_t depth = std::min(info.message_count, header.capacity);
      for (std::uint64_t back = 1; back <= depth; ++back) {
        const std::uint64_t ticket = info.message_count - back;
        const std::uint64_t index = ticket & (header.capacity - 1);
        const auto& slot = *reinterpret_cast<const detail::SlotHeader*>(
            bytes + header.slots_offset + index * header.slot_stride);
        const std::uint64_t committed = 2 * ticket + 2;
        if (slot.seq.load(std::memory_order_acquire) == committed) {
          const std::uint32_t sent = slot.send_time_s.load(std::memory_order_relaxed);
          detail::seqlock_fence(std::memory_order_acquire);
          if (slot.seq.load(std::memory_order_relaxed) == committed) {
            info.last_send = std::chrono::system_clock::time_point(std::chrono::seconds(sent));
            break;
          }
        }
      }
    }
  }
  ::munmap(base, size);
}

}  // namespace

namespace detail {

bool remove_if_abandoned(const std::string& path) {
  const LockedFile file(path, O_RDONLY, LOCK_EX);
  struct stat status {};
  if (file.fd() < 0 || ::fstat(file.fd(), &status) != 0 || !S_ISREG(status.st_mode) ||
      static_cast<std::uint64_t>(status.st_size) < kControlSize) {
    return false;
  }
  void* base = ::mmap(nullptr, kControlSize, PROT_READ, MAP_SHARED, file.fd(), 0);
  if (base == MAP_FAILED) {
    return false;
  }
  const bool in_use = detail::segment_in_use(*static_cast<const ControlBlock*>(base));
  ::munmap(base, kControlSize);
  // Unlinked while the exclusive lock is held, so no opener can be setting it up meanwhile;
  // an opener that opened the path before re-checks the inode after locking (open_locked).
  return !in_use && ::unlink(path.c_str()) == 0;
}

}  // namespace detail

std::string current_namespace() { return detail::current_namespace(); }

std::vector<TopicInfo> list_topics(std::string_view namespace_name) {
  const std::string directory = detail::namespace_directory(namespace_name);
  std::vector<TopicInfo> topics;
  for (const std::string& name : segment_names(directory)) {
    TopicInfo info;
    info.name = name;
    inspect(directory + "/" + name, info);
    topics.push_back(std::move(info));
  }
  return topics;
}

std::size_t clean_namespace(std::string_view namespace_name) {
  const std::string directory = detail::namespace_directory(namespace_name);
  std::size_t removed = 0;
  for (const std::string& name : segment_names(directory)) {
    removed += detail::remove_if_abandoned(directory + "/" + name) ? 1 : 0;
  }
  ::rmdir(directory.c_str());
  return removed;
}

void remove_namespace(std::string_view namespace_name) {
  const std::string directory = detail::namespace_directory(namespace_name);
  for (const std::string& name : segment_names(directory)) {
    ::unlink((directory + "/" + name).c_str());
  }
  ::rmdir(directory.c_str());
}

}  // namespace horus
