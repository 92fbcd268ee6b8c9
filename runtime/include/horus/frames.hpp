// Coordinate frames: one transform tree per namespace, in shared memory, that every process of
// the namespace writes and reads directly (no listener, no buffer per process).
//
// A process is the authority of the child frames it sets: it alone writes their transforms to
// their parent, and a second live process setting the same child is refused (a dead authority's
// frames can be taken over). Static transforms are kept for good; dynamic ones keep a history per
// frame (10 s by default) that any process reads lock-free, interpolating between the two entries
// around the time asked. runtime/src/frames/README.md gives the layout and the read protocol.
//
//   horus::FrameTree frames;                       // the current namespace's tree
//   frames.set_static_transform("base_link", "lidar", {{0.2, 0, 0.1}, {0, 0, 0, 1}});
//   frames.set_transform("odom", "base_link", odometry, stamp);
//   horus::Transform lidar_in_map = frames.lookup("map", "lidar", scan_stamp);
//   horus::Vector3 hit = horus::transform_point(lidar_in_map, point_in_lidar);
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "horus/error.hpp"

namespace horus {

struct Vector3 {
  double x = 0;
  double y = 0;
  double z = 0;
};

/// A rotation as a unit quaternion (x, y, z, w); the default is the identity.
struct Quaternion {
  double x = 0;
  double y = 0;
  double z = 0;
  double w = 1;
};

/// A rigid transform: `rotation` applied first, then `translation`. As the transform of a child
/// frame to its parent, it maps coordinates in the child frame to coordinates in the parent.
struct Transform {
  Vector3 translation;
  Quaternion rotation;
};

/// A position and orientation in some frame (the same numbers as the transform that takes the
/// pose's own axes to that frame).
using Pose = Transform;

/// One entry of a frame's history: its transform to `parent` at `stamp` (ns since the Unix epoch,
/// as horus::now() gives).
struct StampedTransform {
  std::string parent;
  std::string child;
  std::chrono::nanoseconds stamp{0};
  Transform transform;
};

// ---------------------------------------------------------------------------------------------
// Transform arithmetic (what lookups compose; also for users' own frames).

/// `a` after `b`: maps through `b` first, then `a` (parent_T_child = parent_T_middle *
/// middle_T_child).
Transform compose(const Transform& a, const Transform& b) noexcept;
Transform inverse(const Transform& t) noexcept;
/// Linear translation, spherical (shortest-arc) rotation; `fraction` 0 gives `a`, 1 gives `b`.
Transform interpolate(const Transform& a, const Transform& b, double fraction) noexcept;
/// A point: rotated, then translated.
Vector3 transform_point(const Transform& t, const Vector3& point) noexcept;
/// A direction (a velocity, a normal): rotated only.
Vector3 transform_vector(const Transform& t, const Vector3& vector) noexcept;
/// A pose given in the transform's source frame, expressed in its target frame.
Pose transform_pose(const Transform& t, const Pose& pose) noexcept;
Vector3 rotate(const Quaternion& q, const Vector3& v) noexcept;
Quaternion multiply(const Quaternion& a, const Quaternion& b) noexcept;
/// A rotation of `radians` about the unit `axis`.
Quaternion axis_angle(const Vector3& axis, double radians) noexcept;

// ---------------------------------------------------------------------------------------------
// Errors: each names the frame(s) and, where there is one, the amount.

/// Every failure of the frame tree (catch this for all of them).
class FrameError : public Error {
 public:
  using Error::Error;
};

/// A frame nobody has set; the message lists the closest known names.
class UnknownFrameError : public FrameError {
 public:
  UnknownFrameError(const std::string& message, std::string frame, std::vector<std::string> closest)
      : FrameError(message), frame_(std::move(frame)), closest_(std::move(closest)) {}
  const std::string& frame() const noexcept { return frame_; }
  const std::vector<std::string>& closest() const noexcept { return closest_; }

 private:
  std::string frame_;
  std::vector<std::string> closest_;
};

/// The time asked lies outside a frame's history: before its oldest entry (`into_past`) or after
/// its newest, by `by`.
class ExtrapolationError : public FrameError {
 public:
  ExtrapolationError(const std::string& message, std::string frame, bool into_past,
                     std::chrono::nanoseconds by)
      : FrameError(message), frame_(std::move(frame)), into_past_(into_past), by_(by) {}
  const std::string& frame() const noexcept { return frame_; }
  bool into_past() const noexcept { return into_past_; }
  std::chrono::nanoseconds by() const noexcept { return by_; }

