// The frame tree: its file, the authorities' writes and the lock-free lookups.
#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "frame_layout.hpp"
#include "horus/clock.hpp"
#include "horus/detail/futex.hpp"
#include "horus/detail/process.hpp"
#include "horus/detail/shm_access.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/frames.hpp"
#include "horus/internal/errno_text.hpp"
#include "horus/internal/namespace_objects.hpp"

namespace horus {

using detail::frames::FrameSlot;
using detail::frames::HistoryEntry;
using detail::frames::kEntryWords;
using detail::frames::kHeaderSize;
using detail::frames::kTotalSize;
using detail::frames::TreeHeader;
using std::chrono::nanoseconds;

namespace {

constexpr const char* kFramesFolder = "@frames";
/// A lookup whose entries a writer keeps overwriting under it starts over at most this often
/// (a writer would have to lap a 1024-entry history during one lookup), then gives up with an
/// error instead of spinning.
constexpr int kLookupAttempts = 16;

std::string tree_name(std::string_view namespace_name) {
  std::string name =
      namespace_name.empty() ? detail::current_namespace() : std::string(namespace_name);
  detail::validate_segment_name("namespace", name);
  return name;
}

std::string frames_directory() { return detail::shm_root() + "/" + kFramesFolder; }

detail::FileDescriptor open_frames_folder(unsigned mode, bool create) {
  const bool sharing = detail::group_sharing(mode);
  const std::string root = detail::shm_root();
  const detail::FileDescriptor root_folder =
      detail::open_trusted_directory(AT_FDCWD, root, root, mode, true, sharing, create);
  if (root_folder.get() < 0) return detail::FileDescriptor();
  return detail::open_trusted_directory(root_folder.get(), kFramesFolder, frames_directory(), mode,
                                        false, sharing, create);
}

/// Every process with the tree open holds a shared OFD lock on its first byte for as long as it
/// has it (the flock is the writers' structural lock: the two kinds never interact), so a cleaner
/// that gets the exclusive one knows nobody uses the tree. Waits out a cleaner that holds it.
void lock_as_user(int fd, const std::string& path) {
  struct flock range {};
  range.l_type = F_RDLCK;
  range.l_whence = SEEK_SET;
  range.l_len = 1;
  if (::fcntl(fd, F_OFD_SETLKW, &range) != 0) {
    throw FrameError("cannot lock the frame tree " + path + ": " + detail::errno_text(errno));
  }
}

/// Whether the lock of a user of the tree could be taken exclusively now (nobody uses it); holds
/// it until `fd` closes when so.
bool lock_as_cleaner(int fd) noexcept {
  struct flock range {};
  range.l_type = F_WRLCK;
  range.l_whence = SEEK_SET;
  range.l_len = 1;
  return ::fcntl(fd, F_OFD_SETLK, &range) == 0;
}

std::uint64_t hash_name(std::string_view name) noexcept {
  std::uint64_t hash = 14695981039346656037ULL;  // FNV-1a
  for (const char c : name) {
    hash = (hash ^ static_cast<unsigned char>(c)) * 1099511628211ULL;
  }
  return hash;
}

std::string slot_name(const FrameSlot& slot) {
  return {slot.name, ::strnlen(slot.name, detail::frames::kNameBytes)};
}

std::string milliseconds(nanoseconds amount) {
  char text[48];
  std::snprintf(text, sizeof(text), "%.3f ms", static_cast<double>(amount.count()) / 1e6);
  return text;
}

std::string seconds_text(nanoseconds stamp) {
  char text[48];
  std::snprintf(text, sizeof(text), "%.6f s", static_cast<double>(stamp.count()) / 1e9);
  return text;
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

void validate_frame_name(std::string_view name) {
  const auto allowed = [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-' || c == '.' || c == '/';
  };
  if (name.empty() || name.size() > kMaxFrameName || name.front() == '/' ||
      !std::all_of(name.begin(), name.end(), allowed)) {
    throw FrameError("invalid frame name \"" + std::string(name) + "\": 1 to " +
                     std::to_string(kMaxFrameName) +
                     " letters, digits, '_', '-', '.' or '/', not starting with '/'");
  }
}

/// The transform to store: finite, its rotation within kRotationNormTolerance of unit norm
/// (then normalised). Throws InvalidTransformError naming the frame.
Transform checked_transform(std::string_view parent, std::string_view child, const Transform& t) {
  const Vector3& v = t.translation;
  const Quaternion& q = t.rotation;
  const std::string which = "transform " + std::string(parent) + " <- " + std::string(child);
  for (const double value : {v.x, v.y, v.z, q.x, q.y, q.z, q.w}) {
    if (!std::isfinite(value)) {
      throw InvalidTransformError("refused " + which + ": it holds NaN or infinity");
    }
  }
  const double norm = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  if (std::abs(norm - 1) > kRotationNormTolerance) {
    throw InvalidTransformError("refused " + which + ": its rotation has norm " +
                                std::to_string(norm) + ", not 1 (within " +
                                std::to_string(kRotationNormTolerance) + ")");
  }
  return {v, {q.x / norm, q.y / norm, q.z / norm, q.w / norm}};
}

/// One entry as read out of shared memory.
struct EntryValue {
  nanoseconds stamp{0};
  std::uint32_t parent = 0;  // index + 1
  Transform transform;
};

void write_entry(FrameSlot& slot, std::uint64_t ticket, const EntryValue& value) noexcept {
  HistoryEntry& entry = slot.entries[ticket % kFrameHistoryEntries];
  std::uint64_t words[kEntryWords];
  words[0] = static_cast<std::uint64_t>(value.stamp.count());
  words[1] = value.parent;
  const double numbers[7] = {value.transform.translation.x, value.transform.translation.y,
                             value.transform.translation.z, value.transform.rotation.x,
                             value.transform.rotation.y,    value.transform.rotation.z,
                             value.transform.rotation.w};
  std::memcpy(&words[2], numbers, sizeof(numbers));
  entry.seq.store(2 * ticket + 1, std::memory_order_relaxed);
  // Each word's release store publishes the odd seq before it: a reader that sees a new word
  // also sees the entry as being written (no fences, which ThreadSanitizer cannot model).
  for (std::size_t i = 0; i < kEntryWords; ++i) {
    entry.words[i].store(words[i], std::memory_order_release);
  }
  entry.seq.store(2 * ticket + 2, std::memory_order_release);
}

/// Ticket `ticket` of the slot when it is complete and still there; false when it is being
/// written, was never finished (its writer died) or a later lap replaced it. Never waits.
bool read_entry(const FrameSlot& slot, std::uint64_t ticket, EntryValue& out) noexcept {
  const HistoryEntry& entry = slot.entries[ticket % kFrameHistoryEntries];
  const std::uint64_t before = entry.seq.load(std::memory_order_acquire);
  if (before != 2 * ticket + 2) return false;
  // Straight into the value (a braced list is evaluated in order): words gathered in an array
  // first were read back 16 bytes at a time from 8-byte stores, which stalls store forwarding.
  const auto word = [&](std::size_t i) { return entry.words[i].load(std::memory_order_acquire); };
  const auto number = [&](std::size_t i) { return std::bit_cast<double>(word(i)); };
  const EntryValue value{
      nanoseconds(static_cast<std::int64_t>(word(0))),
      static_cast<std::uint32_t>(word(1)),
      {{number(2), number(3), number(4)}, {number(5), number(6), number(7), number(8)}}};
  if (entry.seq.load(std::memory_order_relaxed) != before) return false;
  out = value;
  return true;
}

/// Only the stamp of ticket `ticket`, when the entry is complete, still there and under
/// `parent` (index + 1): what a search compares.
bool read_stamp(const FrameSlot& slot, std::uint64_t ticket, std::uint32_t parent,
                nanoseconds& stamp) noexcept {
  const HistoryEntry& entry = slot.entries[ticket % kFrameHistoryEntries];
  const std::uint64_t before = entry.seq.load(std::memory_order_acquire);
  if (before != 2 * ticket + 2) return false;
  const std::uint64_t stamp_word = entry.words[0].load(std::memory_order_acquire);
  const std::uint64_t parent_word = entry.words[1].load(std::memory_order_acquire);
  if (entry.seq.load(std::memory_order_relaxed) != before) return false;
  stamp = nanoseconds(static_cast<std::int64_t>(stamp_word));
  return parent_word == parent;
}

/// Thrown inside a lookup when a writer replaced what it was reading: the lookup starts over.
struct Overtaken {};

}  // namespace

struct FrameTree::Impl {
  std::string path;
  detail::FileDescriptor file;
  TreeHeader* header = nullptr;
  unsigned char* memory = nullptr;
  /// Copied out of the checked header: another process could change the shared one.
  nanoseconds history_duration{0};
  /// Serialises this process's structural writes; the flock on `file` serialises processes.
  std::mutex structure_mutex;

