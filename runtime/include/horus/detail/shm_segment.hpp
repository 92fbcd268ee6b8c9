// The shared-memory segment behind one topic: its layout, its validation and its set-up.
//
// A segment is one file under the namespace folder (by default
// /dev/shm/horus-<uid>/<namespace>/<topic>):
//
//   [0, 4096)            ControlBlock: type-independent (write index, futex word, users table).
//                        Exists alone while only TopicNotifiers know the topic.
//   [4096, ...)          LayoutHeader: type identity (name, fingerprint) and geometry.
//   [schema_offset, ..)  the schema text, so tools can decode without the type.
//   [description_offset, ..)  the type description (MessagePack, "horus.typedesc"), so tools can
//                        walk messages without parsing the schema text; empty only when the
//                        creator (a raw opener) gave none.
//   [claims_offset, ..)  `capacity` SlotClaims: the publishers' side of each slot.
//   [slots_offset, ..)   `capacity` slots of `slot_stride` bytes: SlotHeader, then the payload.
//
// Every header field is validated against the file size before anything is trusted, and the
// geometry is copied out of shared memory: the hot paths never re-read a size another process
// could corrupt. See runtime/src/transport/README.md for the slot protocol.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "horus/detail/ring.hpp"
#include "horus/detail/shm_access.hpp"
#include "horus/presence.hpp"

namespace horus::detail {

inline constexpr std::uint64_t kControlMagic = 0x4c54435355524f48ULL;  // "HORUSCTL"
inline constexpr std::uint64_t kLayoutMagic = 0x504f545355524f48ULL;   // "HORUSTOP"
inline constexpr std::uint32_t kSegmentVersion = 8;
inline constexpr std::size_t kControlSize = 4096;
inline constexpr std::uint64_t kCacheLine = 64;
inline constexpr std::size_t kMaxUsers = 128;
inline constexpr std::size_t kMaxTypeName = 256;
inline constexpr std::size_t kMaxSchemaSize = std::size_t{1} << 20;
inline constexpr std::size_t kMaxDescriptionSize = std::size_t{1} << 20;
inline constexpr std::size_t kMaxCapacity = std::size_t{1} << 20;
inline constexpr std::size_t kMaxSlotPayload = std::size_t{1} << 30;

/// Bits of UserEntry::roles.
inline constexpr std::uint32_t kRolePublisher = 1;
inline constexpr std::uint32_t kRoleSubscriber = 2;
/// A TopicNotifier: maps only the control page, so it never prevents re-typing a dead topic.
inline constexpr std::uint32_t kRoleNotifier = 4;

/// One open Topic handle: its process and whether it has sent or received.
struct UserEntry {
  /// The identity (detail/process.hpp) of the process that opened the handle; 0 when the entry
  /// is free. A forked child using a handle it inherited is not recorded: the entry stays its
  /// parent's.
  std::atomic<std::uint64_t> process;
  std::atomic<std::uint32_t> roles;
  /// Sleeper announcements this handle holds in RingControl::write_index: counted after they
  /// are made and before they are withdrawn, so a dead process's count never exceeds what it
  /// left there, and whoever takes over its entry can give them back.
  std::atomic<std::uint32_t> sleepers;
};
static_assert(sizeof(UserEntry) == 16);

struct ControlBlock {
  std::uint64_t magic;
  std::uint32_t version;
  std::uint32_t control_size;
  /// 1 once the typed part after the control page is complete (written under the set-up lock).
  std::atomic<std::uint32_t> layout_ready;
  std::uint32_t reserved;
  RingControl ring;
  alignas(64) UserEntry users[kMaxUsers];
};
static_assert(sizeof(ControlBlock) <= kControlSize);

struct LayoutHeader {
  std::uint64_t magic;
  std::uint32_t version;
  std::uint32_t header_size;
  std::uint64_t fingerprint;
  std::uint32_t is_pod;
  std::uint32_t type_name_size;
  char type_name[kMaxTypeName];
  std::uint64_t type_size;  // sizeof(T) for a POD type, 0 for a serialized one
  std::uint64_t type_alignment;
  std::uint64_t capacity;  // slots, a power of two
  std::uint64_t slot_stride;
  std::uint64_t payload_offset;  // from the start of a slot
  std::uint64_t payload_capacity;
  std::uint64_t schema_offset;  // from the start of the file
  std::uint64_t schema_size;
  std::uint64_t claims_offset;
  std::uint64_t slots_offset;
  std::uint64_t total_size;
  std::uint64_t description_offset;  // from the start of the file, right after the schema
  std::uint64_t description_size;
};

/// What a segment records about the message type it carries.
struct TypeDescriptor {
  std::string_view name;
  std::uint64_t fingerprint;
  std::string_view schema;
  bool is_pod;
  std::size_t size;  // sizeof(T) of a POD type
  std::size_t alignment;
  /// The type description bytes; empty when the type carries none.
  std::string_view description{};
};

/// Set-up choices; only the creator's apply, later openers adopt the segment as it is.
struct SegmentOptions {
  std::size_t capacity;
  std::size_t max_message_size;  // serialized types: payload bytes per slot
  unsigned mode;
  std::string namespace_name;  // empty: current_namespace()
  bool single_publisher = false;
};

/// HORUS_NAMESPACE, or "default".
std::string current_namespace();
/// HORUS_SHM_DIR, or /dev/shm/horus-<effective uid>.
std::string shm_root();
/// Folder holding the segments of a namespace (empty: the current one).
std::string namespace_directory(std::string_view namespace_name);

/// A namespace folder opened and checked (detail/shm_access.hpp).
struct NamespaceFolder {
  /// -1 when the folder does not exist and was not to be created.
  FileDescriptor descriptor;
  std::string path;
};
/// Opens the folder of a namespace (empty: the current one) and the root above it, creating
/// them (for segments of `mode`) when missing and `create`. Throws horus::Error naming the
/// folder and its owner when another user could have planted or could write it.
NamespaceFolder open_namespace_folder(std::string_view namespace_name, unsigned mode, bool create);
/// Throws horus::Error unless `name` is usable as one path component ([A-Za-z0-9_.-], not . or ..).
void validate_segment_name(std::string_view what, std::string_view name);
/// Why a segment's headers cannot be trusted with `file_size` bytes, or empty when they can.
std::string validate_layout(const LayoutHeader& header, std::uint64_t file_size);
std::string validate_control(const ControlBlock& control);
/// Whether a live process has the segment open (a notifier counts).
bool segment_in_use(const ControlBlock& control);

/// An open, validated, mapped segment. Move-only; unmaps and leaves the users table on destruction.
class ShmSegment {
 public:
  /// Opens or creates the topic for `type`; throws horus::Error naming the path and the reason
  /// (another type, a corrupt or truncated segment, no space in /dev/shm, bad permissions).
  static ShmSegment open_topic(std::string_view topic, const TypeDescriptor& type,
                               const SegmentOptions& options);
  /// Maps only the control page (creating it when the topic does not exist yet): for notifiers.
  /// The handle is registered as a kRoleNotifier user so cleaning never unlinks it under us.
  static ShmSegment open_control(std::string_view topic, const SegmentOptions& options);

