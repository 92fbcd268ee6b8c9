// Ownership checks of shared-memory folders and files (detail/shm_access.hpp).
#include "horus/detail/shm_access.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <grp.h>
#include <pwd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <utility>
#include <vector>

#include "horus/error.hpp"
#include "horus/internal/errno_text.hpp"

namespace horus::detail {

namespace {

std::string octal(unsigned mode) {
  char text[8];
  std::snprintf(text, sizeof text, "%04o", mode & 07777U);
  return text;
}

/// "user NAME (uid N)", or "uid N" for a user without a name.
std::string describe_user(uid_t uid) {
  std::vector<char> buffer(4096);
  passwd entry{};
  passwd* found = nullptr;
  if (::getpwuid_r(uid, &entry, buffer.data(), buffer.size(), &found) == 0 && found != nullptr) {
    return "user " + std::string(found->pw_name) + " (uid " + std::to_string(uid) + ")";
  }
  return "uid " + std::to_string(uid);
}

std::string describe_group(gid_t gid) {
  std::vector<char> buffer(4096);
  group entry{};
  group* found = nullptr;
  if (::getgrgid_r(gid, &entry, buffer.data(), buffer.size(), &found) == 0 && found != nullptr) {
    return "group " + std::string(found->gr_name) + " (gid " + std::to_string(gid) + ")";
  }
  return "gid " + std::to_string(gid);
}

bool in_my_groups(gid_t gid) {
  if (gid == ::getegid()) {
    return true;
  }
  const int count = ::getgroups(0, nullptr);
  std::vector<gid_t> groups(count > 0 ? static_cast<std::size_t>(count) : 0);
  const int got = ::getgroups(static_cast<int>(groups.size()), groups.data());
  for (int i = 0; i < got; ++i) {
    if (groups[static_cast<std::size_t>(i)] == gid) {
      return true;
    }
  }
  return false;
}

/// Directory mode for a file mode: the classes that may read files may also list and enter; a
/// folder shared with a group passes its group on to what is created in it (setgid), and is
/// sticky so that no member can remove or replace another member's segments.
mode_t directory_mode(unsigned file_mode) {
  const auto mode = static_cast<mode_t>(0700 | (file_mode & 0066) | ((file_mode & 0044) >> 2));
  return group_sharing(file_mode) ? mode | S_ISGID | S_ISVTX : mode;
}

/// What to do about a root another user holds: the default root's name is known to every user.
constexpr const char* kRootRemedy =
    " (use a root of your own: set HORUS_SHM_DIR to a folder only you can write, e.g. "
    "$XDG_RUNTIME_DIR/horus, the same for every process and tool of the robot; or have root "
    "remove it)";

/// Why an open failed, with the owner and mode of what is there when permission was denied: a
/// folder another user made first (0700, say) is refused by the kernel before fstat could name
/// its owner. Only words for the message; nothing is decided on this lookup.
std::string open_failure(int parent, const std::string& name, int error) {
  std::string text = errno_text(error);
  struct stat info {};
  if (error == EACCES && ::fstatat(parent, name.c_str(), &info, AT_SYMLINK_NOFOLLOW) == 0) {
    text += " (it belongs to " + describe_user(info.st_uid) + ", mode " +
            octal(static_cast<unsigned>(info.st_mode)) + ")";
  }
  return text;
}

}  // namespace

FileDescriptor::FileDescriptor(FileDescriptor&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)) {}

FileDescriptor& FileDescriptor::operator=(FileDescriptor&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) {
      ::close(fd_);
    }
    fd_ = std::exchange(other.fd_, -1);
  }
  return *this;
}

FileDescriptor::~FileDescriptor() {
  if (fd_ >= 0) {
    ::close(fd_);
  }
}

std::string untrusted_reason(const struct stat& info, const std::string& path, bool root,
                             bool sharing) {
  const uid_t me = ::geteuid();
  const std::string owner = describe_user(info.st_uid);
  const std::string mode = octal(static_cast<unsigned>(info.st_mode));
  if (root) {
    if (info.st_uid != me && info.st_uid != 0) {
      return path + " belongs to " + owner + ", not to this process's " + describe_user(me) +
             " or root: another user may have created it first" + kRootRemedy;
    }
    if ((info.st_mode & (S_IWGRP | S_IWOTH)) != 0 && (info.st_mode & S_ISVTX) == 0) {
      return path + " (mode " + mode +
             ") is writable by other users without the sticky bit: they could replace what is "
             "in it";
    }
    return {};
  }
  if ((info.st_mode & S_IWOTH) != 0) {
    return path + " (mode " + mode + ", owner " + owner +
           ") is writable by every user: anyone could send on its topics";
  }
  if (info.st_uid == me) {
    if (!sharing && (info.st_mode & S_IWGRP) != 0) {
      return path + " (mode " + mode + ") is writable by " + describe_group(info.st_gid) +
             ", but this process did not ask to share: a member could send on its topics (to "
             "share, open with a mode that has group bits, e.g. 0660)";
    }
    return {};
  }
  if (!sharing) {
    return path + " belongs to " + owner + ", not to this process's " + describe_user(me) +
           ": another user may have created it first (to share topics with a group, both sides "
           "open them with a mode that has group bits, e.g. 0660)";
  }
  if (!in_my_groups(info.st_gid)) {
    return path + " belongs to " + owner + " and " + describe_group(info.st_gid) +
           ", a group this process is not in";
  }
  return {};
}

