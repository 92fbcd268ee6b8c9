// detail::Replayer: see horus/internal/replayer.hpp and docs/recording.md.
#include "horus/internal/replayer.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <optional>
#include <span>
#include <string_view>
#include <utility>

#include "horus/detail/ring.hpp"
#include "horus/detail/service_frame.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/detail/topic_endpoint.hpp"
#include "horus/error.hpp"
#include "horus/frames.hpp"
#include "horus/internal/created_segments.hpp"
#include "horus/log.hpp"
#include "horus/pool_frames.hpp"
#include "horus/recording.hpp"
#include "horus/topic_registry.hpp"
#include "horus/type_description.hpp"

namespace horus::detail {
namespace {

constexpr std::string_view kTicksTopic = "/horus/ticks";

/// The unsigned integer after `"key":` in a tick record (written by recorder.cpp), if any.
bool json_number(std::string_view text, std::string_view key, std::uint64_t& value) {
  const std::string pattern = "\"" + std::string(key) + "\":";
  const std::size_t at = text.find(pattern);
  if (at == std::string_view::npos) return false;
  const std::string digits(text.substr(at + pattern.size(), 24));
  char* end = nullptr;
  value = std::strtoull(digits.c_str(), &end, 10);
  return end != digits.c_str();
}

/// The JSON string literal starting at text[at] (as json_string writes it), or nullopt.
std::optional<std::string> json_literal(std::string_view text, std::size_t& at) {
  if (at >= text.size() || text[at] != '"') return std::nullopt;
  std::string out;
  for (++at; at < text.size(); ++at) {
    const char c = text[at];
    if (c == '"') {
      ++at;
      return out;
    }
    if (c != '\\') {
      out += c;
    } else if (at + 1 < text.size() && text[at + 1] == 'u' && at + 6 <= text.size()) {
      out +=
          static_cast<char>(std::strtoul(std::string(text.substr(at + 2, 4)).c_str(), nullptr, 16));
      at += 5;
    } else if (at + 1 < text.size()) {
      out += text[++at];
    }
  }
  return std::nullopt;
}

using Counts = std::vector<std::pair<std::string, std::uint64_t>>;

/// One recorded tick: the node, its cycle and start, the ring positions of the topics it reads
/// when it started ("received") and how far it read them by its end ("taken", when it read any),
/// as recorder.cpp writes them.
struct RecordedTick {
  std::string node;
  std::uint64_t cycle = 0;
  std::uint64_t start_ns = 0;
  Counts received;
  Counts taken;
};

/// The object `"key":{topic: count, ...}` of a tick record into `counts`; false when malformed.
bool parse_counts(std::string_view text, std::string_view key, Counts& counts) {
  const std::string pattern = "\"" + std::string(key) + "\":{";
  std::size_t at = text.find(pattern);
  if (at == std::string_view::npos) return true;
  at += pattern.size();
  while (at < text.size() && text[at] != '}') {
    if (text[at] == ',') ++at;
    std::optional<std::string> topic = json_literal(text, at);
    if (!topic || at >= text.size() || text[at] != ':') return false;
    const std::string digits(text.substr(at + 1, 24));
    char* end = nullptr;
    const std::uint64_t count = std::strtoull(digits.c_str(), &end, 10);
    if (end == digits.c_str()) return false;
    at += 1 + static_cast<std::size_t>(end - digits.c_str());
    counts.emplace_back(std::move(*topic), count);
  }
  return true;
}

std::optional<RecordedTick> parse_tick(std::string_view text) {
  RecordedTick tick;
  std::size_t at = text.find("\"node\":");
  if (at == std::string_view::npos) return std::nullopt;
  at += 7;
  std::optional<std::string> node = json_literal(text, at);
  if (!node || !json_number(text, "tick", tick.cycle) ||
      !json_number(text, "start_ns", tick.start_ns))
    return std::nullopt;
  tick.node = std::move(*node);
  if (!parse_counts(text, "received", tick.received) || !parse_counts(text, "taken", tick.taken))
    return std::nullopt;
  return tick;
}

/// Where one node was on one topic at each of its ticks that carried it: (the node's tick
/// number, the tickets within its reach: those handed out when it started, or as far as it read
/// by its end when a publisher on another thread sent more meanwhile and it took them).
using Positions = std::vector<std::pair<std::uint64_t, std::uint64_t>>;

/// The number of the first of `ticks` that had `ticket` within its reach, or nullopt.
std::optional<std::uint64_t> first_receipt(const Positions& ticks, std::uint64_t ticket) {
  const auto first =
      std::upper_bound(ticks.begin(), ticks.end(), ticket,
                       [](std::uint64_t t, const std::pair<std::uint64_t, std::uint64_t>& tick) {
                         return t < tick.second;
                       });
  if (first == ticks.end()) return std::nullopt;
  return first->first;
}

/// The frames the recording process set itself (its "horus.frames" authorities that are the
/// "horus.session" pid): a scheduler's own nodes', which a replay of them sets again.
std::set<std::string> frames_set_by_recording_process(const RecordingReader& recording) {
  std::string session_pid;
  for (const RecordedMetadata& metadata : recording.metadata()) {
    if (metadata.name != "horus.session") continue;
    if (const auto pid = metadata.entries.find("pid"); pid != metadata.entries.end())
      session_pid = pid->second;
  }
  std::set<std::string> own;
  constexpr std::string_view kPrefix = "authority.";
  for (const RecordedMetadata& metadata : recording.metadata()) {
    if (metadata.name != kFramesMetadata) continue;
    for (const auto& [key, pid] : metadata.entries) {
      if (key.starts_with(kPrefix) && !session_pid.empty() && pid == session_pid)
        own.insert(key.substr(kPrefix.size()));
    }
  }
  return own;
}

bool is_service_type(std::string_view type_name) {
  return type_name == TypeInfo<ServiceRegistration>::name ||
         type_name.starts_with(kRequestFrameName) || type_name.starts_with(kResponseFrameName);
}

std::uint64_t parse_fingerprint(const RecordedChannel& channel, const std::string& where) {
  const auto found = channel.metadata.find("horus.fingerprint");
  if (found == channel.metadata.end() || found->second.size() != 16) {
    throw Error(where + ": topic '" + channel.topic + "' has no horus.fingerprint");
  }
  return std::strtoull(found->second.c_str(), nullptr, 16);
}

std::string hex16(std::uint64_t value) {
  char text[24];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

/// Refuses a recorded type description that is not of the channel's type: the replayed segment
/// would tell every tool that opens it another layout than its messages have.
void check_description(const RecordedChannel& channel, const std::string& type_name,
                       std::uint64_t fingerprint, const std::string& where) {
  const std::string topic = where + ": topic '" + channel.topic + "': ";
  try {
    const TypeDescription description = TypeDescription::decode(channel.description);
    const MessageType& root = description.root_message();
    if (description.root == type_name && root.fingerprint == fingerprint) return;
    throw Error(topic + "its type description is of " + description.root + " (fingerprint " +
                hex16(root.fingerprint) + "), the channel's type is " + type_name +
                " (fingerprint " + hex16(fingerprint) + "); refusing to replay it");
  } catch (const TypeDescriptionError& e) {
    throw Error(topic + "its type description cannot be read: " + e.what());
  }
}

}  // namespace

Replayer::Replayer(const std::filesystem::path& path, const std::string& namespace_name,
                   const std::set<std::string>& skip)
    : namespace_(namespace_name) {
  const RecordingReader recording(path);
  const std::string where = "replay of " + path.string();
  // Read (and a malformed record refused) before any topic is opened.
  std::vector<RecordedFrameChange> frame_changes = recorded_frame_changes(recording);
  const std::set<std::string> own_frames = frames_set_by_recording_process(recording);
  const std::vector<TopicInfo> now = list_topics(namespace_name);
  // Every channel is checked before the first topic is opened, so that a refusal leaves nothing
  // behind in the namespace.
  struct Planned {
    std::uint16_t id;
    const RecordedChannel* channel;
    TypeDescriptor descriptor;
    SegmentOptions options;
    bool pool;
    bool existed;
  };
  std::vector<Planned> planned;
  for (const auto& entry : recording.channels()) {
    const std::uint16_t id = entry.first;
    const RecordedChannel& channel = entry.second;
    if (channel.topic == kTicksTopic || channel.topic == kParamsChannel ||
        channel.topic == kFramesChannel || channel.topic == kStaticFramesChannel ||
        skip.count(channel.topic) != 0)
      continue;
    const auto schema = recording.schemas().find(channel.schema_id);
    if (schema == recording.schemas().end()) {
      throw Error(where + ": topic '" + channel.topic + "' refers to a missing schema");
    }
    const RecordedSchema& type = schema->second;
    // The nodes make their service calls again: recorded requests fed to their server would be
    // answered twice, and a recorded registration would announce a server that is not there.
    if (is_service_type(type.name)) continue;
    const std::uint64_t fingerprint = parse_fingerprint(channel, where);
    if (!channel.description.empty()) check_description(channel, type.name, fingerprint, where);
    const auto live = std::find_if(now.begin(), now.end(),
                                   [&](const TopicInfo& t) { return t.name == channel.topic; });
    if (live != now.end() && !live->type_name.empty() &&
        (live->type_name != type.name || live->fingerprint != fingerprint)) {
      char text[200];
      std::snprintf(text, sizeof text, "(fingerprint %016llx) but carries %s (fingerprint %016llx)",
                    static_cast<unsigned long long>(fingerprint), live->type_name.c_str(),
                    static_cast<unsigned long long>(live->fingerprint));
      throw Error(where + ": topic '" + channel.topic + "' was recorded as " + type.name + " " +
                  text + " now: the type changed since the recording; refusing to replay it");
    }
    const bool pool = channel.message_encoding == kPoolEncoding;
    const bool pod = pool || channel.message_encoding == "horus.pod";
    std::size_t size = 0;
    if (pod) {
      const auto found = channel.metadata.find("horus.payload_size");
      size =
          found == channel.metadata.end() ? 0 : std::strtoull(found->second.c_str(), nullptr, 10);
    }
    std::size_t largest = size;  // a pool-backed topic's ring carries the descriptor only
    for (const RecordedMessage& m : recording.messages()) {
      if (m.channel_id == id && !pool) largest = std::max(largest, m.data.size());
    }
    planned.push_back(Planned{
        id, &channel,
        TypeDescriptor{type.name, fingerprint, type.data, pod, size, 1, channel.description},
        SegmentOptions{live != now.end() ? live->capacity : 64,
                       std::max<std::size_t>(largest, std::size_t{16} * 1024), 0600, namespace_name,
                       false},
        pool, live != now.end()});
  }
  std::map<std::uint16_t, std::pair<TopicEndpoint*, PoolFrames*>> endpoints;
  try {
    for (const Planned& plan : planned) {
      topics_.push_back(std::make_unique<TopicEndpoint>(
          ShmSegment::open_topic(plan.channel->topic, plan.descriptor, plan.options)));
      PoolFrames* frames = nullptr;
      if (plan.pool) {
        // Each frame is made again in this namespace's pool; the ring's capacity of them stay
        // alive.
        frames_.push_back(make_pool_frames(plan.descriptor.name, plan.descriptor.fingerprint,
                                           namespace_name, topics_.back()->ring().mask + 1));
        if (!frames_.back()) {
          throw Error(where + ": topic '" + plan.channel->topic + "' holds " +
                      std::string(plan.descriptor.name) +
                      " frames with their data, which only a program linking horus::pool "
                      "replays");
        }
        frames = frames_.back().get();
      }
      endpoints[plan.id] = {topics_.back().get(), frames};
    }
  } catch (...) {
    // The topics this replay created go again (those another process opened meanwhile stay).
    frames_.clear();
    topics_.clear();
    const NamespaceFolder folder = open_namespace_folder(namespace_name, 0600, false);
    for (const Planned& plan : planned) {
      if (!plan.existed && folder.descriptor.get() >= 0) {
        remove_if_abandoned(folder, plan.channel->topic);
      }
    }
    throw;
  }
  const RecordedChannel* ticks = recording.channel(kTicksTopic);
  // The ticks first: when each cycle began, and where each reading node was on its topics at
  // each of its ticks, numbered in the order the node ran them (the live run's cycle numbers
  // cannot be matched: a live node's first tick falls in whatever cycle the loop had reached).
  std::map<std::uint64_t, std::uint64_t> cycle_starts;
  std::map<std::string, std::uint64_t, std::less<>> tick_counts;
  std::map<std::string, std::vector<std::uint64_t>, std::less<>> tick_cycles;  // by node
  std::map<std::uint16_t, std::map<std::string, Positions>> positions;         // by channel, node
  std::map<std::string, std::uint16_t, std::less<>> channel_ids;
  for (const auto& [id, channel] : recording.channels()) channel_ids.emplace(channel.topic, id);
  for (const RecordedMessage& m : recording.messages()) {
    if (ticks == nullptr || m.channel_id != ticks->id) continue;
    const std::optional<RecordedTick> tick =
        parse_tick(std::string_view(reinterpret_cast<const char*>(m.data.data()), m.data.size()));
    if (!tick) continue;
    auto [first, fresh] = cycle_starts.emplace(tick->cycle, tick->start_ns);
    if (!fresh) first->second = std::min(first->second, tick->start_ns);
    has_ticks_ = true;
    last_cycle_ = std::max(last_cycle_, tick->cycle);
    const std::uint64_t number = tick_counts[tick->node]++;
    tick_cycles[tick->node].push_back(tick->cycle);
    for (const auto& [topic, received] : tick->received) {
      const auto channel = channel_ids.find(topic);
      if (channel == channel_ids.end()) continue;
      std::uint64_t reach = received;
      for (const auto& [read_topic, taken] : tick->taken) {
        if (read_topic == topic) reach = std::max(reach, taken);
      }
      positions[channel->second][tick->node].emplace_back(number, reach);
    }
  }
  // The file's sequence numbers are tickets mod 2^32, in order on a channel: each is unwrapped
  // against the previous one, starting from the lowest position a reader noted.
  std::map<std::uint16_t, std::uint64_t> tickets;
  for (auto& [channel, readers] : positions) {
    std::uint64_t lowest = UINT64_MAX;
    for (auto& [node, ticks_of_node] : readers) {
      // The counts only grow; the running maximum keeps them sorted for first_receipt.
      for (std::size_t i = 1; i < ticks_of_node.size(); ++i)
        ticks_of_node[i].second = std::max(ticks_of_node[i].second, ticks_of_node[i - 1].second);
      lowest = std::min(lowest, ticks_of_node.front().second);
    }
    tickets[channel] = lowest;
  }
  for (const RecordedMessage& m : recording.messages()) {
    const auto endpoint = endpoints.find(m.channel_id);
    if (endpoint == endpoints.end()) continue;
    const std::size_t index = messages_.size();
    messages_.push_back(Message{endpoint->second.first, endpoint->second.second, m.data, false});
    const auto readers = positions.find(m.channel_id);
    if (readers != positions.end()) {
      std::uint64_t& ticket = tickets[m.channel_id];
      ticket += static_cast<std::int32_t>(m.sequence - static_cast<std::uint32_t>(ticket));
      // What came after a reader's last recorded tick is due at its next one, not earlier by
      // some cycle count: the replay's cycles are not the live run's.
      for (const auto& [node, ticks_of_node] : readers->second) {
        readers_[node].due.emplace_back(
            first_receipt(ticks_of_node, ticket).value_or(tick_counts.at(node)), index);
      }
      continue;
    }
    // No node that names the topic recorded a tick: before the first cycle that began after the
    // recorder took it (after the last, once the recorded cycles are exhausted).
    const auto after = std::find_if(cycle_starts.begin(), cycle_starts.end(),
                                    [&](const auto& cycle) { return cycle.second > m.log_time; });
    unread_.emplace_back(after != cycle_starts.end() ? after->first : UINT64_MAX, index);
  }
  std::stable_sort(unread_.begin(), unread_.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  // Another process's frames, as its messages: before the first cycle that began after the
  // recorder took them (all before the first cycle when the file has no ticks: the tree keeps
  // them by their stamps, so lookups at the recorded times answer as they did).
  for (RecordedFrameChange& change : frame_changes) {
    if (own_frames.count(change.transform.child) != 0) continue;
    const auto after = std::find_if(cycle_starts.begin(), cycle_starts.end(),
                                    [&](const auto& c) { return c.second > change.log_time; });
    frames_due_.emplace_back(after != cycle_starts.end() ? after->first : UINT64_MAX,
                             std::move(change));
  }
  std::stable_sort(frames_due_.begin(), frames_due_.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (auto& [node, reader] : readers_) std::sort(reader.due.begin(), reader.due.end());
  for (RecordedParamChange& change : recorded_param_changes(recording)) {
    if (change.start || !change.cycle) continue;
    const auto cycles = tick_cycles.find(change.node);
    std::uint64_t number = 0;
    if (cycles != tick_cycles.end()) {
      // A node's recorded cycles only grow (one thread ticks it).
      number = static_cast<std::uint64_t>(
          std::lower_bound(cycles->second.begin(), cycles->second.end(), *change.cycle) -
          cycles->second.begin());
    }
    ParamChanges& changes = param_changes_[change.node];
    changes.due.emplace_back(number, std::move(change));
  }
  for (auto& [node, changes] : param_changes_) {
    std::stable_sort(changes.due.begin(), changes.due.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
  }
}

std::map<std::string, std::map<std::string, std::string>> recorded_starting_params(
    const std::filesystem::path& path) {
  std::map<std::string, std::map<std::string, std::string>> values;
  for (RecordedParamChange& change : recorded_param_changes(RecordingReader(path))) {
    // The last starting value recorded for a node wins: a node started again in the same
    // session records its values again.
    if (change.start) values[change.node][change.name] = std::move(change.value);
  }
  return values;
}

void Replayer::apply_params_before_tick(
    std::string_view node, const std::function<void(const RecordedParamChange&)>& apply) {
  const auto found = param_changes_.find(node);
  if (found == param_changes_.end()) return;
  ParamChanges& changes = found->second;
  for (; changes.next < changes.due.size() && changes.due[changes.next].first <= changes.ticks;
       ++changes.next)
    apply(changes.due[changes.next].second);
  ++changes.ticks;
}

Replayer::~Replayer() = default;

void Replayer::deliver_before_cycle(std::uint64_t cycle) {
  const std::uint64_t until = !has_ticks_ || cycle > last_cycle_ ? UINT64_MAX : cycle;
  for (; next_frame_ < frames_due_.size() && frames_due_[next_frame_].first <= until; ++next_frame_)
    set_frame(frames_due_[next_frame_].second);
  for (; next_unread_ < unread_.size() && unread_[next_unread_].first <= until; ++next_unread_)
    send(unread_[next_unread_].second);
}

void Replayer::deliver_before_tick(std::string_view node) {
  if (Reader* reader = deliver_for_next_tick(node)) ++reader->ticks;
}

Replayer::Reader* Replayer::deliver_for_next_tick(std::string_view node) {
  const auto found = readers_.find(node);
  if (found == readers_.end()) return nullptr;
  Reader& reader = found->second;
  // In recorded order, so a topic's messages keep their order whichever reader calls for them.
  for (; reader.next < reader.due.size() && reader.due[reader.next].first <= reader.ticks;
       ++reader.next)
    send(reader.due[reader.next].second);
  return &reader;
}

void Replayer::set_frame(const RecordedFrameChange& change) {
  const StampedTransform& t = change.transform;
  try {
    if (!frame_tree_) {
      FrameTreeOptions options;
      options.namespace_name = namespace_;
      frame_tree_ = std::make_unique<FrameTree>(std::move(options));
    }
    if (change.is_static) {
      frame_tree_->set_static_transform(t.parent, t.child, t.transform);
    } else {
      frame_tree_->set_transform(t.parent, t.child, t.transform, t.stamp);
    }
  } catch (const FrameError& e) {
    // Another live process is its authority here, or a node of the replay set it meanwhile.
    if (refused_frames_.insert(t.child).second)
      log::warn("replay: frame '%s' is not set from the recording: %s", t.child.c_str(), e.what());
  }
}

void Replayer::send(std::size_t message) {
  Message& m = messages_[message];
  if (m.sent) return;
  m.sent = true;
  ++delivered_;
  std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(m.data.data()),
                                   m.data.size());
  if (m.frames != nullptr) {
    try {
      bytes = m.frames->replay(m.data);
    } catch (const Error& e) {
      log::warn("replay: a frame could not be made again: %s", e.what());
      return;
    }
    if (bytes.empty()) return;  // malformed in the file
  }
  m.topic->send([&](std::byte* payload) {
    if (bytes.size() > m.topic->ring().payload_capacity) return kReleasedSlot;
    std::memcpy(payload, bytes.data(), bytes.size());
    return static_cast<std::uint32_t>(bytes.size());
  });
}

}  // namespace horus::detail
