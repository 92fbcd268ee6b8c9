// horus::Recorder: one thread that subscribes to topics, copies each message's bytes straight
// from its slot into the open chunk, and writes the session file (docs/recording.md).
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <vector>

#include "frame_changes.hpp"
#include "horus/detail/ring.hpp"
#include "horus/detail/send_clock.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/detail/topic_endpoint.hpp"
#include "horus/error.hpp"
#include "horus/internal/tick_log.hpp"
#include "horus/json_string.hpp"
#include "horus/log.hpp"
#include "horus/params.hpp"
#include "horus/pool_frames.hpp"
#include "horus/recording.hpp"
#include "horus/topic_registry.hpp"
#include "mcap_writer.hpp"
#include "param_changes.hpp"

namespace horus::detail {
namespace {

/// How long the thread sleeps when a round found nothing: far below the time a 64-slot ring
/// at 1 kHz takes to lap it.
constexpr auto kIdleSleep = std::chrono::microseconds(500);
/// How often topics that do not exist yet (or every topic, for all_topics) are looked for.
constexpr std::int64_t kDiscoverIntervalNs = 200'000'000;
/// A chunk open longer than this is written anyway: a recorder killed with kill -9 loses at
/// most this much of a slow session.
constexpr std::int64_t kChunkMaxAgeNs = 1'000'000'000;
/// How long stop() or drain() keeps taking what the rings still hold.
constexpr std::int64_t kFinalDrainNs = 1'000'000'000;
/// Messages taken from one topic per round before the others get their turn.
constexpr int kRoundLimit = 256;

constexpr std::string_view kTickSchema =
    R"({"title":"horus.recording.Tick","type":"object",)"
    R"("properties":{"node":{"type":"string"},"tick":{"type":"integer"},)"
    R"("start_ns":{"type":"integer"},"duration_ns":{"type":"integer"},)"
    R"("outcome":{"type":"string","enum":["ok","error","deadline_miss"]},)"
    R"("received":{"type":"object","additionalProperties":{"type":"integer"}},)"
    R"("taken":{"type":"object","additionalProperties":{"type":"integer"}}},)"
    R"("required":["node","tick","start_ns","duration_ns","outcome"]})";

std::string hex16(std::uint64_t value) {
  char text[24];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

std::uint64_t realtime_ns() { return static_cast<std::uint64_t>(clock_ns(CLOCK_REALTIME)); }

std::string_view outcome_name(TickOutcome outcome) {
  switch (outcome) {
    case TickOutcome::Ok:
      return "ok";
    case TickOutcome::Error:
      return "error";
    case TickOutcome::DeadlineMiss:
      return "deadline_miss";
  }
  return "ok";
}

}  // namespace

class RecorderImpl {
 public:
  explicit RecorderImpl(RecorderOptions options)
      : options_(std::move(options)),
        namespace_(options_.namespace_name.empty() ? current_namespace() : options_.namespace_name),
        writer_(options_.path.empty() ? new_recording_path() : options_.path),
        clock_offset_ns_(clock_ns(CLOCK_REALTIME) - clock_ns(CLOCK_MONOTONIC)) {
    validate_segment_name("namespace", namespace_);
    for (const std::string& topic : options_.topics) validate_segment_name("topic name", topic);
    if (options_.frames || options_.all_topics) frames_.emplace(writer_, namespace_);
    summary_.path = writer_.path();
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    writer_.add_metadata("horus.session", {{"session", writer_.path().stem().string()},
                                           {"namespace", namespace_},
                                           {"hostname", host},
                                           {"pid", std::to_string(::getpid())},
                                           {"start_ns", std::to_string(realtime_ns())}});
    {
      std::lock_guard lock(mutex_);
      for (const std::string& topic : options_.topics) pending_.push_back(topic);
      open_pending();
      if (frames_) discover_frames();
    }
    thread_ = std::thread([this] { run(); });
  }

  ~RecorderImpl() { stop(); }
  RecorderImpl(const RecorderImpl&) = delete;
  RecorderImpl& operator=(const RecorderImpl&) = delete;

  void add_topic(const std::string& topic) {
    validate_segment_name("topic name", topic);
    std::lock_guard lock(mutex_);
    if (known(topic)) return;
    pending_.push_back(topic);
    open_pending();
  }