  ~Impl() {
    if (memory != nullptr) ::munmap(memory, kTotalSize);
  }

  FrameSlot& slot(std::uint32_t index) const noexcept {
    return *reinterpret_cast<FrameSlot*>(memory + kHeaderSize + index * sizeof(FrameSlot));
  }
  std::uint32_t count() const noexcept {
    return std::min<std::uint32_t>(header->frame_count.load(std::memory_order_acquire), kMaxFrames);
  }
  nanoseconds history() const noexcept { return history_duration; }

  /// What find_index() and parent_index() answer for "none". Lookups use these rather than the
  /// std::optional forms: GCC returns an optional<uint32_t> through the stack, stored in two
  /// parts and loaded whole, a store-forwarding stall on every step of a chain.
  static constexpr std::uint32_t kNone = 0xffffffff;

  std::uint32_t find_index(std::string_view name) const noexcept {
    const std::uint64_t hash = hash_name(name);
    const std::uint32_t frames = count();
    for (std::uint32_t i = 0; i < frames; ++i) {
      const FrameSlot& s = slot(i);
      if (s.name_hash == hash &&
          std::string_view(s.name, ::strnlen(s.name, detail::frames::kNameBytes)) == name) {
        return i;
      }
    }
    return kNone;
  }
  std::optional<std::uint32_t> find(std::string_view name) const noexcept {
    const std::uint32_t index = find_index(name);
    if (index == kNone) return std::nullopt;
    return index;
  }

  std::vector<std::string> closest(std::string_view name) const {
    std::vector<std::pair<std::size_t, std::string>> scored;
    const std::uint32_t frames = count();
    for (std::uint32_t i = 0; i < frames; ++i) {
      std::string known = slot_name(slot(i));
      const std::size_t distance = edit_distance(name, known);
      if (distance <= std::max<std::size_t>(2, name.size() / 2)) {
        scored.emplace_back(distance, std::move(known));
      }
    }
    std::sort(scored.begin(), scored.end());
    std::vector<std::string> names;
    for (std::size_t i = 0; i < scored.size() && i < 3; ++i) names.push_back(scored[i].second);
    return names;
  }

  std::uint32_t resolve(std::string_view name) const {
    if (const std::uint32_t index = find_index(name); index != kNone) return index;
    std::vector<std::string> near = closest(name);
    std::string message = "unknown frame \"" + std::string(name) + "\" in " + path;
    if (!near.empty()) {
      message += " (closest:";
      for (const std::string& n : near) message += " " + n;
      message += ")";
    }
    throw UnknownFrameError(message, std::string(name), std::move(near));
  }

  /// The parent index of frame `index`, or kNone for a root. A parent index out of range is a
  /// malformed file, reported, never followed.
  std::uint32_t parent_index(std::uint32_t index) const {
    const std::uint32_t parent = slot(index).parent.load(std::memory_order_acquire);
    if (parent == 0) return kNone;
    if (parent > count()) {
      throw FrameError("malformed frame tree " + path + ": frame \"" + slot_name(slot(index)) +
                       "\" has parent index " + std::to_string(parent - 1));
    }
    return parent - 1;
  }
  std::optional<std::uint32_t> parent_of(std::uint32_t index) const {
    const std::uint32_t parent = parent_index(index);
    if (parent == kNone) return std::nullopt;
    return parent;
  }

