// detail::Replayer: see horus/detail/replayer.hpp and docs/recording.md.
#include "horus/detail/replayer.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <span>
#include <string_view>
#include <tuple>
#include <utility>

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

/// One recorded tick: the node, its cycle and start, and the ring positions of the topics it
/// reads when it started ("received", written by recorder.cpp).
struct RecordedTick {
  std::string node;
  std::uint64_t cycle = 0;
  std::uint64_t start_ns = 0;
  std::vector<std::pair<std::string, std::uint64_t>> received;
};

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
  at = text.find("\"received\":{");
  if (at == std::string_view::npos) return tick;
  at += 12;
  while (at < text.size() && text[at] != '}') {
    if (text[at] == ',') ++at;
    std::optional<std::string> topic = json_literal(text, at);
    if (!topic || at >= text.size() || text[at] != ':') return std::nullopt;
    const std::string digits(text.substr(at + 1, 24));
    char* end = nullptr;
    const std::uint64_t count = std::strtoull(digits.c_str(), &end, 10);
    if (end == digits.c_str()) return std::nullopt;
    at += 1 + static_cast<std::size_t>(end - digits.c_str());
    tick.received.emplace_back(std::move(*topic), count);
  }
  return tick;
}

/// When each message of one topic is due, from the ticks of the nodes that read it: before the
/// first of those ticks that started with the message's ticket handed out (`received` > ticket).
class FirstReceipt {
 public:
  void add(std::uint64_t cycle, std::uint64_t start_ns, std::uint64_t received) {
    ticks_.push_back({cycle, start_ns, received});
  }
  bool empty() const noexcept { return ticks_.empty(); }
  void prepare() {
    std::sort(ticks_.begin(), ticks_.end(), [](const Tick& a, const Tick& b) {
      return std::tie(a.cycle, a.start_ns) < std::tie(b.cycle, b.start_ns);
    });
    // Readers of one topic start ticks in time order, so their positions only grow; the running
    // maximum makes that exact across readers whose ticks interleave.
    for (std::size_t i = 1; i < ticks_.size(); ++i)
      ticks_[i].received = std::max(ticks_[i].received, ticks_[i - 1].received);
    ticket_ = ticks_.front().received;
  }
  /// The tick that first received the message of 32-bit `sequence` (the file's sequence
  /// numbers are tickets mod 2^32, taken in order: unwrapped against the previous one), or null.
  const std::pair<std::uint64_t, std::uint64_t>* receipt(std::uint32_t sequence) {
    ticket_ += static_cast<std::int32_t>(sequence - static_cast<std::uint32_t>(ticket_));
    const auto first =
        std::upper_bound(ticks_.begin(), ticks_.end(), ticket_,
                         [](std::uint64_t t, const Tick& tick) { return t < tick.received; });
    if (first == ticks_.end()) return nullptr;
    found_ = {first->cycle, first->start_ns};
    return &found_;
  }

 private:
  struct Tick {
    std::uint64_t cycle, start_ns, received;
  };
  std::vector<Tick> ticks_;
  std::uint64_t ticket_ = 0;
  std::pair<std::uint64_t, std::uint64_t> found_;
};

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
  // The ticks first: when each cycle began, and where each reading node was on its topics.
  std::map<std::uint64_t, std::uint64_t> cycle_starts;
  std::map<std::uint16_t, FirstReceipt> receipts;
  std::map<std::string, std::uint16_t> channel_ids;
  for (const auto& [id, channel] : recording.channels()) channel_ids.emplace(channel.topic, id);
  for (const RecordedMessage& m : recording.messages()) {
    if (ticks == nullptr || m.channel_id != ticks->id) continue;
    const std::optional<RecordedTick> tick =
        parse_tick(std::string_view(reinterpret_cast<const char*>(m.data.data()), m.data.size()));
    if (!tick) continue;
    auto [first, fresh] = cycle_starts.emplace(tick->cycle, tick->start_ns);
    if (!fresh) first->second = std::min(first->second, tick->start_ns);
    tick_starts_[{tick->cycle, tick->node}] = tick->start_ns;
    last_cycle_ = std::max(last_cycle_, tick->cycle);
    for (const auto& [topic, received] : tick->received) {
      const auto channel = channel_ids.find(topic);
      if (channel != channel_ids.end())
        receipts[channel->second].add(tick->cycle, tick->start_ns, received);
    }
  }
  for (auto& entry : receipts) entry.second.prepare();
  for (const RecordedMessage& m : recording.messages()) {
    const auto endpoint = endpoints.find(m.channel_id);
    if (endpoint == endpoints.end()) continue;
    Due due{UINT64_MAX, 0};
    const auto receipt = receipts.find(m.channel_id);
    const auto* tick = receipt == receipts.end() ? nullptr : receipt->second.receipt(m.sequence);
    if (tick != nullptr) {
      due = Due{tick->first, tick->second};
    } else {
      // No node that names the topic received it: before the first cycle that began after the
      // recorder took it.
      const auto after = std::find_if(cycle_starts.begin(), cycle_starts.end(),
                                      [&](const auto& cycle) { return cycle.second > m.log_time; });
      if (after != cycle_starts.end()) due = Due{after->first, 0};
    }
    messages_.push_back(Message{due, endpoint->second.first, endpoint->second.second, m.data});
  }
  std::stable_sort(messages_.begin(), messages_.end(),
                   [](const Message& a, const Message& b) { return a.due < b.due; });
}

Replayer::~Replayer() = default;

void Replayer::deliver_before_cycle(std::uint64_t cycle) {
  const bool past_the_recorded_cycles = tick_starts_.empty() || cycle > last_cycle_;
  deliver_until(past_the_recorded_cycles ? Due{UINT64_MAX, UINT64_MAX} : Due{cycle, 0});
}

void Replayer::deliver_before_tick(std::uint64_t cycle, const std::string& node) {
  const auto tick = tick_starts_.find({cycle, node});
  if (tick != tick_starts_.end()) deliver_until(Due{cycle, tick->second});
}

void Replayer::deliver_until(Due due) {
  for (; next_ < messages_.size() && messages_[next_].due <= due; ++next_) {
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