  void add_tick_log(std::string node, std::shared_ptr<TickLog> log,
                    std::vector<std::string> subscribed) {
    std::lock_guard lock(mutex_);
    NodeTicks& ticks = tick_logs_.emplace_back(
        NodeTicks{std::move(node), std::move(log), std::move(subscribed), {}});
    for (const Recorded& topic : topics_) watch(ticks, topic);
  }

  void add_param_change(const RecordedParamChange& change) {
    std::lock_guard lock(mutex_);
    if (stopped_.load(std::memory_order_acquire) || !error_.empty()) return;
    try {
      write_param_change(change);
    } catch (const std::exception& e) {
      error_ = e.what();
      log::error("recorder: recording %s stopped: %s", summary_.path.c_str(), e.what());
    }
  }

  void drain() {
    std::lock_guard lock(mutex_);
    if (stopped_.load(std::memory_order_acquire) || !error_.empty()) return;
    try {
      // A simulation runs ahead of the thread's looks (five a second): a tree made in a pass is
      // followed from that pass on, so that two runs record the same transforms.
      if (frames_ && !frames_->following()) discover_frames();
      take_all();
    } catch (const std::exception& e) {
      error_ = e.what();
      log::error("recorder: recording %s stopped: %s", summary_.path.c_str(), e.what());
    }
  }

  const std::filesystem::path& path() const noexcept { return summary_.path; }
  bool recording() const noexcept { return !stopped_.load(std::memory_order_acquire); }

  RecordingSummary summary() const {
    std::lock_guard lock(mutex_);
    return final_summary_ ? *final_summary_ : current_summary();
  }

  RecordingSummary stop() {
    std::lock_guard stopping(stop_mutex_);
    if (!stopped_.exchange(true)) {
      if (thread_.joinable()) thread_.join();
      finish_file();
    }
    std::lock_guard lock(mutex_);
    return final_summary_ ? *final_summary_ : current_summary();
  }

 private:
  struct Recorded {
    std::string name;
    /// Shared with the tick logs of the nodes that subscribe to it (TickLog::watch).
    std::shared_ptr<TopicEndpoint> endpoint;
    std::uint16_t channel;
    /// Set for a pool-backed type: its frames are recorded with their data.
    std::unique_ptr<PoolFrames> frames;
    std::vector<std::byte> descriptor;  // the frame's descriptor, taken from its slot
    std::uint64_t refused = 0;          // descriptors whose block was gone: counted as lost
  };
  struct NodeTicks {
    std::string node;
    std::shared_ptr<TickLog> log;
    std::vector<std::string> subscribed;  // the node's subscribers()
    std::vector<std::string> watched;     // those its entries carry, in TickLog::watch order
  };

  /// Lets `ticks` carry `topic`'s ring position if the node subscribes to it (mutex_ held).
  static void watch(NodeTicks& ticks, const Recorded& topic) {
    if (std::find(ticks.subscribed.begin(), ticks.subscribed.end(), topic.name) ==
            ticks.subscribed.end() ||
        std::find(ticks.watched.begin(), ticks.watched.end(), topic.name) != ticks.watched.end()) {
      return;
    }
    if (ticks.log->watch(topic.name, topic.endpoint->ring(), topic.endpoint))
      ticks.watched.push_back(topic.name);
  }

  bool known(const std::string& topic) const {
    return std::find(pending_.begin(), pending_.end(), topic) != pending_.end() ||
           std::any_of(topics_.begin(), topics_.end(),
                       [&](const Recorded& r) { return r.name == topic; });
  }

  /// Opens the pending topics that exist with a type by now (mutex_ held).
  void open_pending() {
    if (pending_.empty()) return;
    const std::vector<TopicInfo> infos = list_topics(namespace_);
    for (auto it = pending_.begin(); it != pending_.end();) {
      const auto info = std::find_if(infos.begin(), infos.end(),
                                     [&](const TopicInfo& t) { return t.name == *it; });
      if (info == infos.end() || info->type_name.empty() || !info->error.empty()) {
        ++it;
        continue;
      }
      try {
        open(*info);
      } catch (const Error& e) {
        // Re-typed under us or removed meanwhile: the next look tries again (said once).
        if (unopenable_.insert(*it).second) {
          log::warn("recorder: cannot record topic '%s' yet: %s", it->c_str(), e.what());
        }
        ++it;
        continue;
      }
      it = pending_.erase(it);
    }
  }