  /// A frame and its ancestors up to the root, on the stack: a lookup allocates nothing. The
  /// cycle check in chain() keeps `size` within the capacity.
  struct Chain {
    std::array<std::uint32_t, kMaxFrames + 1> indices;
    std::size_t size = 0;
    std::uint32_t operator[](std::size_t i) const noexcept { return indices[i]; }
    std::uint32_t back() const noexcept { return indices[size - 1]; }
    const std::uint32_t* begin() const noexcept { return indices.data(); }
    const std::uint32_t* end() const noexcept { return indices.data() + size; }
  };

  /// `index` and its ancestors up to the root.
  Chain chain(std::uint32_t index) const {
    Chain frames;
    frames.indices[frames.size++] = index;
    for (std::uint32_t parent = parent_index(index); parent != kNone;
         parent = parent_index(parent)) {
      if (frames.size > kMaxFrames) {
        throw FrameError("malformed frame tree " + path + ": the ancestors of \"" +
                         slot_name(slot(index)) + "\" form a cycle");
      }
      frames.indices[frames.size++] = parent;
    }
    // A root with an authority is a child whose first transform is being written (its parent
    // is stored last): not a tree of its own.
    const FrameSlot& root = slot(frames.back());
    if (root.authority.load(std::memory_order_acquire) != 0) {
      const std::string name = slot_name(root);
      throw ExtrapolationError("frame \"" + name + "\" has no transform yet", name, true,
                               nanoseconds{0});
    }
    return frames;
  }

  /// The answerable tickets of a frame under `parent` (index + 1): [first, last].
  struct Range {
    std::uint64_t first = 0;
    std::uint64_t last = 0;
    EntryValue oldest;
    EntryValue latest;
    bool is_static = false;
    /// Entries older than this are past the history duration.
    nanoseconds horizon{0};
    /// Whether `oldest` was read whole, or only its stamp (a lookup's, until it needs the rest).
    bool oldest_whole = true;
  };
  /// Fills `r` (in place: a lookup reads one per link) and returns true, or false when the frame
  /// has no entry. Without `answerable_oldest` (a lookup's range), `first` and `oldest` may be
  /// older than `horizon`, and only the stamp of `oldest` is read: a lookup at a time needs the
  /// oldest answerable entry only when the time is older than that, which transform_at() finds
  /// out without searching for it, and needs the oldest entry whole only when it interpolates
  /// from it.
  bool read_range(std::uint32_t index, std::uint32_t parent, bool answerable_oldest,
                  Range& r) const {
    const FrameSlot& s = slot(index);
    const std::uint64_t written = s.write_count.load(std::memory_order_acquire);
    const std::uint64_t first_ticket = s.first_ticket.load(std::memory_order_acquire);
    r.is_static = s.is_static.load(std::memory_order_acquire) != 0;
    // The entry after the newest is the one a writer overwrites next: never count on it.
    const std::uint64_t window = kFrameHistoryEntries - 1;
    r.first = std::max(first_ticket, written > window ? written - window : 0);
    if (written == 0 || r.first > written - 1) return false;
    r.last = written - 1;
    if (!read_entry(s, r.last, r.latest) || r.latest.parent != parent) throw Overtaken{};
    if (r.is_static) {
      r.first = r.last;
      r.oldest = r.latest;
      r.oldest_whole = true;
      r.horizon = r.latest.stamp;
      return true;
    }
    r.oldest_whole = answerable_oldest;
    if (!answerable_oldest) {
      if (!read_stamp(s, r.first, parent, r.oldest.stamp)) throw Overtaken{};
    } else if (!read_entry(s, r.first, r.oldest) || r.oldest.parent != parent) {
      throw Overtaken{};
    }
    // Entries older than the history duration are no longer answerable.
    r.horizon = r.latest.stamp - history();
    if (answerable_oldest && r.oldest.stamp < r.horizon) {
      std::uint64_t low = r.first;  // stamp < horizon
      std::uint64_t high = r.last;  // stamp >= horizon
      bracket(s, parent, r.horizon - nanoseconds{1}, low, r.oldest.stamp, high, r.latest.stamp);
      r.first = high;
      if (high == r.last) {
        r.oldest = r.latest;
      } else if (!read_entry(s, high, r.oldest)) {
        throw Overtaken{};
      }
    }
    return true;
  }
  std::optional<Range> range(std::uint32_t index, std::uint32_t parent) const {
    Range r;
    if (!read_range(index, parent, true, r)) return std::nullopt;
    return r;
  }

  /// Narrows tickets [low, high], whose stamps are `low_stamp` <= `time` < `high_stamp`, to two
  /// neighbours, reading only stamps. Entries come at a steady rate, so the first probes aim
  /// where `time` falls between the two stamps (at 100 Hz one or two probes find it); later ones
  /// bisect, so an irregular history still takes O(log n) probes.
  void bracket(const FrameSlot& s, std::uint32_t parent, nanoseconds time, std::uint64_t& low,
               nanoseconds low_stamp, std::uint64_t& high, nanoseconds high_stamp) const {
    constexpr int kAimedProbes = 3;
    for (int probes = 0; high - low > 1; ++probes) {
      std::uint64_t middle = low + (high - low) / 2;
      const double fraction = static_cast<double>((time - low_stamp).count()) /
                              static_cast<double>((high_stamp - low_stamp).count());
      if (probes < kAimedProbes && fraction >= 0 && fraction < 1) {
        const auto aimed =
            low + static_cast<std::uint64_t>(fraction * static_cast<double>(high - low));
        middle = std::clamp(aimed, low + 1, high - 1);
      }
      nanoseconds stamp;
      if (!read_stamp(s, middle, parent, stamp)) throw Overtaken{};
      if (stamp <= time) {
        low = middle;
        low_stamp = stamp;
      } else {
        high = middle;
        high_stamp = stamp;
      }
    }
  }

