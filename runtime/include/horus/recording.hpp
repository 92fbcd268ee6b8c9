// Recording sessions to MCAP files and reading them back (docs/recording.md).
//
//   horus::Recorder recorder({.topics = {"scan", "cmd_vel"}});   // or .all_topics = true
//   ...                                                          // the robot runs
//   horus::RecordingSummary done = recorder.stop();               // done.path, done.lost_total
//
// A Recorder reads its topics as an ordinary subscriber on a thread of its own: publishers never
// wait for it. What it could not keep up with (a ring that lapped it) is counted per topic, in
// the file ("horus.recorder" metadata), in the summary and in a log line. SchedulerConfig's
// recording(true) runs one for the scheduler's nodes; `horus-record` is the standalone one.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "horus/frames.hpp"

namespace horus {

/// The channel that carries parameter changes in a recording (JSON, docs/recording.md).
inline constexpr std::string_view kParamsChannel = "/horus/params";
/// The channels that carry the namespace's frame tree in a recording, one Foxglove
/// FrameTransform record a message (horus/transform_feed.hpp): each new dynamic entry, and the
/// whole static set each time it changed.
inline constexpr std::string_view kFramesChannel = "/horus/frames";
inline constexpr std::string_view kStaticFramesChannel = "/horus/frames_static";
/// The metadata record, written as a recording ends, naming each recorded frame's authority:
/// "authority.<child>" = its pid (a deterministic replay compares it with "horus.session"'s).
inline constexpr std::string_view kFramesMetadata = "horus.frames";

/// One parameter change as a recording holds it, or a node's starting value.
struct RecordedParamChange {
  std::string node;
  std::string name;
  /// MessagePack VALUE bytes (horus/params.hpp), the form every parameter value crosses in.
  std::string value;
  /// The parameter's version once the change took effect (1: the value the node started with).
  std::uint64_t version = 0;
  /// Who wrote it (ParamChange::source); empty when a recorder only saw the store change.
  std::string source;
  /// A starting value: what the node started with (after its parameter file), or, for a store a
  /// standalone recorder found already there, its value when the recording first saw it.
  bool start = false;
  /// The scheduler's cycle the change took effect before (its node's ticks of that cycle and
  /// later see it); none when recorded from the store alone (`horus-record -a`).
  std::optional<std::uint64_t> cycle;
};

namespace detail {
class RecorderImpl;
class TickLog;
}  // namespace detail

/// $HORUS_RECORDINGS, or ~/.local/share/horus/recordings (created when missing).
std::filesystem::path recordings_directory();
/// A new session file in recordings_directory(): session_YYYY_MM_DD_HHMMSS.mcap (local time),
/// with _2, _3, ... when taken.
std::filesystem::path new_recording_path();
/// The session names (file names without .mcap) in recordings_directory(), sorted.
std::vector<std::string> list_recordings();
/// Removes recordings_directory()/<name>.mcap (`name` may carry the extension); whether it
/// existed. Throws horus::Error for a name that is not a plain file name.
bool delete_recording(std::string_view name);

struct RecorderOptions {
  /// The file to write; empty: new_recording_path(). An existing file is never replaced.
  std::filesystem::path path;
  /// Topics to record; a topic that does not exist yet is recorded from when it appears.
  std::vector<std::string> topics;
  /// Every topic of the namespace, also those that appear later.
  bool all_topics = false;
  /// Empty: HORUS_NAMESPACE, or "default".
  std::string namespace_name;
  /// The namespace's frame tree too (from when it exists), on kFramesChannel and
  /// kStaticFramesChannel; all_topics records it whatever this says.
  bool frames = false;
};

/// What a recording holds (so far, or once stopped).
struct RecordingSummary {
  std::filesystem::path path;
  std::uint64_t messages = 0;
  std::uint64_t bytes = 0;  // written to the file
  /// Messages the recorder missed because a topic's ring lapped it (or, on a pool-backed topic,
  /// whose block was gone by the time it read the descriptor), by topic.
  std::uint64_t lost_total = 0;
  std::map<std::string, std::uint64_t> lost;
};

class Recorder {
 public:
  /// Creates the file and starts the recording thread; throws horus::Error when the file cannot
  /// be created or a topic name is invalid.
  explicit Recorder(RecorderOptions options);
  /// stop().
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  /// Records `topic` too, from now on (from when it appears, if it does not exist yet).
  void add_topic(const std::string& topic);
  /// Records the ticks a node's scheduler logs into `log` on the "/horus/ticks" channel, each
  /// with the positions of the recorded `subscribed` topics when the tick started.
  void add_tick_log(std::string node, std::shared_ptr<detail::TickLog> log,
                    std::vector<std::string> subscribed = {});

