// Set-up of topic segments: creation, validation, re-use and the users table.
//
// Every set-up step runs under flock(LOCK_EX) on the segment file: concurrent openers serialise,
// and the kernel drops the lock of a process killed mid-set-up, so nobody waits on a dead one.
#include "horus/detail/shm_segment.hpp"
#include "horus/detail/shm_access.hpp"
#include "horus/internal/errno_text.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "horus/detail/process.hpp"
#include "horus/error.hpp"
#include "horus/internal/created_segments.hpp"

namespace horus::detail {

namespace {

std::string hex(std::uint64_t value) {
  char text[19];
  std::snprintf(text, sizeof text, "0x%016llx", static_cast<unsigned long long>(value));
  return text;
}

std::uint64_t round_up(std::uint64_t value, std::uint64_t multiple) {
  return (value + multiple - 1) / multiple * multiple;
}

/// The set-up lock on a segment, held from open_locked until destruction.
class SetupLock {
 public:
  explicit SetupLock(FileDescriptor file) : file_(std::move(file)) {}
  SetupLock(const SetupLock&) = delete;
  SetupLock& operator=(const SetupLock&) = delete;
  ~SetupLock() {
    // Explicitly: the mapping keeps the open file description (and so a flock) alive after
    // close, which would leave the set-up lock held for as long as the handle lives.
    ::flock(file_.get(), LOCK_UN);
  }
  int get() const { return file_.get(); }