  /// Throws the extrapolation into the past of frame `index` asked at `time`, measured from its
  /// oldest answerable entry (Overtaken when a writer moved that meanwhile).
  [[noreturn]] void throw_into_past(std::uint32_t index, std::uint32_t parent,
                                    nanoseconds time) const {
    const std::optional<Range> answerable = range(index, parent);
    if (!answerable || time >= answerable->oldest.stamp) throw Overtaken{};
    const std::string name = slot_name(slot(index));
    const nanoseconds by = answerable->oldest.stamp - time;
    throw ExtrapolationError("extrapolation into the past: frame \"" + name + "\" asked at " +
                                 seconds_text(time) + ", " + milliseconds(by) +
                                 " before its oldest transform",
                             name, true, by);
  }

  /// The transform of frame `index` to its parent `parent` (index + 1) at `time`.
  Transform transform_at(std::uint32_t index, std::uint32_t parent, const Range& r,
                         nanoseconds time) const {
    if (r.is_static || time == r.latest.stamp) return r.latest.transform;
    if (time > r.latest.stamp) {
      const std::string name = slot_name(slot(index));
      const nanoseconds by = time - r.latest.stamp;
      throw ExtrapolationError("extrapolation into the future: frame \"" + name + "\" asked at " +
                                   seconds_text(time) + ", " + milliseconds(by) +
                                   " after its newest transform",
                               name, false, by);
    }
    if (time < r.oldest.stamp) throw_into_past(index, parent, time);
    const FrameSlot& s = slot(index);
    std::uint64_t low = r.first;  // stamp <= time
    std::uint64_t high = r.last;  // stamp > time
    bracket(s, parent, time, low, r.oldest.stamp, high, r.latest.stamp);
    EntryValue read_before;
    EntryValue read_after;
    const EntryValue* before = &r.oldest;
    const EntryValue* after = &r.latest;
    if (low != r.first || !r.oldest_whole) {
      if (!read_entry(s, low, read_before) || read_before.parent != parent) throw Overtaken{};
      before = &read_before;
    }
    if (high != r.last) {
      if (!read_entry(s, high, read_after) || read_after.parent != parent) throw Overtaken{};
      after = &read_after;
    }
    // Only entries within the history duration answer (the range may have left older ones in).
    if (before->stamp < r.horizon) throw_into_past(index, parent, time);
    const nanoseconds span = after->stamp - before->stamp;
    if (span <= nanoseconds::zero()) return after->transform;
    const double fraction =
        static_cast<double>((time - before->stamp).count()) / static_cast<double>(span.count());
    return interpolate(before->transform, after->transform, fraction);
  }

  /// What a lookup answers, without the frames' names (copying them could allocate).
  struct Answer {
    nanoseconds stamp{0};
    Transform transform;
  };

  /// The links of one lookup: on the stack for any realistic chain, on the heap only beyond
  /// kInlineLinks (a Link is about 190 bytes; a chain of kMaxFrames would not fit a stack).
  /// Never initialised as a whole: a lookup writes only the links it composes.
  struct Link {
    std::uint32_t index;
    std::uint32_t parent;
    Range range;
  };
  static constexpr std::size_t kInlineLinks = 32;
  class Links {
   public:
    explicit Links(std::size_t capacity) {
      if (capacity > kInlineLinks) {
        spilled_.reserve(capacity);
        links_ = spilled_.data();
      } else {
        links_ = reinterpret_cast<Link*>(inline_);
      }
    }
    Links(const Links&) = delete;
    Links& operator=(const Links&) = delete;
    /// A new link, its range to be filled.
    Link& add(std::uint32_t index, std::uint32_t parent) noexcept {
      Link* link = ::new (links_ + size_++) Link;
      link->index = index;
      link->parent = parent;
      return *link;
    }
    const Link& operator[](std::size_t i) const noexcept { return links_[i]; }
    const Link* begin() const noexcept { return links_; }
    const Link* end() const noexcept { return links_ + size_; }

   private:
    alignas(Link) unsigned char inline_[kInlineLinks * sizeof(Link)];
    std::vector<Link> spilled_;
    Link* links_;
    std::size_t size_ = 0;
  };
  static_assert(std::is_trivially_copyable_v<Link> && std::is_trivially_destructible_v<Link>);

  Answer lookup_once(std::string_view target, std::string_view source,
                     std::optional<nanoseconds> time, std::optional<nanoseconds> max_age) const {
    const std::uint32_t source_index = resolve(source);
    const std::uint32_t target_index = resolve(target);
    Answer out{time.value_or(nanoseconds{0}), {}};
    if (source_index == target_index) return out;
    const Chain up_from_source = chain(source_index);
    const Chain up_from_target = chain(target_index);
    std::size_t source_steps = 0;
    std::size_t target_steps = 0;
    bool joined = false;
    for (; source_steps < up_from_source.size && !joined; ++source_steps) {
      const auto found =
          std::find(up_from_target.begin(), up_from_target.end(), up_from_source[source_steps]);
      if (found != up_from_target.end()) {
        target_steps = static_cast<std::size_t>(found - up_from_target.begin());
        joined = true;
      }
    }
    if (!joined) {
      throw DisconnectedFramesError(
          "frames \"" + std::string(target) + "\" and \"" + std::string(source) +
          "\" are in two unconnected trees (roots \"" + slot_name(slot(up_from_target.back())) +
          "\" and \"" + slot_name(slot(up_from_source.back())) + "\")");
    }
    --source_steps;  // the loop stepped past the common ancestor
    // The frames whose transforms the answer composes: below the common ancestor on each side.
    Links links(source_steps + target_steps);
    const auto collect = [&](const Chain& up, std::size_t steps) {
      for (std::size_t i = 0; i < steps; ++i) {
        const std::uint32_t parent = up[i + 1] + 1;
        if (!read_range(up[i], parent, false, links.add(up[i], parent).range)) {
          throw ExtrapolationError("frame \"" + slot_name(slot(up[i])) + "\" has no transform yet",
                                   slot_name(slot(up[i])), true, nanoseconds{0});
        }
      }
    };
    collect(up_from_source, source_steps);
    collect(up_from_target, target_steps);
    if (max_age) {
      const nanoseconds limit = horus::now() - *max_age;
      for (const Link& link : links) {
        if (!link.range.is_static && link.range.latest.stamp < limit) {
          const std::string name = slot_name(slot(link.index));
          const nanoseconds by = limit - link.range.latest.stamp;
          throw StaleFrameError("stale frame \"" + name + "\": its newest transform is " +
                                    milliseconds(by) + " older than the limit of " +
                                    milliseconds(*max_age),
                                name, by);
        }
      }
    }
    if (!time) {
      std::optional<nanoseconds> common;
      for (const Link& link : links) {
        if (!link.range.is_static) {
          common = std::min(common.value_or(link.range.latest.stamp), link.range.latest.stamp);
        }
      }
      out.stamp = common.value_or(nanoseconds{0});
    }
    // Each side from the common ancestor down. The identity is never composed in: a side of one
    // link is that link's transform, and a side of none leaves the other side's as the answer.
    const auto down_to = [&](std::size_t first_link, std::size_t steps) {
      Transform ancestor_from_frame;
      for (std::size_t i = steps; i-- > 0;) {
        const Link& link = links[first_link + i];
        const Transform step = transform_at(link.index, link.parent, link.range, out.stamp);
        ancestor_from_frame = i + 1 == steps ? step : compose(ancestor_from_frame, step);
      }
      return ancestor_from_frame;
    };
    const Transform ancestor_from_source = down_to(0, source_steps);
    const Transform ancestor_from_target = down_to(source_steps, target_steps);
    if (target_steps == 0) {
      out.transform = ancestor_from_source;
    } else if (source_steps == 0) {
      out.transform = inverse(ancestor_from_target);
    } else {
      out.transform = compose(inverse(ancestor_from_target), ancestor_from_source);
    }
    return out;
  }

