// Reading segments for tools: validated like any opener, mapped read-only, under a shared lock.
#include "horus/topic_registry.hpp"
#include "horus/internal/errno_text.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <optional>

#include "horus/detail/shm_segment.hpp"
#include "horus/error.hpp"
#include "horus/frames.hpp"
#include "horus/internal/created_segments.hpp"
#include "horus/internal/namespace_objects.hpp"

namespace horus {

namespace {

using detail::ControlBlock;
using detail::kControlSize;
using detail::LayoutHeader;

/// Tools read the segments of their own user and of the groups they are in (read-only), so a
/// namespace shared through a group lists whole.
constexpr unsigned kToolAccess = 0660;

/// The names in a checked namespace folder (none when it does not exist).
std::vector<std::string> segment_names(const detail::NamespaceFolder& folder) {
  if (folder.descriptor.get() < 0) {
    return {};
  }
  return detail::folder_entries(folder.descriptor.get(), folder.path);
}

const detail::SlotHeader& slot_of(const std::byte* bytes, const LayoutHeader& header,
                                  std::uint64_t ticket) {
  return *reinterpret_cast<const detail::SlotHeader*>(
      bytes + header.slots_offset + (ticket & (header.capacity - 1)) * header.slot_stride);
}

void count_traffic(const std::byte* bytes, const LayoutHeader& header, std::uint64_t written,
                   std::uint64_t since, TopicTraffic& traffic) {
  traffic.message_count = written;
  const std::uint64_t oldest = written > header.capacity ? written - header.capacity : 0;
  for (std::uint64_t ticket = std::max(since, oldest); ticket < written; ++ticket) {
    const detail::SlotHeader& slot = slot_of(bytes, header, ticket);
    const std::uint64_t committed = 2 * ticket + 2;
    if (slot.seq.load(std::memory_order_acquire) != committed) continue;
    const std::uint32_t size = slot.size.load(std::memory_order_relaxed);
    detail::seqlock_fence(std::memory_order_acquire);
    if (slot.seq.load(std::memory_order_relaxed) == committed && size != detail::kReleasedSlot) {
      ++traffic.counted;
      traffic.bytes += size;
    }
  }
  bool follows = false;  // whether the ticket just before was read, stamped `previous`
  std::uint32_t previous = 0;
  for (std::uint64_t ticket = oldest; ticket < written; ++ticket) {
    const detail::SlotHeader& slot = slot_of(bytes, header, ticket);
    const std::uint64_t committed = 2 * ticket + 2;
    const bool read = slot.seq.load(std::memory_order_acquire) == committed;
    const std::uint32_t sent = slot.send_time_s.load(std::memory_order_relaxed);
    detail::seqlock_fence(std::memory_order_acquire);
    if (!read || slot.seq.load(std::memory_order_relaxed) != committed) {
      follows = false;
      continue;
    }
    if (follows && sent > previous) {
      if (!traffic.first_new_second) traffic.first_new_second = SendStamp{ticket, sent};
      traffic.last_new_second = SendStamp{ticket, sent};
    }
    follows = true;
    previous = sent;
    traffic.newest = SendStamp{ticket, sent};
  }
}

/// A segment opened read-only and checked like any opener would, under `lock`.
class LockedFile {
 public:
  LockedFile(const detail::NamespaceFolder& folder, const std::string& name, int lock)
      : file_(detail::open_trusted_file(folder.descriptor.get(), name, folder.path + "/" + name,
                                        O_RDONLY, 0, detail::group_sharing(kToolAccess))) {
    while (::flock(file_.get(), lock) != 0 && errno == EINTR) {
    }
  }
  LockedFile(const LockedFile&) = delete;
  LockedFile& operator=(const LockedFile&) = delete;
  ~LockedFile() { ::flock(file_.get(), LOCK_UN); }
  int fd() const { return file_.get(); }