 private:
  FileDescriptor file_;
};

struct Mapping {
  void* base = nullptr;
  std::size_t size = 0;
};

Mapping map_file(int fd, std::size_t size, int protection, const std::string& path) {
  void* base = ::mmap(nullptr, size, protection, MAP_SHARED, fd, 0);
  if (base == MAP_FAILED) {
    throw Error("cannot map topic segment " + path + ": " + errno_text(errno));
  }
  return {base, size};
}

/// Opens the segment `name` in `folder` (creating it empty with `mode`), checks who owns it, and
/// holds the set-up lock on it. Retries when the file was unlinked between open and lock, so the
/// lock always guards the live file.
SetupLock open_locked(const FileDescriptor& folder, const std::string& name,
                      const std::string& path, unsigned mode) {
  for (int attempt = 0; attempt < 16; ++attempt) {
    FileDescriptor file =
        open_trusted_file(folder.get(), name, path, O_RDWR | O_CREAT, mode, group_sharing(mode));
    while (::flock(file.get(), LOCK_EX) != 0) {
      if (errno != EINTR) {
        throw Error("cannot lock topic segment " + path + ": " + errno_text(errno));
      }
    }
    struct stat opened {};
    struct stat current {};
    if (::fstat(file.get(), &opened) == 0 &&
        ::fstatat(folder.get(), name.c_str(), &current, AT_SYMLINK_NOFOLLOW) == 0 &&
        opened.st_dev == current.st_dev && opened.st_ino == current.st_ino) {
      return SetupLock(std::move(file));
    }
    ::flock(file.get(), LOCK_UN);
  }
  throw Error("topic segment " + path + " keeps being removed while opening it");
}

std::uint64_t file_size(int fd, const std::string& path) {
  struct stat info {};
  if (::fstat(fd, &info) != 0) {
    throw Error("cannot stat topic segment " + path + ": " + errno_text(errno));
  }
  return static_cast<std::uint64_t>(info.st_size);
}

void allocate(int fd, std::uint64_t size, const std::string& path) {
  // posix_fallocate, not ftruncate: a full /dev/shm must fail here, not as SIGBUS on first touch.
  const int error = ::posix_fallocate(fd, 0, static_cast<off_t>(size));
  if (error != 0) {
    ::ftruncate(fd, static_cast<off_t>(kControlSize));
    throw Error("cannot allocate " + std::to_string(size) + " bytes for topic segment " + path +
                ": " + errno_text(error) + " (is /dev/shm full or too small?)");
  }
}

void write_all(int fd, const void* data, std::size_t size, std::uint64_t offset,
               const std::string& path) {
  const auto* bytes = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t written = ::pwrite(fd, bytes, size, static_cast<off_t>(offset));
    if (written < 0 && errno == EINTR) {
      continue;
    }
    if (written <= 0) {
      throw Error("cannot write topic segment " + path + ": " + errno_text(errno));
    }
    bytes += written;
    size -= static_cast<std::size_t>(written);
    offset += static_cast<std::uint64_t>(written);
  }
}

void read_all(int fd, void* data, std::size_t size, std::uint64_t offset, const std::string& path) {
  auto* bytes = static_cast<char*>(data);
  while (size > 0) {
    const ssize_t got = ::pread(fd, bytes, size, static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR) {
      continue;
    }
    if (got <= 0) {
      throw Error("cannot read topic segment " + path + ": truncated");
    }
    bytes += got;
    size -= static_cast<std::size_t>(got);
    offset += static_cast<std::uint64_t>(got);
  }
}

/// Whether a live process has the segment open (counting notifiers only if asked: they map the
/// control page alone, so they do not stand in the way of re-typing).
bool has_live_users(const ControlBlock& control, bool count_notifiers) {
  for (const UserEntry& user : control.users) {
    const bool notifier = (user.roles.load(std::memory_order_relaxed) & kRoleNotifier) != 0;
    if ((count_notifiers || !notifier) &&
        identity_alive(user.process.load(std::memory_order_acquire))) {
      return true;
    }
  }
  return false;
}

/// Gives a new (empty) file its control page; refuses a file too short to hold one.
void prepare_control(int fd, const std::string& path, unsigned mode) {
  const std::uint64_t size = file_size(fd, path);
  if (size == 0) {
    ::fchmod(fd, static_cast<mode_t>(mode));
    allocate(fd, kControlSize, path);
    struct {
      std::uint64_t magic;
      std::uint32_t version;
      std::uint32_t control_size;
    } const prefix{kControlMagic, kSegmentVersion, static_cast<std::uint32_t>(kControlSize)};
    write_all(fd, &prefix, sizeof prefix, 0, path);
    return;
  }
  if (size < kControlSize) {
    throw Error("topic segment " + path + " is truncated (" + std::to_string(size) +
                " bytes, the control page alone is " + std::to_string(kControlSize) + ")");
  }
}

/// Withdraws the sleeper announcements left by the dead process whose entry the caller took.
void give_back_sleepers(RingControl& ring, UserEntry& user) noexcept {
  for (std::uint32_t left = user.sleepers.exchange(0, std::memory_order_acq_rel); left > 0;
       --left) {
    ring_remove_sleeper(ring);
  }
}

int register_user(ControlBlock& control, std::uint32_t roles, const std::string& path) {
  const std::uint64_t me = this_process_identity();
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t i = 0; i < kMaxUsers; ++i) {
      UserEntry& user = control.users[i];
      std::uint64_t current = user.process.load(std::memory_order_acquire);
      const bool free = pass == 0 ? current == 0 : current != 0 && !identity_alive(current);
      if (free && user.process.compare_exchange_strong(current, me, std::memory_order_acq_rel)) {
        give_back_sleepers(control.ring, user);
        user.roles.store(roles, std::memory_order_release);
        return static_cast<int>(i);
      }
    }
  }
  throw Error("topic segment " + path + " already has " + std::to_string(kMaxUsers) +
              " open handles in live processes");
}