  void open(const TopicInfo& info) {
    const TypeDescriptor type{info.type_name,
                              info.fingerprint,
                              info.schema,
                              info.is_pod,
                              info.is_pod ? info.max_message_size : 0,
                              1,
                              info.description};
    ShmSegment segment = ShmSegment::open_topic(
        info.name, type,
        SegmentOptions{info.capacity, info.max_message_size, 0600, namespace_, false});
    std::uint16_t& schema = schema_ids_[info.type_name + "#" + hex16(info.fingerprint)];
    if (schema == 0) schema = writer_.add_schema(info.type_name, "horus.hmsg", info.schema);
    std::unique_ptr<PoolFrames> frames =
        info.is_pod ? make_pool_frames(info.type_name, info.fingerprint, namespace_, 1) : nullptr;
    McapMap metadata{{"horus.fingerprint", hex16(info.fingerprint)},
                     {"horus.type", info.type_name}};
    if (info.is_pod)
      metadata.emplace_back("horus.payload_size", std::to_string(info.max_message_size));
    // The description the segment carries: readers decode the recording from it rather than
    // compile the schema text (docs/recording.md).
    if (!info.description.empty())
      metadata.emplace_back(mcap::kDescriptionKey, mcap::base64_encode(info.description));
    const std::string_view encoding = frames        ? kPoolEncoding
                                      : info.is_pod ? "horus.pod"
                                                    : "horus.msgpack";
    const std::uint16_t channel = writer_.add_channel(info.name, schema, encoding, metadata);
    std::vector<std::byte> descriptor(frames ? info.max_message_size : 0);
    topics_.push_back(Recorded{info.name, std::make_shared<TopicEndpoint>(std::move(segment)),
                               channel, std::move(frames), std::move(descriptor)});
    for (NodeTicks& ticks : tick_logs_) watch(ticks, topics_.back());
  }

  /// Looks for the topics to record that appeared since the last look (mutex_ held).
  void discover() {
    if (options_.all_topics) {
      for (const TopicInfo& info : list_topics(namespace_)) {
        if (!info.type_name.empty() && info.error.empty() && !known(info.name)) {
          pending_.push_back(info.name);
        }
      }
      discover_param_stores();
    }
    if (frames_) discover_frames();
    open_pending();
  }

  /// Starts following the namespace's frame tree once it exists (mutex_ held).
  void discover_frames() {
    try {
      frames_->discover();
    } catch (const Error& e) {
      // Being created right now: the next look tries again (said once).
      if (unopenable_.insert(std::string(kFramesChannel)).second) {
        log::warn("recorder: cannot record the frame tree yet: %s", e.what());
      }
    }
  }

  /// Watches the parameter stores of the namespace that appeared since the last look, each
  /// with its values as first seen (mutex_ held).
  void discover_param_stores() {
    for (const std::string& node : param_nodes(namespace_)) {
      const auto watched = param_stores_.find(node);
      if (watched != param_stores_.end() && watched->second.reader.owner_alive()) continue;
      try {
        WatchedStore store{ParamStoreReader(node, namespace_), 0, 0, {}};
        if (watched != param_stores_.end()) {
          // Its owner ended: a node started again with other declarations has a new store file
          // (the old one, still mapped here, never changes again), watched from its start.
          if (!store.reader.owner_alive()) continue;
          param_stores_.erase(watched);
        }
        store.seen = store.reader.change_count();
        store.owner = store.reader.owner_pid();
        for (const ParamInfo& info : store.reader.list()) {
          store.versions[info.declaration.name] = info.version;
          write_param_change(RecordedParamChange{
              node, info.declaration.name, info.value, info.version, {}, true, std::nullopt});
        }
        param_stores_.emplace(node, std::move(store));
      } catch (const Error& e) {
        // Being created or replaced right now: the next look tries again (said once).
        if (unopenable_.insert("@params/" + node).second) {
          log::warn("recorder: cannot record the parameters of node '%s' yet: %s", node.c_str(),
                    e.what());
        }
      }
    }
  }

