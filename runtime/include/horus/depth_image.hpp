// horus::DepthImage: a depth image in a shared-memory TensorPool, F32 metres or U16 millimetres.
// A Topic<DepthImage> sends only its descriptor (msg::DepthImageDescriptor).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <horus/msg/depth_image_descriptor.hpp>
#include <horus/msg/tensor_dtype.hpp>

#include "horus/detail/pool_backed.hpp"
#include "horus/pool_topic.hpp"
#include "horus/tensor_pool.hpp"

namespace horus {

using msg::TensorDtype;

/// Minimum, maximum and mean of the valid depths of an image, in metres.
struct DepthStatistics {
  float min = 0;
  float max = 0;
  float mean = 0;
};

class DepthImage : public detail::PoolBacked<msg::DepthImageDescriptor> {
 public:
  using Descriptor = msg::DepthImageDescriptor;

  /// A zeroed F32 depth image in metres, `height` rows of `width` pixels.
  static DepthImage meters(std::uint32_t height, std::uint32_t width,
                           const TensorPool& pool = default_pool());
  /// A zeroed U16 depth image in millimetres (depth_scale 0.001).
  static DepthImage millimeters(std::uint32_t height, std::uint32_t width,
                                const TensorPool& pool = default_pool());

  std::uint32_t width() const noexcept { return descriptor_.width; }
  std::uint32_t height() const noexcept { return descriptor_.height; }
  TensorDtype dtype() const noexcept { return descriptor_.dtype; }
  bool is_meters() const noexcept { return descriptor_.dtype == TensorDtype::F32; }
  bool is_millimeters() const noexcept { return descriptor_.dtype == TensorDtype::U16; }
  /// Metres per raw unit (1 for F32, 0.001 for U16).
  float depth_scale() const noexcept { return descriptor_.depth_scale; }

  /// Depth at (x, y) in metres, or nullopt outside the image.
  std::optional<float> get_depth(std::uint32_t x, std::uint32_t y) const noexcept;
  /// Sets the depth at (x, y) in metres (rounded to the nearest unit, clamped to 0..65535, for
  /// U16). Throws horus::Error outside the image or on a received (read-only) image.
  DepthImage& set_depth(std::uint32_t x, std::uint32_t y, float meters);
  /// The raw U16 value at (x, y); nullopt outside the image or for an F32 image.
  std::optional<std::uint16_t> get_depth_u16(std::uint32_t x, std::uint32_t y) const noexcept;
  /// Over the valid pixels (finite and above zero); all zero when there is none.
  DepthStatistics depth_statistics() const noexcept;
  /// Copies all raw bytes from `source`.
  DepthImage& copy_from(std::span<const std::uint8_t> source);
  std::string log_summary() const;

  static bool valid_descriptor(const Descriptor& descriptor, std::size_t block_size) noexcept;
  static DepthImage received(detail::BlockRef ref, const Descriptor& descriptor) noexcept {
    return DepthImage(std::move(ref), descriptor, false);
  }

  DepthImage() = default;

 private:
  DepthImage(detail::BlockRef ref, const Descriptor& descriptor, bool writable) noexcept
      : PoolBacked(std::move(ref), descriptor, writable) {}
  static DepthImage make(std::uint32_t height, std::uint32_t width, TensorDtype dtype, float scale,
                         const TensorPool& pool);
  std::size_t offset(std::uint32_t x, std::uint32_t y) const noexcept;
};

template <>
struct TypeInfo<DepthImage> : TypeInfo<msg::DepthImageDescriptor> {
  static constexpr bool is_pool_backed = true;
};

}  // namespace horus
