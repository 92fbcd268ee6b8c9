// The presence registry, for tools (`horus node list`, `horus monitor`): every process running a
// Scheduler announces, in its namespace's shared memory, which nodes it runs and how they fare;
// every process with open topic handles, service servers or clients announces those (a process
// announcement, below), with or without a scheduler.
//
// Each running Scheduler owns one small file, <root>/@presence/<namespace>/<pid>.<n>, that a
// thread of its own rewrites (write aside, then rename) twice a second and when run() starts and
// ends, so a reader never sees half an announcement and no tick ever waits for one. The file goes
// when the Scheduler is destroyed (and the folder with the last one); a process that dies leaves it
// behind, and readers see from the recorded identity (pid and start time) that it is dead, even
// once its pid is reused.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace horus {

/// One Scheduler's announcement.
struct PresenceInfo {
  /// The file's name in the namespace's presence folder ("<pid>.<n>").
  std::string entry;
  std::uint32_t pid = 0;
  /// Whether the announcing process still runs (a process that took over its pid does not count).
  bool alive = false;
  /// When the announcing process started (ns since the Unix epoch, to the kernel's clock tick;
  /// from the recorded identity, so a dead one's too); 0 when unknown.
  std::int64_t started_wall_ns = 0;
  /// When the announcement was last rewritten (ns since the Unix epoch).
  std::int64_t updated_wall_ns = 0;
  /// The scheduler and its nodes as a JSON object: {"scheduler", "time_ns", "cycle",
  /// "deadline_misses" (all nodes'), "max_deadline_misses" (null: no limit), "nodes": [
  /// {"name", "order", "class", "rate_hz" (null without a rate), "state", "health",
  /// "total_ticks", "failed_ticks", "avg_tick_ns", "max_tick_ns", "last_tick_ns",
  /// "deadline_ns" (null: none), "deadline_misses", "budget_overruns", "messages_sent",
  /// "messages_received", "achieved_rate_hz", "publishers"/"subscribers": [{"topic", "type"}]}]}.
  /// A process announcement instead: {"process" (its program name), "topics": [{"topic",
  /// "type", "handles"}], "services": [{"service", "role" ("server" or "client"),
  /// "request_type", "response_type"}]}.
  std::string snapshot_json;
  /// Why the entry could not be read; empty when it was.
  std::string error;
};

/// The announcements of a namespace (empty: the current one), sorted by entry, the dead ones
/// included (alive == false).
std::vector<PresenceInfo> list_presence(std::string_view namespace_name = {});

/// Removes the announcements that dead processes left in a namespace; returns how many. The
/// namespace's presence folder goes too once it is empty and no live Scheduler uses it.
std::size_t clean_presence(std::string_view namespace_name = {});

namespace detail {

/// The announcement of one running Scheduler: its file, written only off the tick path.
class PresenceAnnouncement {
 public:
  /// Opens (creating) the namespace's presence folder. Throws horus::Error when it cannot be
  /// trusted or made.
  explicit PresenceAnnouncement(std::string_view namespace_name);
  ~PresenceAnnouncement();
  PresenceAnnouncement(const PresenceAnnouncement&) = delete;
  PresenceAnnouncement& operator=(const PresenceAnnouncement&) = delete;

  /// Replaces the announcement with `snapshot_json` (a slow path: file writes). False, with
  /// errno's text in `error`, when it could not.
  bool announce(std::string_view snapshot_json, std::string& error) noexcept;

 private:
  std::string namespace_;
  /// The folder, under a shared flock while this object lives.
  int folder_ = -1;
  std::string entry_;
};

/// What a process uses, for its process announcement.
struct ProcessUse {
  enum class Kind { Topic, ServiceServer, ServiceClient };
  Kind kind = Kind::Topic;
  std::string namespace_name;  // empty: the current one
  std::string name;
  std::string type;           // a topic's type, a service's request type
  std::string response_type;  // services only
};

/// Counts a use into this process's announcement in the use's namespace, which is rewritten
/// (the file appears with the first use and goes with the last). Never throws: a registry that
/// cannot be written leaves the process unannounced, never unable to open a topic. A slow path
/// (file writes): called where handles open and close, never per message.
void announce_use(const ProcessUse& use) noexcept;
void withdraw_use(const ProcessUse& use) noexcept;

/// How many times this process could not write a process announcement (its namespace's presence
/// folder is another user's, say, in a root shared by a group). The first failure is written to
/// stderr once, naming the path and the reason.
std::uint64_t announcement_failures() noexcept;

/// A use announced for the lifetime of the object (a topic handle, a server, a client).
class AnnouncedUse {
 public:
  AnnouncedUse() = default;
  explicit AnnouncedUse(ProcessUse use) noexcept : use_(std::move(use)), active_(true) {
    announce_use(use_);
  }
  AnnouncedUse(AnnouncedUse&& other) noexcept
      : use_(std::move(other.use_)), active_(std::exchange(other.active_, false)) {}
  AnnouncedUse& operator=(AnnouncedUse&& other) noexcept {
    if (this != &other) {
      reset();
      use_ = std::move(other.use_);
      active_ = std::exchange(other.active_, false);
    }
    return *this;
  }
  AnnouncedUse(const AnnouncedUse&) = delete;
  AnnouncedUse& operator=(const AnnouncedUse&) = delete;
  ~AnnouncedUse() { reset(); }

 private:
  void reset() noexcept {
    if (std::exchange(active_, false)) withdraw_use(use_);
  }
  ProcessUse use_;
  bool active_ = false;
};

}  // namespace detail
}  // namespace horus