  Answer lookup(std::string_view target, std::string_view source, std::optional<nanoseconds> time,
                std::optional<nanoseconds> max_age) const {
    for (int attempt = 0; attempt < kLookupAttempts; ++attempt) {
      try {
        return lookup_once(target, source, time, max_age);
      } catch (const Overtaken&) {
        // A writer replaced entries under this lookup, or reparented a frame: read again.
      }
    }
    throw FrameError("cannot look up " + std::string(target) + " <- " + std::string(source) +
                     ": its frames were rewritten during " + std::to_string(kLookupAttempts) +
                     " attempts");
  }

  void bump_changes() noexcept {
    header->changes.fetch_add(1, std::memory_order_seq_cst);
    if (header->waiters.load(std::memory_order_seq_cst) != 0) {
      detail::futex_wake_all(header->changes);
    }
  }

  /// The frame `name`, published when new with `authority` (0 for a root; a child is published
  /// with its writer's, so that until its parent is stored readers take it for a child without a
  /// transform yet, not for a root). Under the structure lock.
  std::uint32_t find_or_add(std::string_view name, std::uint64_t authority) {
    if (const std::optional<std::uint32_t> index = find(name)) return *index;
    const std::uint32_t index = header->frame_count.load(std::memory_order_relaxed);
    if (index >= kMaxFrames) {
      throw FrameCapacityError("cannot add frame \"" + std::string(name) + "\" to " + path +
                               ": it holds " + std::to_string(kMaxFrames) +
                               " frames, the most a tree holds");
    }
    FrameSlot& s = slot(index);
    // A process killed while adding this slot may have left anything in it.
    std::memset(s.name, 0, sizeof(s.name));
    std::memcpy(s.name, name.data(), name.size());
    s.name_hash = hash_name(name);
    s.authority.store(authority, std::memory_order_relaxed);
    s.parent.store(0, std::memory_order_relaxed);
    s.is_static.store(0, std::memory_order_relaxed);
    s.first_ticket.store(0, std::memory_order_relaxed);
    s.write_count.store(0, std::memory_order_relaxed);
    header->frame_count.store(index + 1, std::memory_order_release);
    return index;
  }

  /// Makes this process the authority of `child` with `parent` and kind `is_static`, and writes
  /// the first entry of that parentage. Under the structure lock (both process and file).
  void claim_and_write(std::string_view parent_name, std::string_view child_name, bool is_static,
                       const EntryValue& given) {
    const std::uint64_t me = detail::this_process_identity();
    const std::uint32_t parent = find_or_add(parent_name, 0);
    const std::uint32_t child = find_or_add(child_name, me);
    FrameSlot& s = slot(child);
    const std::uint64_t authority = s.authority.load(std::memory_order_acquire);
    if (authority != 0 && authority != me && detail::identity_alive(authority)) {
      const std::uint32_t pid = detail::identity_pid(authority);
      const std::string program = detail::process_name(pid);
      throw FrameAuthorityError("refused to set frame \"" + std::string(child_name) +
                                    "\": process " + std::to_string(pid) + " (" + program +
                                    ") is its authority; a frame is set by one process",
                                pid, program);
    }
    for (std::uint32_t up = parent;;) {
      if (up == child) {
        throw FrameCycleError("refused transform " + std::string(parent_name) + " <- " +
                              std::string(child_name) + ": \"" + std::string(child_name) +
                              "\" is an ancestor of \"" + std::string(parent_name) +
                              "\", which would make a cycle");
      }
      const std::optional<std::uint32_t> next = parent_of(up);
      if (!next) break;
      up = *next;
    }
    s.authority.store(me, std::memory_order_release);
    const std::uint64_t written = s.write_count.load(std::memory_order_relaxed);
    const bool same_parentage = s.parent.load(std::memory_order_relaxed) == parent + 1 &&
                                (s.is_static.load(std::memory_order_relaxed) != 0) == is_static &&
                                written > s.first_ticket.load(std::memory_order_relaxed);
    if (same_parentage) {
      write_next(child, given, is_static);
      return;
    }
    // A new parent or kind: the older entries stop applying. Readers see the new parent only
    // after the entry written for it (README.md).
    EntryValue value = given;
    value.parent = parent + 1;
    s.first_ticket.store(written, std::memory_order_release);
    s.is_static.store(is_static ? 1 : 0, std::memory_order_release);
    write_entry(s, written, value);
    s.write_count.store(written + 1, std::memory_order_release);
    s.parent.store(parent + 1, std::memory_order_release);
    bump_changes();
  }

