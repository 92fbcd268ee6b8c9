// The frame channels of a recording: written by a recorder following the namespace's tree, and
// read back for a replay (docs/recording.md).
#include "frame_changes.hpp"

#include <optional>
#include <string_view>
#include <utility>

#include "horus/error.hpp"
#include "horus/recording.hpp"

namespace horus::detail {

FrameRecording::FrameRecording(McapWriter& writer, std::string namespace_name)
    : writer_(&writer), namespace_(std::move(namespace_name)) {}

void FrameRecording::discover() {
  if (!feed_ && frame_tree_exists(namespace_)) {
    FrameTreeOptions options;
    options.namespace_name = namespace_;
    tree_ = std::make_unique<FrameTree>(std::move(options));
    feed_ = std::make_unique<TransformFeed>(*tree_);
  }
  note_authorities();
}

void FrameRecording::note_authorities() {
  if (!tree_) return;
  for (const FrameInfo& info : tree_->frames(false)) {
    if (info.authority_pid != 0) authorities_[info.name] = info.authority_pid;
  }
}

McapMap FrameRecording::authorities() const {
  McapMap entries;
  for (const auto& [child, pid] : authorities_)
    entries.emplace_back("authority." + child, std::to_string(pid));
  return entries;
}

std::size_t FrameRecording::take(std::uint64_t now_ns) {
  if (!feed_) return 0;
  const TransformBatch batch = feed_->poll();
  std::size_t written = 0;
  if (batch.statics) {
    for (const StampedTransform& transform : *batch.statics) {
      write(static_channel_, static_sequence_, kStaticFramesChannel, transform, now_ns);
      ++written;
    }
  }
  for (const StampedTransform& transform : batch.dynamic) {
    write(dynamic_channel_, dynamic_sequence_, kFramesChannel, transform, now_ns);
    ++written;
  }
  return written;
}

void FrameRecording::write(std::uint16_t& channel, std::uint32_t& sequence, std::string_view topic,
                           const StampedTransform& transform, std::uint64_t now_ns) {
  if (channel == 0) {
    if (schema_ == 0) {
      schema_ = writer_->add_schema(kFrameTransformSchemaName, "jsonschema",
                                    frame_transform_json_schema());
    }
    channel = writer_->add_channel(topic, schema_, "json", {});
  }
  const std::string text = frame_transform_json(transform);
  writer_->add_message(channel, sequence++, now_ns, now_ns,
                       {reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
}

}  // namespace horus::detail

namespace horus {

std::vector<RecordedFrameChange> recorded_frame_changes(const RecordingReader& recording) {
  std::vector<RecordedFrameChange> changes;
  const RecordedChannel* dynamic = recording.channel(kFramesChannel);
  const RecordedChannel* statics = recording.channel(kStaticFramesChannel);
  if (dynamic == nullptr && statics == nullptr) return changes;
  for (const RecordedMessage& message : recording.messages()) {
    const RecordedChannel* channel =
        dynamic != nullptr && message.channel_id == dynamic->id   ? dynamic
        : statics != nullptr && message.channel_id == statics->id ? statics
                                                                  : nullptr;
    if (channel == nullptr) continue;
    const std::string_view text(reinterpret_cast<const char*>(message.data.data()),
                                message.data.size());
    std::string why;
    std::optional<StampedTransform> transform = frame_transform_from_json(text, &why);
    if (!transform) {
      throw Error("recording channel " + channel->topic + ": malformed record (sequence " +
                  std::to_string(message.sequence) + "): " + why + ": " +
                  std::string(text.substr(0, 120)));
    }
    changes.push_back(
        RecordedFrameChange{std::move(*transform), channel == statics, message.log_time});
  }
  return changes;
}

}  // namespace horus