 private:
  std::string frame_;
  bool into_past_;
  std::chrono::nanoseconds by_;
};

/// The two frames belong to trees with different roots: no transform joins them.
class DisconnectedFramesError : public FrameError {
 public:
  using FrameError::FrameError;
};

/// A frame's newest transform is older than the caller's limit, by `by`.
class StaleFrameError : public FrameError {
 public:
  StaleFrameError(const std::string& message, std::string frame, std::chrono::nanoseconds by)
      : FrameError(message), frame_(std::move(frame)), by_(by) {}
  const std::string& frame() const noexcept { return frame_; }
  std::chrono::nanoseconds by() const noexcept { return by_; }

 private:
  std::string frame_;
  std::chrono::nanoseconds by_;
};

/// A write refused because its transform is not one: NaN or infinity, or a rotation whose norm
/// is further than kRotationNormTolerance from 1.
class InvalidTransformError : public FrameError {
 public:
  using FrameError::FrameError;
};

/// A write refused because the child is an ancestor of its new parent (or the parent itself).
class FrameCycleError : public FrameError {
 public:
  using FrameError::FrameError;
};

/// A write refused because another live process is the child's authority; the message names it.
class FrameAuthorityError : public FrameError {
 public:
  FrameAuthorityError(const std::string& message, std::uint32_t pid, std::string program)
      : FrameError(message), pid_(pid), program_(std::move(program)) {}
  std::uint32_t pid() const noexcept { return pid_; }
  const std::string& program() const noexcept { return program_; }

 private:
  std::uint32_t pid_;
  std::string program_;
};

/// A write refused because the tree holds kMaxFrames frames already.
class FrameCapacityError : public FrameError {
 public:
  using FrameError::FrameError;
};

// ---------------------------------------------------------------------------------------------

/// Fixed capacities of every tree (runtime/src/frames/README.md says why).
inline constexpr std::size_t kMaxFrames = 256;
/// History entries kept per frame: 10 s at 100 Hz with room to spare; a faster writer keeps less
/// than its tree's history duration.
inline constexpr std::size_t kFrameHistoryEntries = 1024;
/// Frame names are at most this many bytes.
inline constexpr std::size_t kMaxFrameName = 63;
/// A written rotation's norm may differ from 1 by this much (float round-off of a computed
/// quaternion passes, a forgotten normalisation does not); it is stored normalised.
inline constexpr double kRotationNormTolerance = 1e-3;

struct FrameTreeOptions {
  /// The namespace whose tree this is; empty: the current one (HORUS_NAMESPACE).
  std::string namespace_name;
  /// How long dynamic transforms stay answerable. Only the tree's creator's choice applies.
  std::chrono::nanoseconds history = std::chrono::seconds(10);
  /// Creation mode of the tree's file (group bits share it with the group).
  unsigned mode = 0600;
};

/// What frames() reports of one frame.
struct FrameInfo {
  std::string name;
  /// Empty for a root (a frame only ever named as a parent).
  std::string parent;
  bool is_static = false;
  /// The authority's pid and program ("" when unknown); pid 0: none (a root).
  std::uint32_t authority_pid = 0;
  std::string authority_program;
  bool authority_alive = false;
  /// Stamps of the oldest answerable and the newest entry; zero without entries.
  std::chrono::nanoseconds oldest{0};
  std::chrono::nanoseconds latest{0};
  /// Transforms ever written to this frame (a rate is the difference of two readings).
  std::uint64_t updates = 0;
};

/// What FrameTree::history_since() gives.
struct FrameUpdates {
  std::vector<StampedTransform> entries;
  /// Of the updates asked for, those the history no longer held (overwritten, or older than the
  /// tree's history duration).
  std::uint64_t lost = 0;
  /// The update number to ask from next time.
  std::uint64_t next = 0;
};

/// One namespace's frame tree. Lookups are lock-free and safe from any thread; writes from one
/// thread per child frame. Opening creates the tree when missing.
class FrameTree {
 public:
  /// Throws FrameError when the tree's file is malformed or cannot be made.
  explicit FrameTree(FrameTreeOptions options = {});
  ~FrameTree();
  FrameTree(FrameTree&&) noexcept;
  FrameTree& operator=(FrameTree&&) noexcept;
  FrameTree(const FrameTree&) = delete;
  FrameTree& operator=(const FrameTree&) = delete;

