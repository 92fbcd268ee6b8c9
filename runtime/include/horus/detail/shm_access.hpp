// Opening shared-memory objects (folders and segment files) that other local users cannot plant,
// take over or write: the one pattern every shared-memory object of the runtime follows.
//
// Every object is opened first (O_NOFOLLOW, relative to its already-checked parent folder) and
// judged by fstat on the descriptor, so nothing can be swapped between the check and the use. An
// object is trusted when this process's effective user owns it, or, when the caller shares
// through a group (a mode with group bits, on both sides), when it belongs to a group this process
// is in; in both cases it must not be writable by every user, nor by a group unless the caller
// shares (a group member could otherwise write what was meant to be private). Folders created for
// sharing are setgid and sticky (3770). The root folder may also belong to root, and may be
// writable by a group or by everyone only when it is sticky (like /tmp), so that nobody can rename
// or remove what another user made in it. runtime/src/transport/README.md explains the layout and
// how to share.
#pragma once

#include <sys/stat.h>

#include <string>
#include <string_view>
#include <vector>

namespace horus::detail {

/// An open file descriptor, closed on destruction.
class FileDescriptor {
 public:
  explicit FileDescriptor(int fd = -1) noexcept : fd_(fd) {}
  FileDescriptor(FileDescriptor&& other) noexcept;
  FileDescriptor& operator=(FileDescriptor&& other) noexcept;
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  ~FileDescriptor();
  int get() const noexcept { return fd_; }

 private:
  int fd_;
};

/// Whether a mode asks to share with the group (any group permission bit).
inline bool group_sharing(unsigned mode) noexcept { return (mode & 0070U) != 0; }

/// Why this process must not trust an object with `info` (from fstat) at `path`, or empty when it
/// may. `root`: the root folder of all namespaces (see above).
std::string untrusted_reason(const struct stat& info, const std::string& path, bool root,
                             bool sharing);

/// Refuses a creation mode that lets every user write (with the reason), or one without owner
/// read and write.
void check_creation_mode(unsigned mode, std::string_view what);

/// The folder `name` inside the folder `parent` (a descriptor, or AT_FDCWD with an absolute
/// `name`), created for files of `mode` when missing and `create` (otherwise a missing folder
/// gives a descriptor of -1), opened O_DIRECTORY | O_NOFOLLOW and checked. `path` names it in
/// errors. Throws horus::Error.
FileDescriptor open_trusted_directory(int parent, const std::string& name, const std::string& path,
                                      unsigned mode, bool root, bool sharing, bool create);

/// The file `name` inside the checked folder `directory`, opened with `flags` (O_CREAT creates
/// it with `mode`) and O_NOFOLLOW | O_CLOEXEC, and checked. Throws horus::Error.
FileDescriptor open_trusted_file(int directory, const std::string& name, const std::string& path,
                                 int flags, unsigned mode, bool sharing);

/// The names in the checked folder open as `folder` (which stays open), "." and ".." left out,
/// sorted. Throws horus::Error naming `path`.
std::vector<std::string> folder_entries(int folder, const std::string& path);

/// Whether the file or folder open as `fd` still has a name: an opener that locks an object
/// checks that no cleaner removed it between the open and the lock.
bool still_linked(int fd) noexcept;

}  // namespace horus::detail