void check_creation_mode(unsigned mode, std::string_view what) {
  if ((mode & 0002U) != 0) {
    throw Error(std::string(what) + " mode " + octal(mode) +
                " lets every local user write: share through a group instead (e.g. 0660)");
  }
  if ((mode & 0600U) != 0600U) {
    throw Error(std::string(what) + " mode " + octal(mode) + " must let the owner read and write");
  }
}

FileDescriptor open_trusted_directory(int parent, const std::string& name, const std::string& path,
                                      unsigned mode, bool root, bool sharing, bool create) {
  const mode_t wanted = root ? mode_t{0700} : directory_mode(mode);
  const bool created = create && ::mkdirat(parent, name.c_str(), wanted) == 0;
  if (create && !created && errno != EEXIST) {
    throw Error("cannot create the topic directory " + path + ": " + errno_text(errno));
  }
  FileDescriptor folder(
      ::openat(parent, name.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC));
  if (folder.get() < 0) {
    const int error = errno;
    if (!create && error == ENOENT) {
      return folder;
    }
    throw Error("cannot open the topic directory " + path + ": " +
                (error == ENOTDIR || error == ELOOP ? "it exists but is not a directory"
                                                    : open_failure(parent, name, error)) +
                (root && error != ENOENT ? kRootRemedy : ""));
  }
  struct stat info {};
  if (::fstat(folder.get(), &info) != 0) {
    throw Error("cannot stat the topic directory " + path + ": " + errno_text(errno));
  }
  if (std::string reason = untrusted_reason(info, path, root, sharing); !reason.empty()) {
    throw Error("refusing the topic directory " + reason);
  }
  if (created && info.st_uid == ::geteuid()) {
    // mkdir applies the umask; the requested mode is the contract.
    ::fchmod(folder.get(), wanted);
  }
  return folder;
}

FileDescriptor open_trusted_file(int directory, const std::string& name, const std::string& path,
                                 int flags, unsigned mode, bool sharing) {
  FileDescriptor file(
      ::openat(directory, name.c_str(), flags | O_NOFOLLOW | O_CLOEXEC, static_cast<mode_t>(mode)));
  if (file.get() < 0) {
    const int error = errno;
    throw Error("cannot open topic segment " + path + ": " +
                (error == ELOOP ? "it is a symbolic link (refused: it could point anywhere)"
                                : open_failure(directory, name, error)));
  }
  struct stat info {};
  if (::fstat(file.get(), &info) != 0) {
    throw Error("cannot stat topic segment " + path + ": " + errno_text(errno));
  }
  if (!S_ISREG(info.st_mode)) {
    throw Error("topic segment " + path + " is not a regular file");
  }
  if (std::string reason = untrusted_reason(info, path, false, sharing); !reason.empty()) {
    throw Error("refusing topic segment " + reason);
  }
  return file;
}

std::vector<std::string> folder_entries(int folder, const std::string& path) {
  // fdopendir takes over the descriptor it is given: a duplicate, so the folder stays open.
  const int duplicate = ::fcntl(folder, F_DUPFD_CLOEXEC, 0);
  DIR* dir = duplicate >= 0 ? ::fdopendir(duplicate) : nullptr;
  if (dir == nullptr) {
    const int error = errno;
    if (duplicate >= 0) ::close(duplicate);
    throw Error("cannot list " + path + ": " + errno_text(error));
  }
  std::vector<std::string> names;
  // This DIR stream is local to the call, which is all readdir needs to be safe.
  while (const dirent* entry = ::readdir(dir)) {  // NOLINT(concurrency-mt-unsafe)
    const std::string_view name = entry->d_name;
    if (name != "." && name != "..") names.emplace_back(name);
  }
  ::closedir(dir);
  std::sort(names.begin(), names.end());
  return names;
}

bool still_linked(int fd) noexcept {
  struct stat info {};
  return ::fstat(fd, &info) == 0 && info.st_nlink > 0;
}

}  // namespace horus::detail