  /// Records what changed in the watched stores since the last look, by their change counters
  /// (mutex_ held): each parameter whose version moved, with its value now (several writes
  /// between two looks show as the last of them). A node started again in the same store
  /// (another owner, or versions back at 1) gives its values as starting values.
  std::size_t take_param_changes() {
    std::size_t taken = 0;
    for (auto& [node, store] : param_stores_) {
      const std::uint64_t count = store.reader.change_count();
      if (count == store.seen) continue;
      store.seen = count;
      const std::uint32_t owner = store.reader.owner_pid();
      const bool new_owner = owner != 0 && owner != store.owner;
      if (new_owner) store.owner = owner;
      for (const ParamInfo& info : store.reader.list()) {
        std::uint64_t& version = store.versions[info.declaration.name];
        if (info.version == version && !new_owner) continue;
        const bool start = new_owner || info.version < version;
        version = info.version;
        write_param_change(RecordedParamChange{
            node, info.declaration.name, info.value, info.version, {}, start, std::nullopt});
        ++taken;
      }
    }
    return taken;
  }

  void write_param_change(const RecordedParamChange& change) {
    if (params_channel_ == 0) {
      const std::uint16_t schema =
          writer_.add_schema(kParamChangeSchemaName, "jsonschema", kParamChangeSchema);
      params_channel_ = writer_.add_channel(kParamsChannel, schema, "json", {});
    }
    const std::string text = param_change_json(change);
    const std::uint64_t now = realtime_ns();
    writer_.add_message(params_channel_, params_sequence_++, now, now,
                        {reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
  }

  void run() noexcept {
    std::int64_t last_discovery = clock_ns(CLOCK_MONOTONIC);
    std::int64_t chunk_opened = 0;
    try {
      while (!stopped_.load(std::memory_order_acquire)) {
        std::size_t taken = 0;
        {
          std::lock_guard lock(mutex_);
          if (!error_.empty()) return;
          const std::int64_t now = clock_ns(CLOCK_MONOTONIC);
          if (now - last_discovery >= kDiscoverIntervalNs) {
            discover();
            last_discovery = now;
          }
          taken = take_round(kRoundLimit);
          if (taken > 0 && chunk_opened == 0) chunk_opened = now;
          if (chunk_opened != 0 && now - chunk_opened >= kChunkMaxAgeNs) {
            writer_.flush();
            chunk_opened = 0;
          }
        }
        if (taken == 0) std::this_thread::sleep_for(kIdleSleep);
      }
      std::lock_guard lock(mutex_);
      take_all();
    } catch (const std::exception& e) {
      std::lock_guard lock(mutex_);
      error_ = e.what();
      log::error("recorder: recording %s stopped: %s", summary_.path.c_str(), e.what());
    }
  }

  /// Takes rounds until one finds nothing (mutex_ held); bounded, as a publisher may never pause.
  void take_all() {
    const std::int64_t give_up = clock_ns(CLOCK_MONOTONIC) + kFinalDrainNs;
    while (take_round(kRoundLimit) > 0 && clock_ns(CLOCK_MONOTONIC) < give_up) {
    }
  }

  /// Takes up to `limit` messages from each topic and every waiting tick (mutex_ held).
  std::size_t take_round(int limit) {
    std::size_t taken = 0;
    for (Recorded& topic : topics_) {
      for (int i = 0; i < limit && take_one(topic); ++i) ++taken;
    }
    for (NodeTicks& ticks : tick_logs_) {
      taken += ticks.log->drain([&](const TickEntry& entry) { write_tick(ticks, entry); });
    }
    taken += take_param_changes();
    if (frames_) taken += frames_->take(realtime_ns());
    return taken;
  }

  bool take_one(Recorded& topic) {
    if (topic.frames) return take_frame(topic);
    const RingView& ring = topic.endpoint->ring();
    std::uint32_t size = 0;
    std::uint32_t sent_s = 0;
    const bool got =
        receive_stamped(topic, sent_s, [&](const std::byte* payload, std::uint32_t bytes) {
          if (bytes > ring.payload_capacity) return false;
          std::memcpy(writer_.reserve_message(bytes), payload, bytes);
          size = bytes;
          return true;
        });
    if (!got) return false;
    writer_.commit_message(topic.channel,
                           static_cast<std::uint32_t>(topic.endpoint->next_ticket() - 1),
                           realtime_ns(), std::uint64_t{sent_s} * 1'000'000'000U, size);
    return true;
  }

  /// Takes the topic's next message through `copy(payload, bytes)` (false: not taken), and the
  /// send stamp of the slot it came from into `sent_s`.
  template <class Copy>
  static bool receive_stamped(Recorded& topic, std::uint32_t& sent_s, Copy&& copy) {
    const RingView& ring = topic.endpoint->ring();
    return topic.endpoint->receive(
        false,
        [&](const std::byte* payload, std::uint32_t bytes) {
          if (!copy(payload, bytes)) return false;
          const auto* slot = reinterpret_cast<const SlotHeader*>(payload - ring.payload_offset);
          sent_s = slot->send_time_s.load(std::memory_order_relaxed);
          return true;
        },
        [] { return true; });
  }

  /// A frame of a pool-backed topic: its descriptor from the slot, then (PoolFrames::record)
  /// the data from its block, held only for that copy.
  bool take_frame(Recorded& topic) {
    std::uint32_t size = 0;
    std::uint32_t sent_s = 0;
    const bool got =
        receive_stamped(topic, sent_s, [&](const std::byte* payload, std::uint32_t bytes) {
          if (bytes != topic.descriptor.size()) return false;
          std::memcpy(topic.descriptor.data(), payload, bytes);
          size = bytes;
          return true;
        });
    if (!got) return false;
    const std::size_t written =
        topic.frames->record(topic.descriptor.data(), size,
                             [&](std::size_t bytes) { return writer_.reserve_message(bytes); });
    if (written == 0) {
      ++topic.refused;
      return true;
    }
    writer_.commit_message(topic.channel,
                           static_cast<std::uint32_t>(topic.endpoint->next_ticket() - 1),
                           realtime_ns(), std::uint64_t{sent_s} * 1'000'000'000U, written);
    return true;
  }

  void write_tick(const NodeTicks& ticks, const TickEntry& entry) {
    if (ticks_channel_ == 0) {
      const std::uint16_t schema =
          writer_.add_schema("horus.recording.Tick", "jsonschema", kTickSchema);
      ticks_channel_ = writer_.add_channel("/horus/ticks", schema, "json", {});
    }
    const auto start = static_cast<std::uint64_t>(entry.start_ns + clock_offset_ns_);
    tick_text_.clear();
    tick_text_ += "{\"node\":";
    tick_text_ += json_string(ticks.node);
    tick_text_ += ",\"tick\":" + std::to_string(entry.tick) +
                  ",\"start_ns\":" + std::to_string(start) +
                  ",\"duration_ns\":" + std::to_string(entry.duration_ns) + ",\"outcome\":\"";
    tick_text_ += outcome_name(entry.outcome);
    tick_text_ += '"';
    if (entry.watched > 0) {
      tick_text_ += ",\"received\":{";
      for (std::size_t i = 0; i < entry.watched; ++i) {
        if (i > 0) tick_text_ += ',';
        tick_text_ += json_string(ticks.watched[i]) + ":" + std::to_string(entry.received[i]);
      }
      tick_text_ += '}';
      bool first = true;
      for (std::size_t i = 0; i < entry.watched; ++i) {
        if (entry.taken[i] == 0) continue;
        tick_text_ += first ? ",\"taken\":{" : ",";
        first = false;
        tick_text_ += json_string(ticks.watched[i]) + ":" + std::to_string(entry.taken[i]);
      }
      if (!first) tick_text_ += '}';
    }
    tick_text_ += '}';
    writer_.add_message(
        ticks_channel_, tick_sequence_++, start, start,
        {reinterpret_cast<const std::uint8_t*>(tick_text_.data()), tick_text_.size()});
  }

  /// Counts as they stand (mutex_ held).
  RecordingSummary current_summary() const {
    RecordingSummary summary = summary_;
    summary.messages = writer_.message_count();
    summary.bytes = writer_.file_size();
    for (const Recorded& topic : topics_) {
      const TopicStats stats = topic.endpoint->stats();
      const std::uint64_t lost = stats.lost + stats.invalid + topic.refused;
      if (lost > 0) summary.lost[topic.name] = lost;
      summary.lost_total += lost;
    }
    std::uint64_t dropped = 0;
    for (const NodeTicks& ticks : tick_logs_) dropped += ticks.log->dropped();
    if (dropped > 0) summary.lost["/horus/ticks"] = dropped;
    summary.lost_total += dropped;
    if (const std::uint64_t lapped = frames_ ? frames_->lost() : 0; lapped > 0) {
      summary.lost[std::string(kFramesChannel)] = lapped;
      summary.lost_total += lapped;
    }
    return summary;
  }

  void finish_file() {
    std::lock_guard lock(mutex_);
    for (NodeTicks& ticks : tick_logs_) ticks.log->close();
    RecordingSummary& summary = final_summary_.emplace(current_summary());
    McapMap entries{{"lost_total", std::to_string(summary.lost_total)}};
    for (const auto& [topic, lost] : summary.lost)
      entries.emplace_back("lost." + topic, std::to_string(lost));
    entries.emplace_back("end_ns", std::to_string(realtime_ns()));
    if (!error_.empty()) entries.emplace_back("error", error_);
    try {
      if (frames_) {
        frames_->note_authorities();
        if (McapMap authorities = frames_->authorities(); !authorities.empty())
          writer_.add_metadata(kFramesMetadata, authorities);
      }
      writer_.add_metadata("horus.recorder", entries);
      writer_.finish();
      summary.bytes = writer_.file_size();
    } catch (const std::exception& e) {
      log::error("recorder: cannot finish recording %s: %s", summary_.path.c_str(), e.what());
      return;
    }
    if (summary.lost_total > 0) {
      std::string topics;
      for (const auto& [topic, lost] : summary.lost) {
        topics += (topics.empty() ? "" : ", ") + topic + ": " + std::to_string(lost);
      }
      log::warn("recorder: %s lost %llu messages it could not keep up with (%s)",
                summary_.path.c_str(), static_cast<unsigned long long>(summary.lost_total),
                topics.c_str());
    } else {
      log::info("recorder: %s: %llu messages, nothing lost", summary_.path.c_str(),
                static_cast<unsigned long long>(summary.messages));
    }
    topics_.clear();  // the subscriptions end with the recording
    param_stores_.clear();
    frames_.reset();
  }

  RecorderOptions options_;
  std::string namespace_;
  McapWriter writer_;
  std::int64_t clock_offset_ns_;  // CLOCK_REALTIME - CLOCK_MONOTONIC when recording started

  mutable std::mutex mutex_;  // everything below, and the writer
  std::vector<std::string> pending_;
  std::set<std::string> unopenable_;  // warned about once
  std::vector<Recorded> topics_;
  std::vector<NodeTicks> tick_logs_;
  std::map<std::string, std::uint16_t> schema_ids_;
  std::uint16_t ticks_channel_ = 0;
  std::uint32_t tick_sequence_ = 0;
  /// A parameter store a standalone recorder watches (all_topics): the change count and the
  /// versions it recorded last.
  struct WatchedStore {
    ParamStoreReader reader;
    std::uint64_t seen;
    std::uint32_t owner;  // its owner's pid when last looked at (0: none ran)
    std::map<std::string, std::uint64_t> versions;
  };
  std::map<std::string, WatchedStore> param_stores_;
  std::uint16_t params_channel_ = 0;
  std::uint32_t params_sequence_ = 0;
  /// Set when the recording follows the namespace's frame tree.
  std::optional<FrameRecording> frames_;
  std::string tick_text_;
  std::string error_;
  RecordingSummary summary_;
  std::optional<RecordingSummary> final_summary_;  // once stopped

  std::mutex stop_mutex_;
  std::atomic<bool> stopped_{false};
  std::thread thread_;
};

}  // namespace horus::detail

namespace horus {

Recorder::Recorder(RecorderOptions options)
    : impl_(std::make_unique<detail::RecorderImpl>(std::move(options))) {}
Recorder::~Recorder() = default;
void Recorder::add_topic(const std::string& topic) { impl_->add_topic(topic); }
void Recorder::add_tick_log(std::string node, std::shared_ptr<detail::TickLog> log,
                            std::vector<std::string> subscribed) {
  impl_->add_tick_log(std::move(node), std::move(log), std::move(subscribed));
}
const std::filesystem::path& Recorder::path() const noexcept { return impl_->path(); }
bool Recorder::recording() const noexcept { return impl_->recording(); }
RecordingSummary Recorder::summary() const { return impl_->summary(); }
void Recorder::drain() { impl_->drain(); }
void Recorder::add_param_change(const RecordedParamChange& change) {
  impl_->add_param_change(change);
}
RecordingSummary Recorder::stop() { return impl_->stop(); }

}  // namespace horus