 private:
  detail::FileDescriptor file_;
};

/// Fills `info` from the segment; with `traffic`, also counts the payload bytes of the messages
/// from ticket `since` on that are still in the ring (slot headers only, nothing decoded).
void inspect(const detail::NamespaceFolder& folder, TopicInfo& info,
             TopicTraffic* traffic = nullptr, std::uint64_t since = 0) {
  std::optional<LockedFile> file;
  try {
    file.emplace(folder, info.name, LOCK_SH);
  } catch (const Error& e) {
    info.error = e.what();
    return;
  }
  struct stat status {};
  if (::fstat(file->fd(), &status) != 0) {
    info.error = std::string("cannot stat: ") + detail::errno_text(errno);
    return;
  }
  const auto size = static_cast<std::uint64_t>(status.st_size);
  if (size < kControlSize) {
    info.error = "truncated: " + std::to_string(size) + " bytes";
    return;
  }
  void* base = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, file->fd(), 0);
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
    const std::uint64_t here = detail::this_process_identity();
    for (const detail::UserEntry& user : control.users) {
      const std::uint32_t roles = user.roles.load(std::memory_order_relaxed);
      const std::uint64_t process = user.process.load(std::memory_order_acquire);
      if (process == here && (roles & detail::kRoleNotifier) == 0) info.open_here = true;
      if (detail::identity_alive(process)) {
        info.publishers += (roles & detail::kRolePublisher) != 0 ? 1 : 0;
        info.subscribers += (roles & detail::kRoleSubscriber) != 0 ? 1 : 0;
        info.user_pids.push_back(detail::identity_pid(process));
      }
    }
    std::sort(info.user_pids.begin(), info.user_pids.end());
    info.user_pids.erase(std::unique(info.user_pids.begin(), info.user_pids.end()),
                         info.user_pids.end());
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
      info.description.assign(reinterpret_cast<const char*>(bytes + header.description_offset),
                              header.description_size);
      info.is_pod = header.is_pod != 0;
      info.capacity = header.capacity;
      info.max_message_size = header.payload_capacity;
      if (traffic != nullptr) {
        count_traffic(bytes, header, info.message_count, since, *traffic);
      }
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

bool remove_if_abandoned(const detail::NamespaceFolder& folder, const std::string& name) {
  std::optional<LockedFile> file;
  try {
    file.emplace(folder, name, LOCK_EX);
  } catch (const Error&) {
    return false;  // not this user's to judge (or gone meanwhile)
  }
  struct stat status {};
  if (::fstat(file->fd(), &status) != 0 ||
      static_cast<std::uint64_t>(status.st_size) < kControlSize) {
    return false;
  }
  void* base = ::mmap(nullptr, kControlSize, PROT_READ, MAP_SHARED, file->fd(), 0);
  if (base == MAP_FAILED) {
    return false;
  }
  const bool in_use = detail::segment_in_use(*static_cast<const ControlBlock*>(base));
  ::munmap(base, kControlSize);
  // Unlinked while the exclusive lock is held, so no opener can be setting it up meanwhile;
  // an opener that opened the path before re-checks the inode after locking (open_locked).
  return !in_use && ::unlinkat(folder.descriptor.get(), name.c_str(), 0) == 0;
}

}  // namespace detail

namespace {

/// Removes the namespace folder once it is empty (a folder still in use stays).
void remove_folder_if_empty(const detail::NamespaceFolder& folder) {
  const std::string root = detail::shm_root();
  const detail::FileDescriptor root_folder(
      ::open(root.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC));
  const std::string name = folder.path.substr(root.size() + 1);
  if (root_folder.get() >= 0) {
    ::unlinkat(root_folder.get(), name.c_str(), AT_REMOVEDIR);
  }
}

}  // namespace

std::string current_namespace() { return detail::current_namespace(); }

std::string namespace_directory(std::string_view namespace_name) {
  return detail::namespace_directory(namespace_name);
}

std::size_t remove_created_topics_nobody_uses() {
  return detail::remove_created_segments_nobody_uses();
}

std::vector<TopicInfo> list_topics(std::string_view namespace_name) {
  const detail::NamespaceFolder folder =
      detail::open_namespace_folder(namespace_name, kToolAccess, false);
  std::vector<TopicInfo> topics;
  for (const std::string& name : segment_names(folder)) {
    TopicInfo info;
    info.name = name;
    inspect(folder, info);
    topics.push_back(std::move(info));
  }
  return topics;
}

TopicTraffic topic_traffic(std::string_view topic, std::uint64_t since,
                           std::string_view namespace_name) {
  detail::validate_segment_name("topic", topic);
  const detail::NamespaceFolder folder =
      detail::open_namespace_folder(namespace_name, kToolAccess, false);
  TopicInfo info;
  info.name = topic;
  TopicTraffic traffic;
  if (folder.descriptor.get() >= 0) {
    inspect(folder, info, &traffic, since);
  }
  if (folder.descriptor.get() < 0 || !info.error.empty()) {
    throw Error("topic '" + std::string(topic) +
                "': " + (info.error.empty() ? "no such topic" : info.error));
  }
  return traffic;
}

std::size_t clean_namespace(std::string_view namespace_name) {
  const detail::NamespaceFolder folder =
      detail::open_namespace_folder(namespace_name, kToolAccess, false);
  std::size_t removed = 0;
  for (const std::string& name : segment_names(folder)) {
    removed += detail::remove_if_abandoned(folder, name) ? 1 : 0;
  }
  remove_folder_if_empty(folder);
  detail::remove_log_ring(namespace_name, false);
  detail::remove_presence_folder(namespace_name, false);
  detail::remove_param_stores(namespace_name, false);
  detail::remove_unused_frame_tree(namespace_name);
  return removed;
}

void remove_namespace(std::string_view namespace_name) {
  const detail::NamespaceFolder folder =
      detail::open_namespace_folder(namespace_name, kToolAccess, false);
  for (const std::string& name : segment_names(folder)) {
    ::unlinkat(folder.descriptor.get(), name.c_str(), 0);
  }
  remove_folder_if_empty(folder);
  detail::remove_log_ring(namespace_name, true);
  detail::remove_presence_folder(namespace_name, true);
  detail::remove_param_stores(namespace_name, true);
  remove_frame_tree(namespace_name);
}

std::vector<NamespaceObjectInfo> list_namespace_objects(std::string_view namespace_name) {
  std::vector<NamespaceObjectInfo> objects;
  if (auto ring = detail::log_ring_object(namespace_name)) objects.push_back(std::move(*ring));
  if (auto folder = detail::presence_folder_object(namespace_name)) {
    objects.push_back(std::move(*folder));
  }
  for (NamespaceObjectInfo& store : detail::param_store_objects(namespace_name)) {
    objects.push_back(std::move(store));
  }
  if (auto tree = detail::frame_tree_object(namespace_name)) objects.push_back(std::move(*tree));
  return objects;
}

}  // namespace horus
