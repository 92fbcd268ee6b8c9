// A local topic's frames as every bridge takes them out of this machine (the DDS export pump, the
// remote link's forwarder, a live view): each message in order with its sequence on the topic and
// the count of messages this reader lost before it. A message of a pool-backed type (Image,
// DepthImage, PointCloud, Tensor) is only a descriptor naming a block of a shared-memory pool, so
// its frame is recorded as horus::PoolFrames writes it (the descriptor, then the data of its
// block, copied as it is read); a descriptor whose block was freed or reused before it was read
// is skipped and counted as lost, as a local subscriber would refuse it.
// Pool frames are recorded with horus::pool's PoolFrames, which the program registers before it
// makes a FrameSource (horus::enable_pool_frames(), as every bridge does first): without it no
// type is known to be pool-backed, and a descriptor would pass as its bare bytes.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "horus/pool_frames.hpp"
#include "horus/raw_topic.hpp"

namespace horus::bridge {

/// One frame of a topic, as a FrameSource gives it.
struct Frame {
  /// The message's ticket on the topic: consecutive frames differ by one plus `lost`.
  std::uint64_t sequence = 0;
  /// Messages left out since the previous frame the source gave: overwritten in the ring before
  /// its reader got to them, or skipped because their pool block was freed or reused.
  std::uint64_t lost = 0;
  /// The message's bytes, or a pool type's recorded frame; valid until the source's next call.
  std::span<const std::byte> bytes;
};

class FrameSource {
 public:
  using Frame = bridge::Frame;

  /// Reads `topic` from where its handle stands. `namespace_name` (empty: the current one): the
  /// namespace whose pool a pool type's descriptors name.
  FrameSource(std::unique_ptr<RawTopic> topic, const std::string& namespace_name);
  FrameSource(const FrameSource&) = delete;
  FrameSource& operator=(const FrameSource&) = delete;
  ~FrameSource();

  /// The next frame, waiting up to `wait` asleep on the topic; nothing when none came in time.
  /// Allocates only to grow the buffer of pool frames to a larger frame than any before (which
  /// may throw std::bad_alloc).
  std::optional<Frame> next(std::chrono::milliseconds wait);
  /// The next frame if one is there; never waits (a woken event loop calls it until nothing).
  std::optional<Frame> try_next();
  /// The newest message the topic holds, for a late joiner of a latched topic, when this reader
  /// stands past it (took it, or it was sent before the reader opened); nothing while a message
  /// is waiting, which next() gives to everyone alike, so no joiner gets a message twice. It moves
  /// no read position and counts nothing lost; its sequence is the ticket just before this
  /// reader's position.
  std::optional<Frame> latest();

  RawTopic& topic() noexcept { return *topic_; }
  const RawTopic& topic() const noexcept { return *topic_; }
  bool pool_backed() const noexcept { return frames_ != nullptr; }
  /// Every message lost so far (the sum of the frames' `lost`, and those of a frame not given
  /// yet): counted as they are met, so a caller that counts drops as they happen reads it after
  /// each call, whether or not the call gave a frame.
  std::uint64_t lost() const noexcept { return ring_lost_ + stale_; }
  /// Of lost(), the frames skipped because their pool block was freed or reused.
  std::uint64_t stale() const noexcept { return stale_; }

 private:
  /// The frame of the message of `size` bytes the topic just received, or nothing when it is a
  /// stale pool frame (counted).
  std::optional<Frame> frame_of(std::ptrdiff_t size, std::uint64_t sequence);
  /// Records the pool frame `descriptor` names into recorded_; its size, or 0 when refused.
  std::size_t record(std::span<const std::byte> descriptor);

  std::unique_ptr<RawTopic> topic_;
  /// Set for a pool-backed type.
  std::unique_ptr<PoolFrames> frames_;
  /// A pool type's recorded frame: grown to the largest frame, then reused.
  std::vector<std::byte> recorded_;
  /// The topic's count of overwritten messages, and the stale frames, as counted so far.
  std::uint64_t ring_lost_ = 0;
  std::uint64_t stale_ = 0;
  /// lost() when the last frame was given.
  std::uint64_t lost_given_ = 0;
};

}  // namespace horus::bridge
