#include "horus/bridge/frame_source.hpp"

#include <utility>

namespace horus::bridge {

FrameSource::FrameSource(std::unique_ptr<RawTopic> topic, const std::string& namespace_name)
    : topic_(std::move(topic)),
      // Keeps no made frames: a FrameSource only records.
      frames_(make_pool_frames(topic_->type().name, topic_->type().fingerprint, namespace_name, 1)),
      ring_lost_(topic_->stats().lost),
      lost_given_(ring_lost_) {}

FrameSource::~FrameSource() = default;

std::optional<Frame> FrameSource::next(std::chrono::milliseconds wait) {
  const auto deadline = std::chrono::steady_clock::now() + wait;
  for (;;) {
    const std::ptrdiff_t size = topic_->recv(deadline - std::chrono::steady_clock::now());
    if (size < 0) {
      return std::nullopt;
    }
    if (auto frame = frame_of(size, topic_->received_ticket())) {
      return frame;
    }
  }
}

std::optional<Frame> FrameSource::try_next() {
  for (;;) {
    const std::ptrdiff_t size = topic_->try_recv();
    if (size < 0) {
      return std::nullopt;
    }
    if (auto frame = frame_of(size, topic_->received_ticket())) {
      return frame;
    }
  }
}

std::optional<Frame> FrameSource::latest() {
  const std::ptrdiff_t size = topic_->read_latest();
  // Asked after the read: a message sent since then is waiting too, and may be the one read.
  if (size < 0 || topic_->has_msg()) {
    return std::nullopt;
  }
  const std::span<const std::byte> message = topic_->received(static_cast<std::size_t>(size));
  const std::uint64_t sequence = topic_->received_ticket();
  if (!frames_) {
    return Frame{sequence, 0, message};
  }
  const std::size_t recorded = record(message);
  if (recorded == 0) {  // not lost: this reader will meet it (or met it) in its turn
    return std::nullopt;
  }
  return Frame{sequence, 0, std::span<const std::byte>(recorded_.data(), recorded)};
}

std::optional<Frame> FrameSource::frame_of(std::ptrdiff_t size, std::uint64_t sequence) {
  ring_lost_ = topic_->stats().lost;
  std::span<const std::byte> bytes = topic_->received(static_cast<std::size_t>(size));
  if (frames_) {
    const std::size_t recorded = record(bytes);
    if (recorded == 0) {
      ++stale_;
      return std::nullopt;
    }
    bytes = {recorded_.data(), recorded};
  }
  const std::uint64_t lost = this->lost() - lost_given_;
  lost_given_ = this->lost();
  return Frame{sequence, lost, bytes};
}

std::size_t FrameSource::record(std::span<const std::byte> descriptor) {
  // PoolFrames::record asks for the room of the whole frame: within what recorded_ holds
  // already, resize() keeps its allocation.
  return frames_->record(descriptor.data(), descriptor.size(), [this](std::size_t room) {
    recorded_.resize(room);
    return reinterpret_cast<std::uint8_t*>(recorded_.data());
  });
}

}  // namespace horus::bridge