  /// Records a parameter change (or a starting value) on the "/horus/params" channel; any
  /// thread. Ignored once the recording stopped.
  void add_param_change(const RecordedParamChange& change);

  /// Takes what the rings hold now, on the calling thread (the recording thread waits
  /// meanwhile). A deterministic scheduler calls it after each pass, so that a simulation that
  /// runs faster than real time loses nothing.
  void drain();

  const std::filesystem::path& path() const noexcept;
  bool recording() const noexcept;
  /// Counts so far.
  RecordingSummary summary() const;
  /// Takes what is still in the rings, writes the "horus.recorder" metadata, the summary and the
  /// footer, and closes the file; reports losses in a log line. Idempotent.
  RecordingSummary stop();

 private:
  std::unique_ptr<detail::RecorderImpl> impl_;
};

/// A schema of a recording: the message type's name, encoding ("horus.hmsg") and text.
struct RecordedSchema {
  std::uint16_t id = 0;
  std::string name;
  std::string encoding;
  std::string data;
};

struct RecordedChannel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;  // "horus.pod", "horus.msgpack" or "json"
  std::map<std::string, std::string> metadata;
  /// The topic's type description (MessagePack, "horus.typedesc"), from the metadata key
  /// `horus.description`; empty when the file has none (written before recordings carried it,
  /// or a type without one).
  std::string description;
};

struct RecordedMessage {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;
  std::uint64_t publish_time = 0;
  std::vector<std::uint8_t> data;
};

struct RecordedMetadata {
  std::string name;
  std::map<std::string, std::string> entries;
};

/// An MCAP file read whole, in file order: schemas, channels, messages and metadata records.
/// A file cut short (a recorder killed with kill -9) reads up to its last complete chunk.
class RecordingReader {
 public:
  /// Throws horus::Error naming the file when it is not MCAP, a CRC does not match, or a
  /// complete record is malformed.
  explicit RecordingReader(const std::filesystem::path& path);

  const std::map<std::uint16_t, RecordedSchema>& schemas() const noexcept { return schemas_; }
  const std::map<std::uint16_t, RecordedChannel>& channels() const noexcept { return channels_; }
  const std::vector<RecordedMessage>& messages() const noexcept { return messages_; }
  const std::vector<RecordedMetadata>& metadata() const noexcept { return metadata_; }
  /// The channel recorded for `topic`, or nullptr.
  const RecordedChannel* channel(std::string_view topic) const;
  /// The messages of the channel of `topic`, in file order (none when it has no channel).
  std::vector<const RecordedMessage*> messages_on(std::string_view topic) const;
  /// Whether the data section ends with its data-end record (its CRC checked): the recorder
  /// finished the file. A file cut by kill -9 has none.
  bool complete() const noexcept { return complete_; }
  /// Chunks read (complete ones only).
  std::size_t chunk_count() const noexcept { return chunks_; }

 private:
  void read_records(const std::uint8_t* data, std::size_t size, bool in_chunk);

  std::filesystem::path path_;
  std::map<std::uint16_t, RecordedSchema> schemas_;
  std::map<std::uint16_t, RecordedChannel> channels_;
  std::vector<RecordedMessage> messages_;
  std::vector<RecordedMetadata> metadata_;
  bool complete_ = false;
  std::size_t chunks_ = 0;
};

/// The parameter changes and starting values a recording holds on "/horus/params", in file
/// order; throws horus::Error naming the file's channel when a record is malformed.
std::vector<RecordedParamChange> recorded_param_changes(const RecordingReader& recording);

/// One transform a recording holds on kFramesChannel or kStaticFramesChannel.
struct RecordedFrameChange {
  /// With the stamp it had in the tree (a static transform's as its tree gave it).
  StampedTransform transform;
  bool is_static = false;
  /// When the recorder took it (CLOCK_REALTIME ns): when a timed replay sets it again.
  std::uint64_t log_time = 0;
};

/// The transforms a recording holds on its two frame channels, in file order; throws
/// horus::Error naming the channel when a record is not a FrameTransform.
std::vector<RecordedFrameChange> recorded_frame_changes(const RecordingReader& recording);

}  // namespace horus