LayoutHeader make_layout(const TypeDescriptor& type, const SegmentOptions& options,
                         const std::string& path) {
  if (type.name.empty() || type.name.size() > kMaxTypeName) {
    throw Error("type name '" + std::string(type.name) + "' must have 1 to " +
                std::to_string(kMaxTypeName) + " characters (topic " + path + ")");
  }
  if (type.schema.size() > kMaxSchemaSize) {
    throw Error("schema of " + std::string(type.name) + " exceeds " +
                std::to_string(kMaxSchemaSize) + " bytes (topic " + path + ")");
  }
  if (type.description.size() > kMaxDescriptionSize) {
    throw Error("type description of " + std::string(type.name) + " exceeds " +
                std::to_string(kMaxDescriptionSize) + " bytes (topic " + path + ")");
  }
  if (options.capacity == 0 || options.capacity > kMaxCapacity) {
    throw Error("topic capacity " + std::to_string(options.capacity) + " is not within 1.." +
                std::to_string(kMaxCapacity) + " (topic " + path + ")");
  }
  const std::uint64_t alignment = std::max<std::uint64_t>(type.alignment, 8);
  if (!std::has_single_bit(alignment) || alignment > kControlSize) {
    throw Error("alignment " + std::to_string(type.alignment) + " of " + std::string(type.name) +
                " is not supported in shared memory (topic " + path + ")");
  }
  const std::uint64_t payload = type.is_pod ? type.size : options.max_message_size;
  if (payload == 0 || payload > kMaxSlotPayload) {
    throw Error("message size " + std::to_string(payload) + " of " + std::string(type.name) +
                " is not within 1.." + std::to_string(kMaxSlotPayload) + " (topic " + path + ")");
  }
  LayoutHeader header{};
  header.magic = kLayoutMagic;
  header.version = kSegmentVersion;
  header.header_size = sizeof(LayoutHeader);
  header.fingerprint = type.fingerprint;
  header.is_pod = type.is_pod ? 1 : 0;
  header.type_name_size = static_cast<std::uint32_t>(type.name.size());
  std::memcpy(header.type_name, type.name.data(), type.name.size());
  header.type_size = type.is_pod ? type.size : 0;
  header.type_alignment = alignment;
  header.capacity = std::bit_ceil(static_cast<std::uint64_t>(options.capacity));
  header.payload_offset = round_up(sizeof(SlotHeader), alignment);
  if (header.payload_offset + payload > kCacheLine) {
    // A payload that does not fit beside `seq` starts on its own cache line: the writer then
    // fills it without fighting a subscriber that is polling `seq`.
    header.payload_offset = round_up(kCacheLine, alignment);
  }
  header.payload_capacity = payload;
  header.slot_stride =
      round_up(header.payload_offset + payload, std::max<std::uint64_t>(kCacheLine, alignment));
  header.schema_offset = kControlSize + sizeof(LayoutHeader);
  header.schema_size = type.schema.size();
  header.description_offset = header.schema_offset + header.schema_size;
  header.description_size = type.description.size();
  header.claims_offset = round_up(header.description_offset + header.description_size, kCacheLine);
  // Two free lines before the slots keep the last claims out of reach of the adjacent-line
  // prefetch of the first slot.
  header.slots_offset = round_up(
      header.claims_offset + header.capacity * sizeof(SlotClaim) + 2 * kCacheLine, kControlSize);
  header.total_size = header.slots_offset + header.capacity * header.slot_stride;
  return header;
}

/// Starts the publishers' side of a ring afresh, for a topic being (re)created or one whose every
/// user died: no lease, not shared, the next lease holder numbering tickets from the count so far.
/// That count never goes backwards: notifiers and readers compare against it.
void start_publishers_afresh(RingControl& ring, bool single) {
  const std::uint64_t written = ring_written(ring);
  ring.commits.store(written, std::memory_order_release);
  ring.lease_announce.store(written, std::memory_order_release);
  ring.first_ticket.store(written, std::memory_order_release);
  ring.write_index.fetch_and(~kIndexMask, std::memory_order_acq_rel);
  ring.publisher_lease.store(0, std::memory_order_release);
  ring.shared_base.store(0, std::memory_order_release);
  ring.single_publisher.store(single ? 1 : 0, std::memory_order_release);
}

/// The topic's name, checked, once the options are known to be safe to create it with.
std::string checked_topic_name(std::string_view topic, const SegmentOptions& options) {
  validate_segment_name("topic name", topic);
  check_creation_mode(options.mode, "topic '" + std::string(topic) + "':");
  return std::string(topic);
}

bool same_type(const LayoutHeader& header, const TypeDescriptor& type) {
  return std::string_view(header.type_name, header.type_name_size) == type.name &&
         header.fingerprint == type.fingerprint && (header.is_pod != 0) == type.is_pod &&
         (!type.is_pod || (header.type_size == type.size &&
                           (header.slots_offset + header.payload_offset) % type.alignment == 0 &&
                           header.slot_stride % type.alignment == 0));
}

}  // namespace

std::string current_namespace() {
  // Read when a topic opens; programs set the variable before they start threads.
  const char* value = std::getenv("HORUS_NAMESPACE");  // NOLINT(concurrency-mt-unsafe)
  if (value == nullptr || *value == '\0') {
    return "default";
  }
  validate_segment_name("namespace (HORUS_NAMESPACE)", value);
  return value;
}

