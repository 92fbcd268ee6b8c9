// What the recorder and the replayers need of a topic of a pool-backed type (Image, DepthImage,
// PointCloud, Tensor): its frames recorded with their data, and made again from a recording.
// The runtime (recorder.cpp, replayer.cpp) only sees this interface: the tensor pool is
// horus::pool, a library above the runtime, which registers the implementation when a program
// links it (pool_frames.cpp). Encoding: docs/recording.md, "Pool-backed topics".
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace horus::detail {

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

/// The PoolFrames of a type; nullptr when it is not pool-backed, or horus::pool is not linked
/// (then no value of such a type can exist in this process either).
inline std::unique_ptr<PoolFrames> make_pool_frames(std::string_view type_name,
                                                    std::uint64_t fingerprint,
                                                    const std::string& namespace_name,
                                                    std::size_t keep) {
  const PoolFramesFactory factory = pool_frames_factory().load(std::memory_order_acquire);
  return factory != nullptr ? factory(type_name, fingerprint, namespace_name, keep) : nullptr;
}

/// Registers horus::pool's PoolFrames (done when pool_mapping.cpp is linked; a program that
/// records topics of processes other than itself, such as horus-record, calls it).
void enable_pool_frames() noexcept;

}  // namespace horus::detail
