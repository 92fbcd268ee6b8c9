// The "/horus/frames" and "/horus/frames_static" channels of a recording (docs/recording.md):
// a namespace's frame tree followed through horus::TransformFeed, one Foxglove FrameTransform
// record a transform.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "horus/frames.hpp"
#include "horus/transform_feed.hpp"
#include "mcap_writer.hpp"

namespace horus::detail {

class FrameRecording {
 public:
  FrameRecording(McapWriter& writer, std::string namespace_name);

  /// Opens the namespace's tree once it exists: opening creates a missing tree, and a tree's
  /// creator fixes its history duration, which is not a recorder's to choose.
  void discover();
  bool following() const noexcept { return feed_ != nullptr; }
  /// Writes each dynamic entry set since the last call on "/horus/frames", and the static set,
  /// when it changed, on "/horus/frames_static"; the number of records written.
  std::size_t take(std::uint64_t now_ns);
  /// Entries a writer lapped in its history before the recorder took them.
  std::uint64_t lost() const noexcept { return feed_ ? feed_->lost() : 0; }
  /// Notes the authority of each frame (on each discovery, and as the recording ends): a
  /// deterministic replay leaves the frames the recording process set itself to its nodes.
  void note_authorities();
  /// The "horus.frames" metadata: "authority.<child>" = the pid that set it (none: no tree).
  McapMap authorities() const;

 private:
  void write(std::uint16_t& channel, std::uint32_t& sequence, std::string_view topic,
             const StampedTransform& transform, std::uint64_t now_ns);

  McapWriter* writer_;
  std::string namespace_;
  std::unique_ptr<FrameTree> tree_;
  std::unique_ptr<TransformFeed> feed_;
  std::map<std::string, std::uint32_t> authorities_;
  std::uint16_t schema_ = 0;
  std::uint16_t dynamic_channel_ = 0;
  std::uint16_t static_channel_ = 0;
  std::uint32_t dynamic_sequence_ = 0;
  std::uint32_t static_sequence_ = 0;
};

}  // namespace horus::detail
