// Introspection of the topics of a namespace, for tools: what exists, with which type, who uses
// it and how busy it is, without decoding any message.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace horus {

struct TopicInfo {
  std::string name;
  /// Empty while only TopicNotifiers have opened the topic (no type chosen yet).
  std::string type_name;
  std::uint64_t fingerprint = 0;
  /// Canonical schema text of the type, enough to decode the messages.
  std::string schema;
  /// The type description bytes (MessagePack, "horus.typedesc"): the type's fields with offsets,
  /// defaults and units, for tools that walk messages; empty when the type carries none.
  std::string description;
  bool is_pod = false;
  std::size_t capacity = 0;
  /// Payload bytes per slot (sizeof(T) for POD types).
  std::size_t max_message_size = 0;
  /// Created with TopicOptions::single_publisher: one handle at a time may send.
  bool single_publisher = false;
  /// Open handles in live processes that have sent / received at least once.
  std::size_t publishers = 0;
  std::size_t subscribers = 0;
  /// The live processes with the segment open (any handle, notifiers too: what keeps
  /// `horus shm clean` away), ascending, each once.
  std::vector<std::uint32_t> user_pids;
  /// Whether the calling process has a Topic handle on it (a notifier does not count): how a
  /// session recording finds the topics its nodes opened without naming them.
  bool open_here = false;
  /// Messages sent since the segment was created.
  std::uint64_t message_count = 0;
  /// When the newest message still in the ring was sent, to the whole second of time() (a finer
  /// stamp would cost every send a clock read; time() may lag system_clock by a kernel tick);
  /// empty before the first message.
  std::optional<std::chrono::system_clock::time_point> last_send;
  /// Why the segment could not be read (corrupt, truncated, unreadable); empty when it was.
  std::string error;
};

/// HORUS_NAMESPACE, or "default".
std::string current_namespace();

/// The folder holding the topic segments of a namespace (empty: the current one).
std::string namespace_directory(std::string_view namespace_name = {});

/// The topics of a namespace (empty: the current one), sorted by name. A namespace nobody has
/// used yet has none.
std::vector<TopicInfo> list_topics(std::string_view namespace_name = {});

/// A message's ticket and its send stamp (whole seconds of time(), as TopicInfo::last_send).
struct SendStamp {
  std::uint64_t ticket = 0;
  std::uint32_t second = 0;
};

/// What `topic_traffic` counted: read from slot headers, no message decoded (`horus hz`, `bw`).
struct TopicTraffic {
  /// Messages sent since the segment was created.
  std::uint64_t message_count = 0;
  /// Of the messages from the asked ticket on, those still in the ring, and their payload bytes.
  std::uint64_t counted = 0;
  std::uint64_t bytes = 0;
  /// Of the messages still in the ring, the first and the last one stamped a later second than
  /// the message just before it (the same one when only one is): the (last - first) messages
  /// from one to the other took (last.second - first.second) seconds, give or take one message's
  /// period. The rate of a topic too slow for a short window to count (`horus topic list -v`).
  std::optional<SendStamp> first_new_second;
  std::optional<SendStamp> last_new_second;
  /// The newest message still in the ring.
  std::optional<SendStamp> newest;
};

/// The traffic of one topic from ticket `since` on (a message_count seen before). Throws
/// horus::Error naming the topic when it does not exist or cannot be read.
TopicTraffic topic_traffic(std::string_view topic, std::uint64_t since,
                           std::string_view namespace_name = {});

/// A namespace's shared-memory object other than a topic segment: its log ring ("@logs", what
/// `horus log` reads) or its presence folder ("@presence", what `horus node list` reads).
struct NamespaceObjectInfo {
  /// "@logs", "@presence", "@params" (one node's parameter store) or "@frames" (the tree).
  std::string kind;
  std::string path;
  /// Bytes: the ring's or the store's file size, the total of the folder's announcements, or
  /// the memory the frame tree holds (its file is sparse).
  std::size_t size = 0;
  /// Whether a live process writes the ring, a live Scheduler announces in the folder, the
  /// store's node runs, or a process has the frame tree open.
  bool in_use = false;
};

/// The namespace's log ring, presence folder, parameter stores and frame tree, those that exist,
/// in that order.
std::vector<NamespaceObjectInfo> list_namespace_objects(std::string_view namespace_name = {});

/// Unlinks the segments of a namespace whose every user process has died (they would otherwise
/// be re-used by the next opener); returns how many. Segments in use are left alone. The
/// namespace's log ring goes too once no live process writes it (its lines with it), and its
/// presence folder once it is empty (clean_presence() empties it) and no live Scheduler uses it,
/// each parameter store whose node no longer runs (its values with it), and the frame tree once
/// no process has it open (its static frames with it).
std::size_t clean_namespace(std::string_view namespace_name = {});

/// Unlinks every segment of a namespace and its folder, its log ring, its presence folder, its
/// parameter stores and its frame tree, in use or not (tests, `horus clean -f`). Handles still open
/// keep working on the unlinked memory but no longer meet new ones.
void remove_namespace(std::string_view namespace_name);

/// Unlinks the topic segments this process created that no live process has open any more, what
/// a Scheduler does when it is destroyed (a program without one, such as a Python script, calls
/// it itself); returns how many. Segments still in use are left alone.
std::size_t remove_created_topics_nobody_uses();

}  // namespace horus