std::string shm_root() {
  const char* value = std::getenv("HORUS_SHM_DIR");  // NOLINT(concurrency-mt-unsafe)
  if (value != nullptr && *value != '\0') {
    return value;
  }
  // Per user: a root shared by every user could be created first by any of them.
  return "/dev/shm/horus-" + std::to_string(::geteuid());
}

std::string namespace_directory(std::string_view namespace_name) {
  std::string name = namespace_name.empty() ? current_namespace() : std::string(namespace_name);
  validate_segment_name("namespace", name);
  return shm_root() + "/" + name;
}

NamespaceFolder open_namespace_folder(std::string_view namespace_name, unsigned mode, bool create) {
  std::string name = namespace_name.empty() ? current_namespace() : std::string(namespace_name);
  validate_segment_name("namespace", name);
  const std::string root = shm_root();
  const bool sharing = group_sharing(mode);
  NamespaceFolder folder{FileDescriptor(), root + "/" + name};
  const FileDescriptor root_folder =
      open_trusted_directory(AT_FDCWD, root, root, mode, true, sharing, create);
  if (root_folder.get() >= 0) {
    folder.descriptor =
        open_trusted_directory(root_folder.get(), name, folder.path, mode, false, sharing, create);
  }
  return folder;
}

void validate_segment_name(std::string_view what, std::string_view name) {
  bool valid = !name.empty() && name.size() <= 200 && name != "." && name != "..";
  for (const char c : name) {
    const bool allowed = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                         (c >= '0' && c <= '9') || c == '_' || c == '.' || c == '-';
    valid = valid && allowed;
  }
  if (!valid) {
    throw Error(std::string(what) + " '" + std::string(name) +
                "' is not valid: use 1 to 200 of [A-Za-z0-9_.-] (and not . or ..)");
  }
}

/// The live processes holding the segment's typed part, as "pid 1234 (arm_driver)", for an
/// error that must say who still uses the old type.
std::string live_users_text(const ControlBlock& control) {
  std::vector<std::uint32_t> pids;
  for (const UserEntry& user : control.users) {
    const std::uint64_t identity = user.process.load(std::memory_order_acquire);
    const std::uint32_t pid = identity_pid(identity);
    if ((user.roles.load(std::memory_order_relaxed) & kRoleNotifier) == 0 &&
        identity_alive(identity) && std::find(pids.begin(), pids.end(), pid) == pids.end()) {
      pids.push_back(pid);
    }
  }
  std::string text;
  for (const std::uint32_t pid : pids) {
    text += text.empty() ? "pid " : ", pid ";
    text += std::to_string(pid);
    if (const std::string name = process_name(pid); !name.empty()) text += " (" + name + ")";
  }
  return text.empty() ? "a process that has just exited" : text;
}

bool segment_in_use(const ControlBlock& control) { return has_live_users(control, true); }

std::string validate_control(const ControlBlock& control) {
  if (control.magic != kControlMagic) {
    return "bad control magic " + hex(control.magic);
  }
  if (control.version != kSegmentVersion) {
    return "unsupported version " + std::to_string(control.version) + " (this build reads " +
           std::to_string(kSegmentVersion) + ")";
  }
  if (control.control_size != kControlSize) {
    return "control page size " + std::to_string(control.control_size) + " instead of " +
           std::to_string(kControlSize);
  }
  const std::uint32_t ready = control.layout_ready.load(std::memory_order_acquire);
  if (ready > 1) {
    return "invalid layout state " + std::to_string(ready);
  }
  const std::uint32_t single = control.ring.single_publisher.load(std::memory_order_acquire);
  if (single > 1) {
    return "invalid publisher mode " + std::to_string(single);
  }
  return {};
}

