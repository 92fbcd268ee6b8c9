// detail::Replayer: see horus/detail/replayer.hpp and docs/recording.md.
#include "horus/detail/replayer.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <span>
#include <string_view>

#include "horus/detail/pool_frames.hpp"
#include "horus/detail/ring.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/detail/topic_endpoint.hpp"
#include "horus/error.hpp"
#include "horus/log.hpp"
#include "horus/recording.hpp"
#include "horus/topic_registry.hpp"

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

std::uint64_t parse_fingerprint(const RecordedChannel& channel, const std::string& where) {
  const auto found = channel.metadata.find("horus.fingerprint");
  if (found == channel.metadata.end() || found->second.size() != 16) {
    throw Error(where + ": topic '" + channel.topic + "' has no horus.fingerprint");
  }
  return std::strtoull(found->second.c_str(), nullptr, 16);
}

}  // namespace

Replayer::Replayer(const std::filesystem::path& path, const std::string& namespace_name,
                   const std::set<std::string>& skip) {
  const RecordingReader recording(path);
  const std::string where = "replay of " + path.string();
  const std::vector<TopicInfo> now = list_topics(namespace_name);
  std::map<std::uint16_t, std::pair<TopicEndpoint*, PoolFrames*>> endpoints;
  for (const auto& entry : recording.channels()) {
    const std::uint16_t id = entry.first;
    const RecordedChannel& channel = entry.second;
    if (channel.topic == kTicksTopic || skip.count(channel.topic) != 0) continue;
    const auto schema = recording.schemas().find(channel.schema_id);
    if (schema == recording.schemas().end()) {
      throw Error(where + ": topic '" + channel.topic + "' refers to a missing schema");
    }
    const std::uint64_t fingerprint = parse_fingerprint(channel, where);
    const RecordedSchema& type = schema->second;
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
    const TypeDescriptor descriptor{type.name, fingerprint, type.data, pod, size, 1};
    SegmentOptions options{live != now.end() ? live->capacity : 64,
                           std::max<std::size_t>(largest, std::size_t{16} * 1024), 0600,
                           namespace_name, false};
    topics_.push_back(std::make_unique<TopicEndpoint>(
        ShmSegment::open_topic(channel.topic, descriptor, options)));
    PoolFrames* frames = nullptr;
    if (pool) {
      // Each frame is made again in this namespace's pool; the ring's capacity of them stay alive.
      frames_.push_back(make_pool_frames(type.name, fingerprint, namespace_name,
                                         topics_.back()->ring().mask + 1));
      if (!frames_.back()) {
        throw Error(where + ": topic '" + channel.topic + "' holds " + type.name +
                    " frames with their data, which only a program linking horus::pool replays");
      }
      frames = frames_.back().get();
    }
    endpoints[id] = {topics_.back().get(), frames};
  }
  const RecordedChannel* ticks = recording.channel(kTicksTopic);
  for (const RecordedMessage& m : recording.messages()) {
    if (ticks != nullptr && m.channel_id == ticks->id) {
      const std::string_view text(reinterpret_cast<const char*>(m.data.data()), m.data.size());
      std::uint64_t cycle = 0;
      std::uint64_t start = 0;
      if (json_number(text, "tick", cycle) && json_number(text, "start_ns", start)) {
        auto [entry, fresh] = cycle_starts_.emplace(cycle, start);
        if (!fresh) entry->second = std::min(entry->second, start);
      }
      continue;
    }
    const auto endpoint = endpoints.find(m.channel_id);
    if (endpoint != endpoints.end())
      messages_.push_back(
          Message{m.log_time, endpoint->second.first, endpoint->second.second, m.data});
  }
  std::stable_sort(messages_.begin(), messages_.end(),
                   [](const Message& a, const Message& b) { return a.log_time < b.log_time; });
}

Replayer::~Replayer() = default;

void Replayer::deliver_before_cycle(std::uint64_t cycle) {
  const auto start = cycle_starts_.lower_bound(cycle);
  const std::uint64_t before = start == cycle_starts_.end() ? UINT64_MAX : start->second;
  for (; next_ < messages_.size() && messages_[next_].log_time < before; ++next_) {
    Message& m = messages_[next_];
    std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(m.data.data()),
                                     m.data.size());
    if (m.frames != nullptr) {
      try {
        bytes = m.frames->replay(m.data);
      } catch (const Error& e) {
        log::warn("replay: a frame could not be made again: %s", e.what());
        continue;
      }
      if (bytes.empty()) continue;  // malformed in the file
    }
    m.topic->send([&](std::byte* payload) {
      if (bytes.size() > m.topic->ring().payload_capacity) return kReleasedSlot;
      std::memcpy(payload, bytes.data(), bytes.size());
      return static_cast<std::uint32_t>(bytes.size());
    });
  }
}

}  // namespace horus::detail