  ShmSegment(ShmSegment&& other) noexcept;
  ShmSegment& operator=(ShmSegment&& other) noexcept;
  ShmSegment(const ShmSegment&) = delete;
  ShmSegment& operator=(const ShmSegment&) = delete;
  ~ShmSegment();

  ControlBlock& control() const noexcept { return *reinterpret_cast<ControlBlock*>(base_); }
  /// Geometry copied out of the validated header (typed segments only).
  const RingView& ring() const noexcept { return ring_; }
  const std::string& path() const noexcept { return path_; }
  /// Records that this handle publishes or subscribes (for introspection); idempotent.
  void add_role(std::uint32_t role) noexcept;
  /// ring_add_sleeper, counted in this handle's user entry. A forked child sleeping on a handle
  /// it inherited first takes an entry of its own, so that its announcements are given back if
  /// it dies asleep (its parent's entry would keep them while the parent lives).
  std::uint64_t announce_sleeper() noexcept;
  /// ring_remove_sleeper for an announcement that announce_sleeper() made.
  void withdraw_sleeper() noexcept;

 private:
  ShmSegment() = default;
  void release() noexcept;

  void* base_ = nullptr;
  std::size_t mapped_size_ = 0;
  int user_index_ = -1;
  RingView ring_{};
  std::string path_;
  /// The handle in this process's presence announcement (typed handles only).
  AnnouncedUse announced_;
};

}  // namespace horus::detail