  /// The transform of `child` to `parent` at `stamp` (stamps of one child must not go back in
  /// time; a static child becomes dynamic, its history starting afresh). Makes this process the
  /// child's authority. Throws InvalidTransformError, FrameCycleError, FrameAuthorityError,
  /// FrameCapacityError, FrameError (a stamp older than the child's newest).
  void set_transform(std::string_view parent, std::string_view child, const Transform& transform,
                     std::chrono::nanoseconds stamp);
  /// A transform that holds at every time (a sensor bolted to the base), kept after this process
  /// exits. Setting it again replaces it.
  void set_static_transform(std::string_view parent, std::string_view child,
                            const Transform& transform);

  /// The transform taking coordinates in `source` to `target`, at `time`; nullopt time: the latest
  /// time every frame of the chain has. `max_age`, when given: every dynamic frame of the chain
  /// must have an entry newer than now() - max_age (StaleFrameError otherwise).
  Transform lookup(std::string_view target, std::string_view source,
                   std::optional<std::chrono::nanoseconds> time = std::nullopt,
                   std::optional<std::chrono::nanoseconds> max_age = std::nullopt) const;
  /// The same, with the time the answer holds for (the latest common time when none was asked).
  StampedTransform lookup_stamped(
      std::string_view target, std::string_view source,
      std::optional<std::chrono::nanoseconds> time = std::nullopt,
      std::optional<std::chrono::nanoseconds> max_age = std::nullopt) const;
  /// Whether lookup() would answer (never throws a lookup error; `why`, when given, gets the
  /// message lookup would throw).
  bool can_lookup(std::string_view target, std::string_view source,
                  std::optional<std::chrono::nanoseconds> time = std::nullopt,
                  std::string* why = nullptr) const;
  /// Sleeps until the transform can be looked up (true) or `timeout` passes (false), woken by
  /// every write to the tree: no polling.
  bool wait_for(std::string_view target, std::string_view source,
                std::optional<std::chrono::nanoseconds> time,
                std::chrono::nanoseconds timeout) const;

  /// Every frame, in the order they were first named. Without `with_programs`, authority_alive
  /// and authority_program are left unset and no /proc file is read: for loops that follow the
  /// tree at its writers' rate.
  std::vector<FrameInfo> frames(bool with_programs = true) const;
  /// A frame's answerable history, oldest first (one entry for a static frame).
  std::vector<StampedTransform> history(std::string_view frame) const;
  /// The entries written to `frame` from its update number `since` on (FrameInfo::updates counts
  /// them; the first is 0), oldest first, as far as its history still holds them.
  FrameUpdates history_since(std::string_view frame, std::uint64_t since) const;
  /// Counts every write to the tree (wraps at 2^32): what tools wait on.
  std::uint32_t change_count() const noexcept;
  /// Sleeps while change_count() == `seen`, at most `timeout`; returns the count then.
  std::uint32_t wait_for_change(std::uint32_t seen, std::chrono::nanoseconds timeout) const;
  /// How long dynamic transforms stay answerable in this tree (its creator's choice).
  std::chrono::nanoseconds history_duration() const noexcept;

  /// The tree as indented text, one frame a line with its parent, authority and rate of entries.
  std::string as_text() const;
  /// The tree as a Graphviz digraph (parent -> child; static edges dashed).
  std::string as_dot() const;

  /// The path of the tree's file.
  const std::string& path() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Removes the namespace's frame tree file (empty: the current namespace); whether there was one.
/// Processes that have it open keep using their mapping.
bool remove_frame_tree(std::string_view namespace_name = {});

/// Whether the namespace's frame tree exists (empty: the current namespace), without creating it:
/// tools look before they open, since a tree's creator fixes its history duration.
bool frame_tree_exists(std::string_view namespace_name = {});

}  // namespace horus