std::string validate_layout(const LayoutHeader& h, std::uint64_t file_size) {
  if (h.magic != kLayoutMagic) {
    return "bad layout magic " + hex(h.magic);
  }
  if (h.version != kSegmentVersion || h.header_size != sizeof(LayoutHeader)) {
    return "unsupported layout version " + std::to_string(h.version) + " / header size " +
           std::to_string(h.header_size);
  }
  if (h.type_name_size == 0 || h.type_name_size > kMaxTypeName || h.is_pod > 1) {
    return "invalid type identity fields";
  }
  if (h.capacity == 0 || h.capacity > kMaxCapacity || !std::has_single_bit(h.capacity)) {
    return "invalid capacity " + std::to_string(h.capacity);
  }
  if (h.type_alignment < 8 || h.type_alignment > kControlSize ||
      !std::has_single_bit(h.type_alignment)) {
    return "invalid alignment " + std::to_string(h.type_alignment);
  }
  if (h.payload_capacity == 0 || h.payload_capacity > kMaxSlotPayload ||
      (h.is_pod != 0 && (h.type_size == 0 || h.payload_capacity < h.type_size))) {
    return "invalid payload capacity " + std::to_string(h.payload_capacity);
  }
  if (h.payload_offset < sizeof(SlotHeader) || h.payload_offset % h.type_alignment != 0 ||
      h.payload_offset > kControlSize || h.slot_stride % kCacheLine != 0 ||
      h.slot_stride % h.type_alignment != 0 ||
      h.slot_stride < h.payload_offset + h.payload_capacity ||
      h.slot_stride > kMaxSlotPayload + 2 * kControlSize) {
    return "invalid slot geometry (stride " + std::to_string(h.slot_stride) + ", payload at " +
           std::to_string(h.payload_offset) + ")";
  }
  if (h.description_offset != h.schema_offset + h.schema_size ||
      h.description_size > kMaxDescriptionSize) {
    return "invalid type description offset " + std::to_string(h.description_offset) + " / size " +
           std::to_string(h.description_size);
  }
  if (h.schema_offset != kControlSize + sizeof(LayoutHeader) || h.schema_size > kMaxSchemaSize ||
      h.claims_offset < h.description_offset + h.description_size ||
      h.claims_offset % kCacheLine != 0 || h.slots_offset > h.total_size ||
      h.claims_offset > h.slots_offset ||
      h.slots_offset - h.claims_offset < h.capacity * sizeof(SlotClaim) ||
      h.slots_offset % kCacheLine != 0 || h.slots_offset % h.type_alignment != 0) {
    return "invalid schema or slot offsets";
  }
  if (h.total_size != h.slots_offset + h.capacity * h.slot_stride) {
    return "total size " + std::to_string(h.total_size) + " does not match the geometry";
  }
  if (h.total_size > file_size) {
    return "truncated: the header describes " + std::to_string(h.total_size) +
           " bytes but the file has " + std::to_string(file_size);
  }
  return {};
}

