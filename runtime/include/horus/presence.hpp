// The presence registry, for tools (`horus node list`, `horus monitor`): every process running a
// Scheduler announces, in its namespace's shared memory, which nodes it runs and how they fare.
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
#include <vector>

namespace horus {

/// One Scheduler's announcement.
struct PresenceInfo {
  /// The file's name in the namespace's presence folder ("<pid>.<n>").
  std::string entry;
  std::uint32_t pid = 0;
  /// Whether the announcing process still runs (a process that took over its pid does not count).
  bool alive = false;
  /// When the announcement was last rewritten (ns since the Unix epoch).
  std::int64_t updated_wall_ns = 0;
  /// The scheduler and its nodes as a JSON object: {"scheduler", "time_ns", "cycle", "nodes": [
  /// {"name", "order", "class", "rate_hz" (null without a rate), "state", "health",
  /// "total_ticks", "failed_ticks", "avg_tick_ns", "max_tick_ns", "last_tick_ns",
  /// "deadline_misses", "budget_overruns", "messages_sent", "messages_received",
  /// "achieved_rate_hz", "publishers"/"subscribers": [{"topic", "type"}]}]}.
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

}  // namespace detail
}  // namespace horus
