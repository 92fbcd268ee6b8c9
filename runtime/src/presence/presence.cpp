// The presence registry's files: the announcement a Scheduler rewrites, and the readers tools use.
#include "horus/presence.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cinttypes>
#include <condition_variable>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <string>
#include <thread>
#include <tuple>

#include "horus/detail/process.hpp"
#include "horus/detail/shm_access.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/error.hpp"
#include "horus/internal/errno_text.hpp"
#include "horus/internal/namespace_objects.hpp"
#include "horus/json_string.hpp"

namespace horus {
namespace {

constexpr const char* kPresenceFolder = "@presence";
/// The first line of every announcement: format version, identity, update time.
constexpr const char* kHeaderFormat = "horus-presence 1 %" PRIu64 " %" PRId64 "\n";
/// An announcement larger than this is not one (a scheduler of thousands of nodes stays below).
constexpr off_t kMaxAnnouncement = 4 << 20;

std::string namespace_of(std::string_view namespace_name) {
  std::string name =
      namespace_name.empty() ? detail::current_namespace() : std::string(namespace_name);
  detail::validate_segment_name("namespace", name);
  return name;
}

/// The checked folder <root>/@presence (this user's only), or -1 when missing and not `create`d.
detail::FileDescriptor open_presence_root(bool create) {
  const std::string root = detail::shm_root();
  const detail::FileDescriptor root_folder =
      detail::open_trusted_directory(AT_FDCWD, root, root, 0600, true, false, create);
  if (root_folder.get() < 0) return detail::FileDescriptor();
  return detail::open_trusted_directory(root_folder.get(), kPresenceFolder,
                                        root + "/" + kPresenceFolder, 0600, false, false, create);
}

std::string presence_path(const std::string& namespace_name) {
  return detail::shm_root() + "/" + kPresenceFolder + "/" + namespace_name;
}

/// The checked folder <root>/@presence/<namespace> (this user's only), or -1 when missing and
/// not `create`d.
detail::FileDescriptor open_presence_folder(const std::string& namespace_name, bool create) {
  const detail::FileDescriptor presence_folder = open_presence_root(create);
  if (presence_folder.get() < 0) return detail::FileDescriptor();
  return detail::open_trusted_directory(presence_folder.get(), namespace_name,
                                        presence_path(namespace_name), 0600, false, false, create);
}

/// Entry names ("<pid>.<n>"; the ".tmp" files being written are skipped unless
/// `with_temporaries`), sorted.
std::vector<std::string> entry_names(int folder, const std::string& path,
                                     bool with_temporaries = false) {
  std::vector<std::string> names = detail::folder_entries(folder, path);
  if (!with_temporaries) {
    std::erase_if(names,
                  [](const std::string& name) { return name.find(".tmp") != std::string::npos; });
  }
  return names;
}

/// Reads one announcement; its identity goes to `identity`.
PresenceInfo read_entry(int folder, const std::string& folder_path, const std::string& name,
                        std::uint64_t& identity) {
  PresenceInfo info;
  info.entry = name;
  identity = 0;
  try {
    const detail::FileDescriptor file =
        detail::open_trusted_file(folder, name, folder_path + "/" + name, O_RDONLY, 0, false);
    struct stat status {};
    if (::fstat(file.get(), &status) != 0) {
      info.error = "cannot stat: " + detail::errno_text(errno);
      return info;
    }
    if (status.st_size > kMaxAnnouncement) {
      info.error = "not an announcement: " + std::to_string(status.st_size) + " bytes";
      return info;
    }
    std::string text(static_cast<std::size_t>(status.st_size), '\0');
    std::size_t done = 0;
    while (done < text.size()) {
      const ssize_t got =
          ::pread(file.get(), text.data() + done, text.size() - done, static_cast<off_t>(done));
      if (got < 0 && errno == EINTR) continue;
      if (got <= 0) break;
      done += static_cast<std::size_t>(got);
    }
    text.resize(done);
    std::int64_t updated = 0;
    int header_size = 0;
    if (std::sscanf(text.c_str(), "horus-presence 1 %" SCNu64 " %" SCNd64 "\n%n", &identity,
                    &updated, &header_size) != 2 ||
        header_size <= 0) {
      info.error = "not an announcement (bad header)";
      return info;
    }
    info.pid = detail::identity_pid(identity);
    info.started_wall_ns = detail::identity_start_wall_ns(identity);
    info.updated_wall_ns = updated;
    info.snapshot_json = text.substr(static_cast<std::size_t>(header_size));
    info.alive = detail::identity_alive(identity);
  } catch (const Error& e) {
    info.error = e.what();
  }
  return info;
}

std::atomic<std::uint32_t> announcements_made{0};

}  // namespace

std::vector<PresenceInfo> list_presence(std::string_view namespace_name) {
  const std::string name = namespace_of(namespace_name);
  const detail::FileDescriptor folder = open_presence_folder(name, false);
  std::vector<PresenceInfo> out;
  if (folder.get() < 0) return out;
  const std::string path = presence_path(name);
  for (const std::string& entry : entry_names(folder.get(), path)) {
    std::uint64_t identity = 0;
    out.push_back(read_entry(folder.get(), path, entry, identity));
  }
  return out;
}

std::size_t clean_presence(std::string_view namespace_name) {
  const std::string name = namespace_of(namespace_name);
  const detail::FileDescriptor folder = open_presence_folder(name, false);
  if (folder.get() < 0) return 0;
  const std::string path = presence_path(name);
  std::size_t removed = 0;
  for (const std::string& entry : entry_names(folder.get(), path, true)) {
    bool dead = false;
    if (entry.ends_with(".tmp")) {
      // An announcement being written ("<pid>.<n>.tmp"): its writer was killed mid-write when
      // that pid runs no more, and the half-written file would keep the folder forever.
      std::uint32_t pid = 0;
      const auto [end, error] = std::from_chars(entry.data(), entry.data() + entry.size(), pid);
      dead = error == std::errc() && *end == '.' && !detail::identity_alive(pid);
    } else {
      std::uint64_t identity = 0;
      const PresenceInfo info = read_entry(folder.get(), path, entry, identity);
      // Only a readable announcement of a process known dead goes; anything else is left alone.
      dead = info.error.empty() && !info.alive;
    }
    if (dead && ::unlinkat(folder.get(), entry.c_str(), 0) == 0) ++removed;
  }
  detail::remove_presence_folder(name, false);
  return removed;
}

namespace detail {

std::optional<NamespaceObjectInfo> presence_folder_object(std::string_view namespace_name) {
  const std::string name = namespace_of(namespace_name);
  const FileDescriptor folder = open_presence_folder(name, false);
  if (folder.get() < 0) return std::nullopt;
  NamespaceObjectInfo info;
  info.kind = kPresenceFolder;
  info.path = presence_path(name);
  for (const std::string& entry : entry_names(folder.get(), info.path, true)) {
    struct stat status {};
    if (::fstatat(folder.get(), entry.c_str(), &status, AT_SYMLINK_NOFOLLOW) == 0) {
      info.size += static_cast<std::size_t>(status.st_size);
    }
  }
  info.in_use = ::flock(folder.get(), LOCK_EX | LOCK_NB) != 0;
  return info;
}

bool remove_presence_folder(std::string_view namespace_name, bool force) {
  const std::string name = namespace_of(namespace_name);
  const FileDescriptor presence_root = open_presence_root(false);
  if (presence_root.get() < 0) return false;
  const FileDescriptor folder = open_presence_folder(name, false);
  if (folder.get() < 0) return false;
  if (force) {
    for (const std::string& entry : entry_names(folder.get(), presence_path(name), true)) {
      ::unlinkat(folder.get(), entry.c_str(), 0);
    }
  } else if (::flock(folder.get(), LOCK_EX | LOCK_NB) != 0 || !still_linked(folder.get())) {
    return false;  // a live Scheduler announces here (or another cleaner was first)
  }
  // Only an empty folder goes: an announcement that could not be read is left for a person.
  return ::unlinkat(presence_root.get(), name.c_str(), AT_REMOVEDIR) == 0;
}

}  // namespace detail

namespace detail {

PresenceAnnouncement::PresenceAnnouncement(std::string_view namespace_name)
    : namespace_(namespace_of(namespace_name)) {
  for (;;) {
    FileDescriptor folder = open_presence_folder(namespace_, true);
    // Held while this object lives, before the first announcement too: cleaners leave the folder
    // alone meanwhile (internal/namespace_objects.hpp).
    if (::flock(folder.get(), LOCK_SH) != 0) {
      throw Error("cannot lock the presence directory " + presence_path(namespace_) + ": " +
                  errno_text(errno));
    }
    if (!still_linked(folder.get())) continue;  // a cleaner removed it before we locked
    folder_ = ::fcntl(folder.get(), F_DUPFD_CLOEXEC, 0);
    if (folder_ < 0) {
      throw Error("cannot keep the presence directory open: " + errno_text(errno));
    }
    break;
  }
  entry_ = std::to_string(this_pid()) + "." +
           std::to_string(announcements_made.fetch_add(1, std::memory_order_relaxed));
}

PresenceAnnouncement::~PresenceAnnouncement() {
  ::unlinkat(folder_, entry_.c_str(), 0);
  ::close(folder_);  // drops the lock: the folder goes if no other Scheduler announces there
  try {
    remove_presence_folder(namespace_, false);
  } catch (const Error&) {
    // The root became untrusted meanwhile: the folder stays for `horus shm clean` to judge.
  }
}

bool PresenceAnnouncement::announce(std::string_view snapshot_json, std::string& error) noexcept {
  const std::string temporary = entry_ + ".tmp";
  const int fd = ::openat(folder_, temporary.c_str(),
                          O_WRONLY | O_CREAT | O_TRUNC | O_NOFOLLOW | O_CLOEXEC, 0600);
  if (fd < 0) {
    error = "cannot write " + temporary + ": " + errno_text(errno);
    return false;
  }
  char header[96];
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const int header_size = std::snprintf(
      header, sizeof header, kHeaderFormat, this_process_identity(),
      static_cast<std::int64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(now).count()));
  bool written = true;
  for (std::string_view part :
       {std::string_view(header, static_cast<std::size_t>(header_size)), snapshot_json}) {
    while (written && !part.empty()) {
      const ssize_t put = ::write(fd, part.data(), part.size());
      if (put < 0 && errno == EINTR) continue;
      written = put > 0;
      if (written) part.remove_prefix(static_cast<std::size_t>(put));
    }
  }
  if (!written) error = "cannot write " + temporary + ": " + errno_text(errno);
  ::close(fd);
  if (written && ::renameat(folder_, temporary.c_str(), folder_, entry_.c_str()) != 0) {
    error = "cannot publish " + entry_ + ": " + errno_text(errno);
    written = false;
  }
  if (!written) ::unlinkat(folder_, temporary.c_str(), 0);
  return written;
}

namespace {

/// This process's uses in one namespace, and the announcement that lists them.
/// How long the writer lets changes pile up after a rewrite: a process opening hundreds of
/// topics rewrites its announcement a few times, not once per topic.
constexpr auto kRewriteInterval = std::chrono::milliseconds(50);

struct NamespaceUses {
  std::map<std::tuple<int, std::string, std::string, std::string>, std::size_t> counts;
  std::unique_ptr<PresenceAnnouncement> announcement;
  bool dirty = false;  // the counts changed since the announcement was written
};

struct ProcessUses {
  std::mutex mutex;
  std::condition_variable changed;
  std::map<std::string, NamespaceUses> namespaces;
  /// The process whose writer thread runs (a forked child starts its own).
  std::uint32_t writer_pid = 0;
};

ProcessUses& process_uses() {
  // Never destroyed: handles in other static objects may close after it would have been.
  static auto* uses = [] {
    auto* created = new ProcessUses();  // NOLINT(cppcoreguidelines-owning-memory)
    // fork() waits until no thread (the writer above all) holds the lock, so that a child never
    // starts with it held by a thread it does not have; the child's condition variable starts
    // afresh (the parent's writer waits on it, a thread the child does not have).
    ::pthread_atfork([] { process_uses().mutex.lock(); }, [] { process_uses().mutex.unlock(); },
                     [] {
                       ProcessUses& all = process_uses();
                       new (&all.changed) std::condition_variable();
                       all.mutex.unlock();
                     });
    return created;
  }();
  return *uses;
}

std::string program_name() {
  std::string name = detail::process_name(detail::this_pid());
  return name.empty() ? "?" : name;
}

std::string uses_json(const NamespaceUses& uses) {
  std::string topics;
  std::string services;
  for (const auto& [key, count] : uses.counts) {
    const auto& [kind, name, type, response_type] = key;
    if (kind == static_cast<int>(ProcessUse::Kind::Topic)) {
      topics += std::string(topics.empty() ? "" : ",") + "{\"topic\":" + json_string(name) +
                ",\"type\":" + json_string(type) + ",\"handles\":" + std::to_string(count) + "}";
    } else {
      const char* role =
          kind == static_cast<int>(ProcessUse::Kind::ServiceServer) ? "server" : "client";
      services += std::string(services.empty() ? "" : ",") + "{\"service\":" + json_string(name) +
                  ",\"role\":\"" + role + "\",\"request_type\":" + json_string(type) +
                  ",\"response_type\":" + json_string(response_type) + "}";
    }
  }
  return "{\"process\":" + json_string(program_name()) + ",\"topics\":[" + topics +
         "],\"services\":[" + services + "]}";
}

std::atomic<std::uint64_t> announcement_failures_seen{0};

/// Counts a failed process announcement; the first one in this process is said on stderr (a
/// process that cannot announce still works, but `horus node list` will not show it).
void announcement_failed(const std::string& namespace_name, const std::string& why) noexcept {
  if (announcement_failures_seen.fetch_add(1, std::memory_order_relaxed) != 0) return;
  char note[768];
  const int n =
      std::snprintf(note, sizeof note,
                    "[horus] this process is not announced in namespace '%s' (`horus node "
                    "list` will not show it; further failures are not reported): %s\n",
                    namespace_name.c_str(), why.c_str());
  std::size_t left = static_cast<std::size_t>(std::clamp(n, 0, static_cast<int>(sizeof note) - 1));
  const char* at = note;
  while (left > 0) {
    const ssize_t put = ::write(STDERR_FILENO, at, left);
    if (put < 0 && errno == EINTR) continue;
    if (put <= 0) break;
    at += put;
    left -= static_cast<std::size_t>(put);
  }
}

void write_announcement(const std::string& namespace_name, NamespaceUses& uses) noexcept {
  uses.dirty = false;
  std::string error;
  try {
    if (!uses.announcement) {
      uses.announcement = std::make_unique<PresenceAnnouncement>(namespace_name);
    }
    if (uses.announcement->announce(uses_json(uses), error)) return;
  } catch (const std::exception& e) {
    error = e.what();
  }
  announcement_failed(namespace_name, error);
}

/// Rewrites the announcements whose uses changed, at most once per kRewriteInterval.
[[noreturn]] void rewrite_changed(ProcessUses& all) noexcept {
  std::unique_lock lock(all.mutex);
  while (true) {
    all.changed.wait(lock, [&] {
      return std::any_of(all.namespaces.begin(), all.namespaces.end(),
                         [](const auto& entry) { return entry.second.dirty; });
    });
    for (auto& [namespace_name, uses] : all.namespaces) {
      if (uses.dirty) write_announcement(namespace_name, uses);
    }
    lock.unlock();
    std::this_thread::sleep_for(kRewriteInterval);
    lock.lock();
  }
}

void change_use(const ProcessUse& use, bool add) noexcept {
  try {
    const std::string namespace_name = namespace_of(use.namespace_name);
    ProcessUses& all = process_uses();
    const std::lock_guard lock(all.mutex);
    if (all.writer_pid != this_pid()) {
      // A forked child: the announcements it inherited are its parent's (their destruction
      // would remove the parent's files), and it needs a writer thread of its own.
      for (auto& entry : all.namespaces) {
        static_cast<void>(
            entry.second.announcement.release());  // NOLINT(bugprone-unused-return-value)
        entry.second.counts.clear();
        entry.second.dirty = false;
      }
      std::thread(rewrite_changed, std::ref(all)).detach();
      all.writer_pid = this_pid();
    }
    NamespaceUses& uses = all.namespaces[namespace_name];
    const auto key =
        std::make_tuple(static_cast<int>(use.kind), use.name, use.type, use.response_type);
    if (add) {
      ++uses.counts[key];
    } else if (auto found = uses.counts.find(key);
               found != uses.counts.end() && --found->second == 0) {
      uses.counts.erase(found);
    }
    if (uses.counts.empty()) {
      // The last use went, and so does the announcement, at once: the process may be exiting.
      uses.announcement.reset();
      uses.dirty = false;
    } else if (!uses.announcement) {
      write_announcement(namespace_name, uses);  // the first use: announced at once
    } else {
      uses.dirty = true;
      all.changed.notify_one();
    }
  } catch (...) {  // NOLINT(bugprone-empty-catch): an unannounced process still works
  }
}

}  // namespace

void announce_use(const ProcessUse& use) noexcept { change_use(use, true); }
void withdraw_use(const ProcessUse& use) noexcept { change_use(use, false); }

std::uint64_t announcement_failures() noexcept {
  return announcement_failures_seen.load(std::memory_order_relaxed);
}

}  // namespace detail
}  // namespace horus