ShmSegment ShmSegment::open_topic(std::string_view topic, const TypeDescriptor& type,
                                  const SegmentOptions& options) {
  const std::string name = checked_topic_name(topic, options);
  const NamespaceFolder folder = open_namespace_folder(options.namespace_name, options.mode, true);
  ShmSegment segment;
  segment.path_ = folder.path + "/" + name;
  const std::string& path = segment.path_;
  const SetupLock fd = open_locked(folder.descriptor, name, path, options.mode);
  prepare_control(fd.get(), path, options.mode);

  const Mapping control_page = map_file(fd.get(), kControlSize, PROT_READ | PROT_WRITE, path);
  segment.base_ = control_page.base;
  segment.mapped_size_ = control_page.size;
  ControlBlock& control = segment.control();
  if (std::string problem = validate_control(control); !problem.empty()) {
    throw Error("topic segment " + path + " is corrupt: " + problem +
                "; remove the file if no process uses it");
  }

  LayoutHeader header{};
  bool usable = false;
  if (control.layout_ready.load(std::memory_order_acquire) == 1) {
    const std::uint64_t size = file_size(fd.get(), path);
    if (size < kControlSize + sizeof(LayoutHeader)) {
      throw Error("topic segment " + path + " is corrupt: truncated to " + std::to_string(size) +
                  " bytes; remove the file if no process uses it");
    }
    read_all(fd.get(), &header, sizeof header, kControlSize, path);
    if (std::string problem = validate_layout(header, size); !problem.empty()) {
      throw Error("topic segment " + path + " is corrupt: " + problem +
                  "; remove the file if no process uses it");
    }
    usable = same_type(header, type);
    if (!usable && has_live_users(control, false)) {
      throw Error("topic '" + std::string(topic) + "' (" + path + ") carries " +
                  std::string(header.type_name, header.type_name_size) + " (fingerprint " +
                  hex(header.fingerprint) + "), open in " + live_users_text(control) +
                  "; cannot open it as " + std::string(type.name) + " (fingerprint " +
                  hex(type.fingerprint) +
                  "): stop what uses the old type, or rebuild it with the same schema");
    }
  }
  if (!usable) {
    // New, abandoned half-way by a dead creator, or re-typed after every user died. The ticket
    // count is kept: it only grows, so notifiers never see it go backwards.
    header = make_layout(type, options, path);
    control.layout_ready.store(0, std::memory_order_release);
    ::ftruncate(fd.get(), static_cast<off_t>(kControlSize));
    allocate(fd.get(), header.total_size, path);
    write_all(fd.get(), &header, sizeof header, kControlSize, path);
    write_all(fd.get(), type.schema.data(), type.schema.size(), header.schema_offset, path);
    write_all(fd.get(), type.description.data(), type.description.size(), header.description_offset,
              path);
    start_publishers_afresh(control.ring, options.single_publisher);
    control.layout_ready.store(1, std::memory_order_release);
    remember_created_segment(options.namespace_name, name, options.mode);
  }

  if (!has_live_users(control, true)) {
    // Sleepers killed while waiting never took themselves off the count; with nobody alive,
    // clear it, or every send would keep making a wake-up syscall for nobody.
    control.ring.write_index.fetch_and(kIndexMask, std::memory_order_acq_rel);
    if (usable) {
      // A ring that was shared goes back to its fast lease for whoever publishes first now (a
      // re-created one was started afresh above).
      start_publishers_afresh(control.ring,
                              control.ring.single_publisher.load(std::memory_order_acquire) == 1);
    }
  }

  ::munmap(segment.base_, segment.mapped_size_);
  segment.base_ = nullptr;
  const Mapping whole = map_file(fd.get(), header.total_size, PROT_READ | PROT_WRITE, path);
  segment.base_ = whole.base;
  segment.mapped_size_ = whole.size;
  auto* bytes = static_cast<std::byte*>(segment.base_);
  segment.ring_.control = &segment.control().ring;
  segment.ring_.users = segment.control().users;
  segment.ring_.claims = reinterpret_cast<SlotClaim*>(bytes + header.claims_offset);
  segment.ring_.slots = bytes + header.slots_offset;
  segment.ring_.mask = header.capacity - 1;
  segment.ring_.stride = header.slot_stride;
  segment.ring_.payload_offset = header.payload_offset;
  segment.ring_.payload_capacity = header.payload_capacity;
  segment.ring_.single_publisher =
      segment.control().ring.single_publisher.load(std::memory_order_acquire) == 1;
  segment.user_index_ = register_user(segment.control(), 0, path);
  segment.announced_ = AnnouncedUse(ProcessUse{
      ProcessUse::Kind::Topic, options.namespace_name, name, std::string(type.name), {}});
  return segment;
}

ShmSegment ShmSegment::open_control(std::string_view topic, const SegmentOptions& options) {
  const std::string name = checked_topic_name(topic, options);
  const NamespaceFolder folder = open_namespace_folder(options.namespace_name, options.mode, true);
  ShmSegment segment;
  segment.path_ = folder.path + "/" + name;
  const SetupLock fd = open_locked(folder.descriptor, name, segment.path_, options.mode);
  prepare_control(fd.get(), segment.path_, options.mode);
  const Mapping page = map_file(fd.get(), kControlSize, PROT_READ | PROT_WRITE, segment.path_);
  segment.base_ = page.base;
  segment.mapped_size_ = page.size;
  if (std::string problem = validate_control(segment.control()); !problem.empty()) {
    throw Error("topic segment " + segment.path_ + " is corrupt: " + problem +
                "; remove the file if no process uses it");
  }
  segment.ring_.control = &segment.control().ring;
  segment.ring_.users = segment.control().users;
  segment.user_index_ = register_user(segment.control(), kRoleNotifier, segment.path_);
  return segment;
}

