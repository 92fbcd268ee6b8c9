// horus::PoolFrames: the frames of a topic of a pool-backed type (Image, DepthImage, PointCloud,
// Tensor) as bytes that stand alone. Such a topic's ring carries only descriptors naming blocks of
// a shared-memory pool; whatever takes frames out of this machine or this run (the recorder, the
// remote link, a bridge) records each descriptor with the data its block holds, and makes a frame
// again from such a record. Used beside horus::RawTopic (raw_topic.hpp).
//
// The runtime only sees this interface: the tensor pool is horus::pool, a library above the
// runtime, which registers the implementation when a program links it (src/pool/pool_frames.cpp).
// Encoding: docs/recording.md, "Pool-backed topics".
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace horus {

/// The message encoding of a recorded pool-backed topic: the descriptor (its block zeroed)
/// followed by the `data_size` bytes it covers.
inline constexpr std::string_view kPoolEncoding = "horus.pool";

class PoolFrames {
 public:
  virtual ~PoolFrames() = default;

  /// Records the frame `descriptor` (`size` bytes, as taken from the ring) names: holds a
  /// reference on its block only while copying the descriptor and the data into the buffer
  /// `reserve(bytes)` returns. The bytes written, or 0 when the descriptor is refused (its block
  /// freed or reused since, another pool, a size that does not fit): nothing is dereferenced then.
  virtual std::size_t record(const std::byte* descriptor, std::size_t size,
                             const std::function<std::uint8_t*(std::size_t)>& reserve) = 0;

  /// Makes a recorded frame again: allocates a block of the namespace's "default" pool, copies
  /// the recorded data into it and returns the descriptor naming it (empty when the recording is
  /// malformed; throws horus::Error when the pool cannot give a block). The block is held until
  /// `keep` more frames were made, as a sending Topic<T> holds the frames its ring can still give.
  virtual std::span<const std::byte> replay(std::span<const std::uint8_t> recorded) = 0;
};

namespace detail {

/// Makes the PoolFrames of a type, or nullptr when `type_name` with `fingerprint` is not a
/// pool-backed type.
using PoolFramesFactory = std::unique_ptr<PoolFrames> (*)(std::string_view type_name,
                                                          std::uint64_t fingerprint,
                                                          const std::string& namespace_name,
                                                          std::size_t keep);

inline std::atomic<PoolFramesFactory>& pool_frames_factory() noexcept {
  static std::atomic<PoolFramesFactory> factory{nullptr};
  return factory;
}

}  // namespace detail

/// The PoolFrames of a type in a namespace (empty: the current one), keeping `keep` replayed
/// frames alive; nullptr when the type is not pool-backed, or horus::pool is not linked (then no
/// value of such a type can exist in this process either).
inline std::unique_ptr<PoolFrames> make_pool_frames(std::string_view type_name,
                                                    std::uint64_t fingerprint,
                                                    const std::string& namespace_name,
                                                    std::size_t keep) {
  const detail::PoolFramesFactory factory =
      detail::pool_frames_factory().load(std::memory_order_acquire);
  return factory != nullptr ? factory(type_name, fingerprint, namespace_name, keep) : nullptr;
}

/// Registers horus::pool's PoolFrames. Linking horus::pool's pool_mapping.cpp does it; a program
/// that takes frames of other processes' topics without using a pool itself (horus-record,
/// horus remote) calls it, as it may hold no reference that pulls that file in.
void enable_pool_frames() noexcept;

}  // namespace horus