  /// The authority's append of the child's next entry (same parent and kind).
  void write_next(std::uint32_t child, EntryValue value, bool is_static) {
    FrameSlot& s = slot(child);
    value.parent = s.parent.load(std::memory_order_relaxed);
    const std::uint64_t written = s.write_count.load(std::memory_order_relaxed);
    if (!is_static && written > 0) {
      EntryValue newest;
      if (read_entry(s, written - 1, newest) && value.stamp < newest.stamp) {
        throw FrameError("refused transform of frame \"" + slot_name(s) + "\" at " +
                         seconds_text(value.stamp) + ": " +
                         milliseconds(newest.stamp - value.stamp) +
                         " older than its newest; a frame's stamps must not go back");
      }
    }
    write_entry(s, written, value);
    s.write_count.store(written + 1, std::memory_order_release);
    bump_changes();
  }

  void set(std::string_view parent_name, std::string_view child_name, const Transform& transform,
           nanoseconds stamp, bool is_static) {
    validate_frame_name(parent_name);
    validate_frame_name(child_name);
    if (parent_name == child_name) {
      throw FrameCycleError("refused transform " + std::string(parent_name) + " <- " +
                            std::string(child_name) + ": a frame cannot be its own parent");
    }
    EntryValue value{stamp, 0, checked_transform(parent_name, child_name, transform)};
    // The hot path: this process already sets the child, under the same parent and kind.
    if (const std::optional<std::uint32_t> child = find(child_name)) {
      const FrameSlot& s = slot(*child);
      const std::optional<std::uint32_t> parent = find(parent_name);
      if (parent &&
          s.authority.load(std::memory_order_acquire) == detail::this_process_identity() &&
          s.parent.load(std::memory_order_acquire) == *parent + 1 &&
          (s.is_static.load(std::memory_order_acquire) != 0) == is_static) {
        write_next(*child, value, is_static);
        return;
      }
    }
    const std::lock_guard<std::mutex> in_process(structure_mutex);
    if (::flock(file.get(), LOCK_EX) != 0) {
      throw FrameError("cannot lock the frame tree " + path + ": " + detail::errno_text(errno));
    }
    try {
      claim_and_write(parent_name, child_name, is_static, value);
    } catch (...) {
      ::flock(file.get(), LOCK_UN);
      throw;
    }
    ::flock(file.get(), LOCK_UN);
  }
};

namespace {

std::string validate_tree(const void* memory, std::size_t size) {
  if (size < sizeof(TreeHeader)) return "shorter than a frame tree header";
  const auto* header = static_cast<const TreeHeader*>(memory);
  if (header->magic != detail::frames::kTreeMagic) return "not a horus frame tree (bad magic)";
  if (header->version != detail::frames::kTreeVersion) {
    return "frame tree version " + std::to_string(header->version) + ", this build reads " +
           std::to_string(detail::frames::kTreeVersion);
  }
  if (header->header_size != kHeaderSize || header->max_frames != kMaxFrames ||
      header->history_entries != kFrameHistoryEntries || header->frame_size != sizeof(FrameSlot) ||
      header->total_size != kTotalSize) {
    return "its geometry differs from this build's";
  }
  if (size != kTotalSize) return "its size does not match its geometry";
  if (header->history_ns <= 0) return "its history duration is not positive";
  if (header->frame_count.load(std::memory_order_acquire) > kMaxFrames) {
    return "it claims more frames than it holds";
  }
  return {};
}

void format_tree(void* memory, nanoseconds history) noexcept {
  auto* header = static_cast<TreeHeader*>(memory);
  header->version = detail::frames::kTreeVersion;
  header->header_size = kHeaderSize;
  header->max_frames = kMaxFrames;
  header->history_entries = kFrameHistoryEntries;
  header->frame_size = sizeof(FrameSlot);
  header->total_size = kTotalSize;
  header->history_ns = history.count();
  header->frame_count.store(0, std::memory_order_relaxed);
  header->changes.store(0, std::memory_order_relaxed);
  header->waiters.store(0, std::memory_order_relaxed);
  header->magic = detail::frames::kTreeMagic;
}

void* map_tree(int fd, const std::string& path) {
  void* memory = ::mmap(nullptr, kTotalSize, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (memory == MAP_FAILED) {
    throw FrameError("cannot map the frame tree " + path + ": " + detail::errno_text(errno));
  }
  return memory;
}

}  // namespace

FrameTree::FrameTree(FrameTreeOptions options) : impl_(std::make_unique<Impl>()) {
  if (options.history <= nanoseconds::zero()) {
    throw FrameError("a frame tree's history must be positive");
  }
  detail::check_creation_mode(options.mode, "frame tree");
  const std::string name = tree_name(options.namespace_name);
  const bool sharing = detail::group_sharing(options.mode);
  impl_->path = frames_directory() + "/" + name;
  const std::string& path = impl_->path;
  const detail::FileDescriptor folder = open_frames_folder(options.mode, true);
  for (;;) {
    struct stat named {};
    if (::fstatat(folder.get(), name.c_str(), &named, AT_SYMLINK_NOFOLLOW) != 0 &&
        errno == ENOENT) {
      // Made unnamed, formatted, then named: nobody ever sees a tree half made.
      detail::FileDescriptor fd(
          ::openat(folder.get(), ".", O_TMPFILE | O_RDWR | O_CLOEXEC, options.mode & 0777));
      if (fd.get() < 0) {
        throw FrameError("cannot create the frame tree " + path + ": " + detail::errno_text(errno));
      }
      if (::fchmod(fd.get(), options.mode & 0777) != 0 ||
          ::ftruncate(fd.get(), static_cast<off_t>(kTotalSize)) != 0) {
        throw FrameError("cannot size the frame tree " + path + ": " + detail::errno_text(errno));
      }
      lock_as_user(fd.get(), path);
      void* memory = map_tree(fd.get(), path);
      format_tree(memory, options.history);
      const std::string self = "/proc/self/fd/" + std::to_string(fd.get());
      if (::linkat(AT_FDCWD, self.c_str(), folder.get(), name.c_str(), AT_SYMLINK_FOLLOW) != 0) {
        const int error = errno;
        ::munmap(memory, kTotalSize);
        if (error == EEXIST) continue;  // another process named its tree first: use that one
        throw FrameError("cannot name the frame tree " + path + ": " + detail::errno_text(error));
      }
      impl_->file = std::move(fd);
      impl_->memory = static_cast<unsigned char*>(memory);
      break;
    }
    detail::FileDescriptor fd =
        detail::open_trusted_file(folder.get(), name, path, O_RDWR, 0, sharing);
    lock_as_user(fd.get(), path);
    if (!detail::still_linked(fd.get())) continue;  // a cleaner removed it before we locked
    struct stat info {};
    if (::fstat(fd.get(), &info) != 0) {
      throw FrameError("cannot stat the frame tree " + path + ": " + detail::errno_text(errno));
    }
    const auto size = static_cast<std::size_t>(info.st_size);
    if (size != kTotalSize) {
      throw FrameError("frame tree " + path + ": " + std::to_string(size) + " bytes, not the " +
                       std::to_string(kTotalSize) + " of a frame tree");
    }
    void* memory = map_tree(fd.get(), path);
    if (const std::string why = validate_tree(memory, size); !why.empty()) {
      ::munmap(memory, kTotalSize);
      throw FrameError("frame tree " + path + ": " + why);
    }
    impl_->file = std::move(fd);
    impl_->memory = static_cast<unsigned char*>(memory);
    break;
  }
  impl_->header = reinterpret_cast<TreeHeader*>(impl_->memory);
  impl_->history_duration = nanoseconds(impl_->header->history_ns);
  if (impl_->history_duration <= nanoseconds::zero()) {
    throw FrameError("frame tree " + impl_->path + ": its history duration is not positive");
  }
}

FrameTree::~FrameTree() = default;
FrameTree::FrameTree(FrameTree&&) noexcept = default;
FrameTree& FrameTree::operator=(FrameTree&&) noexcept = default;

void FrameTree::set_transform(std::string_view parent, std::string_view child,
                              const Transform& transform, nanoseconds stamp) {
  impl_->set(parent, child, transform, stamp, false);
}

void FrameTree::set_static_transform(std::string_view parent, std::string_view child,
                                     const Transform& transform) {
  impl_->set(parent, child, transform, horus::now(), true);
}

Transform FrameTree::lookup(std::string_view target, std::string_view source,
                            std::optional<nanoseconds> time,
                            std::optional<nanoseconds> max_age) const {
  return impl_->lookup(target, source, time, max_age).transform;
}

StampedTransform FrameTree::lookup_stamped(std::string_view target, std::string_view source,
                                           std::optional<nanoseconds> time,
                                           std::optional<nanoseconds> max_age) const {
  const Impl::Answer answer = impl_->lookup(target, source, time, max_age);
  return {std::string(target), std::string(source), answer.stamp, answer.transform};
}

bool FrameTree::can_lookup(std::string_view target, std::string_view source,
                           std::optional<nanoseconds> time, std::string* why) const {
  try {
    impl_->lookup(target, source, time, std::nullopt);
    return true;
  } catch (const FrameError& error) {
    if (why != nullptr) *why = error.what();
    return false;
  }
}

bool FrameTree::wait_for(std::string_view target, std::string_view source,
                         std::optional<nanoseconds> time, nanoseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  TreeHeader& header = *impl_->header;
  for (;;) {
    // Read before the check: a write after the check changes the word and the sleep returns.
    const std::uint32_t seen = header.changes.load(std::memory_order_seq_cst);
    if (can_lookup(target, source, time)) return true;
    const nanoseconds left = deadline - std::chrono::steady_clock::now();
    if (left <= nanoseconds::zero()) return false;
    wait_for_change(seen, left);
  }
}

std::uint32_t FrameTree::change_count() const noexcept {
  return impl_->header->changes.load(std::memory_order_acquire);
}

std::uint32_t FrameTree::wait_for_change(std::uint32_t seen, nanoseconds timeout) const {
  TreeHeader& header = *impl_->header;
  // Announced before the word is re-read, and a writer bumps the word before it reads the
  // count (both sequentially consistent): either the writer sees a sleeper and wakes it, or
  // the sleeper sees the new word and does not sleep.
  header.waiters.fetch_add(1, std::memory_order_seq_cst);
  if (header.changes.load(std::memory_order_seq_cst) == seen) {
    detail::futex_wait(header.changes, seen, timeout);
  }
  header.waiters.fetch_sub(1, std::memory_order_seq_cst);
  return header.changes.load(std::memory_order_acquire);
}

nanoseconds FrameTree::history_duration() const noexcept { return impl_->history(); }

const std::string& FrameTree::path() const noexcept { return impl_->path; }

std::vector<FrameInfo> FrameTree::frames(bool with_programs) const {
  std::vector<FrameInfo> out;
  const std::uint32_t count = impl_->count();
  for (std::uint32_t index = 0; index < count; ++index) {
    const FrameSlot& s = impl_->slot(index);
    FrameInfo info;
    info.name = slot_name(s);
    const std::optional<std::uint32_t> parent = impl_->parent_of(index);
    if (parent) info.parent = slot_name(impl_->slot(*parent));
    info.is_static = s.is_static.load(std::memory_order_acquire) != 0;
    const std::uint64_t authority = s.authority.load(std::memory_order_acquire);
    info.authority_pid = detail::identity_pid(authority);
    if (authority != 0 && with_programs) {
      info.authority_alive = detail::identity_alive(authority);
      info.authority_program = info.authority_alive ? detail::process_name(info.authority_pid) : "";
    }
    info.updates = s.write_count.load(std::memory_order_acquire);
    if (parent) {
      for (int attempt = 0; attempt < kLookupAttempts; ++attempt) {
        try {
          if (const auto r = impl_->range(index, *parent + 1)) {
            info.oldest = r->oldest.stamp;
            info.latest = r->latest.stamp;
          }
          break;
        } catch (const Overtaken&) {
        }
      }
    }
    out.push_back(std::move(info));
  }
  return out;
}

std::vector<StampedTransform> FrameTree::history(std::string_view frame) const {
  return history_since(frame, 0).entries;
}

FrameUpdates FrameTree::history_since(std::string_view frame, std::uint64_t since) const {
  const std::uint32_t index = impl_->resolve(frame);
  const std::optional<std::uint32_t> parent = impl_->parent_of(index);
  FrameUpdates out;
  out.next = since;
  if (!parent) return out;
  const std::string parent_name = slot_name(impl_->slot(*parent));
  const FrameSlot& s = impl_->slot(index);
  for (int attempt = 0; attempt < kLookupAttempts; ++attempt) {
    try {
      const auto r = impl_->range(index, *parent + 1);
      if (!r || r->last < since) return out;
      const std::uint64_t first = std::max(r->first, since);
      std::uint64_t lost = first - since;
      for (std::uint64_t ticket = first; ticket <= r->last; ++ticket) {
        EntryValue value;
        if (read_entry(s, ticket, value) && value.parent == *parent + 1) {
          out.entries.push_back({parent_name, std::string(frame), value.stamp, value.transform});
        } else {
          ++lost;  // overwritten since the range was read
        }
      }
      out.lost = lost;
      out.next = r->last + 1;
      return out;
    } catch (const Overtaken&) {
      out.entries.clear();
    }
  }
  return out;
}

std::string FrameTree::as_text() const {
  const std::vector<FrameInfo> all = frames();
  std::ostringstream text;
  const std::function<void(const std::string&, int)> print = [&](const std::string& parent,
                                                                 int depth) {
    for (const FrameInfo& frame : all) {
      if (frame.parent != parent) continue;
      text << std::string(static_cast<std::size_t>(depth) * 2, ' ') << frame.name;
      if (!parent.empty()) {
        text << (frame.is_static ? "  [static" : "  [dynamic");
        if (!frame.is_static && frame.latest > frame.oldest && frame.updates > 1) {
          const double seconds = static_cast<double>((frame.latest - frame.oldest).count()) / 1e9;
          const auto kept =
              static_cast<double>(std::min<std::uint64_t>(frame.updates, kFrameHistoryEntries));
          char rate[32];
          std::snprintf(rate, sizeof(rate), ", %.1f Hz", (kept - 1) / seconds);
          text << rate;
        }
        text << ", pid " << frame.authority_pid;
        if (!frame.authority_program.empty()) text << " " << frame.authority_program;
        if (!frame.authority_alive) text << " (exited)";
        text << "]";
      }
      text << "\n";
      print(frame.name, depth + 1);
    }
  };
  print("", 0);
  return text.str();
}

std::string FrameTree::as_dot() const {
  std::ostringstream dot;
  dot << "digraph frames {\n";
  for (const FrameInfo& frame : frames()) {
    dot << "  \"" << frame.name << "\";\n";
    if (!frame.parent.empty()) {
      dot << "  \"" << frame.parent << "\" -> \"" << frame.name << "\"";
      if (frame.is_static) dot << " [style=dashed]";
      dot << ";\n";
    }
  }
  dot << "}\n";
  return dot.str();
}

bool remove_frame_tree(std::string_view namespace_name) {
  const std::string name = tree_name(namespace_name);
  const detail::FileDescriptor folder = open_frames_folder(0600, false);
  if (folder.get() < 0) return false;
  if (::unlinkat(folder.get(), name.c_str(), 0) == 0) return true;
  if (errno == ENOENT) return false;
  throw FrameError("cannot remove the frame tree " + frames_directory() + "/" + name + ": " +
                   detail::errno_text(errno));
}

namespace detail {

std::optional<NamespaceObjectInfo> frame_tree_object(std::string_view namespace_name) {
  const std::string name = tree_name(namespace_name);
  const FileDescriptor folder = open_frames_folder(0600, false);
  if (folder.get() < 0) return std::nullopt;
  NamespaceObjectInfo info;
  info.kind = kFramesFolder;
  info.path = frames_directory() + "/" + name;
  struct stat status {};
  if (::fstatat(folder.get(), name.c_str(), &status, AT_SYMLINK_NOFOLLOW) != 0) return std::nullopt;
  try {
    // Read-write: an exclusive OFD lock needs a descriptor open for writing.
    const FileDescriptor file = open_trusted_file(folder.get(), name, info.path, O_RDWR, 0, false);
    // The memory it holds: tmpfs gives pages only to the frames and entries written.
    if (::fstat(file.get(), &status) == 0)
      info.size = static_cast<std::size_t>(status.st_blocks) * 512;
    info.in_use = !lock_as_cleaner(file.get());
  } catch (const Error&) {
    info.in_use = true;  // not ours to judge: left for a person
  }
  return info;
}

bool remove_unused_frame_tree(std::string_view namespace_name) {
  const std::string name = tree_name(namespace_name);
  const FileDescriptor folder = open_frames_folder(0600, false);
  if (folder.get() < 0) return false;
  try {
    const FileDescriptor file =
        open_trusted_file(folder.get(), name, frames_directory() + "/" + name, O_RDWR, 0, false);
    if (!lock_as_cleaner(file.get()) || !still_linked(file.get())) return false;
    // Unlinked while locked: an opener waiting for the lock sees it gone and makes a new tree.
    return ::unlinkat(folder.get(), name.c_str(), 0) == 0;
  } catch (const Error&) {
    return false;  // missing, or not ours to judge
  }
}

}  // namespace detail

bool frame_tree_exists(std::string_view namespace_name) {
  const std::string name = tree_name(namespace_name);
  const detail::FileDescriptor folder = open_frames_folder(0600, false);
  if (folder.get() < 0) return false;
  struct stat status {};
  return ::fstatat(folder.get(), name.c_str(), &status, 0) == 0;
}

}  // namespace horus