ShmSegment::ShmSegment(ShmSegment&& other) noexcept
    : base_(std::exchange(other.base_, nullptr)),
      mapped_size_(std::exchange(other.mapped_size_, 0)),
      user_index_(std::exchange(other.user_index_, -1)),
      ring_(std::exchange(other.ring_, RingView{})),
      path_(std::move(other.path_)),
      announced_(std::move(other.announced_)) {}

ShmSegment& ShmSegment::operator=(ShmSegment&& other) noexcept {
  if (this != &other) {
    release();
    base_ = std::exchange(other.base_, nullptr);
    mapped_size_ = std::exchange(other.mapped_size_, 0);
    user_index_ = std::exchange(other.user_index_, -1);
    ring_ = std::exchange(other.ring_, RingView{});
    path_ = std::move(other.path_);
    announced_ = std::move(other.announced_);
  }
  return *this;
}

ShmSegment::~ShmSegment() { release(); }

void ShmSegment::add_role(std::uint32_t role) noexcept {
  if (user_index_ >= 0) {
    control().users[user_index_].roles.fetch_or(role, std::memory_order_relaxed);
  }
}

std::uint64_t ShmSegment::announce_sleeper() noexcept {
  if (user_index_ >= 0 && control().users[user_index_].process.load(std::memory_order_relaxed) !=
                              this_process_identity()) {
    const std::uint32_t roles = control().users[user_index_].roles.load(std::memory_order_relaxed);
    try {
      user_index_ = register_user(control(), roles, path_);
    } catch (const std::exception&) {
      // Every entry is a live handle's: sleep uncounted, as a handle without an entry does.
      user_index_ = -1;
    }
  }
  const std::uint64_t claimed_before = ring_add_sleeper(control().ring);
  if (claimed_before != UINT64_MAX && user_index_ >= 0) {
    control().users[user_index_].sleepers.fetch_add(1, std::memory_order_release);
  }
  return claimed_before;
}

void ShmSegment::withdraw_sleeper() noexcept {
  if (user_index_ >= 0) {
    control().users[user_index_].sleepers.fetch_sub(1, std::memory_order_relaxed);
  }
  ring_remove_sleeper(control().ring);
}

bool ring_reclaim_due() noexcept {
  constexpr std::int64_t kReclaimIntervalNs = 50'000'000;
  thread_local std::int64_t next_search_ns = 0;
  timespec now{};
  ::clock_gettime(CLOCK_MONOTONIC_COARSE, &now);  // the vDSO's: no syscall
  const std::int64_t now_ns = std::int64_t{now.tv_sec} * 1'000'000'000 + now.tv_nsec;
  if (now_ns < next_search_ns) {
    return false;
  }
  next_search_ns = now_ns + kReclaimIntervalNs;
  return true;
}

void ring_reclaim_dead_sleepers(const RingView& ring) noexcept {
  if (ring.users == nullptr) {
    return;
  }
  for (std::size_t i = 0; i < kMaxUsers; ++i) {
    UserEntry& user = ring.users[i];
    if (user.sleepers.load(std::memory_order_acquire) == 0) {
      continue;
    }
    std::uint64_t process = user.process.load(std::memory_order_acquire);
    if (process == 0 || identity_alive(process)) {
      continue;
    }
    // Taken over as register_user takes a dead entry, so only one process gives it back.
    const std::uint64_t me = this_process_identity();
    if (user.process.compare_exchange_strong(process, me, std::memory_order_acq_rel)) {
      give_back_sleepers(*ring.control, user);
      user.roles.store(0, std::memory_order_relaxed);
      user.process.store(0, std::memory_order_release);
    }
  }
}

void ShmSegment::release() noexcept {
  if (base_ == nullptr) {
    return;
  }
  if (user_index_ >= 0) {
    // Only the process that registered the handle frees its entry: a forked child letting go of
    // a handle it inherited leaves its parent's entry alone.
    UserEntry& user = control().users[user_index_];
    if (user.process.load(std::memory_order_relaxed) == this_process_identity()) {
      user.roles.store(0, std::memory_order_relaxed);
      user.process.store(0, std::memory_order_release);
    }
    user_index_ = -1;
  }
  ::munmap(base_, mapped_size_);
  base_ = nullptr;
  announced_ = AnnouncedUse();
}

}  // namespace horus::detail
