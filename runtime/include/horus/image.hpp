// horus::Image: a camera image whose pixels live in a shared-memory TensorPool. A Topic<Image>
// sends only its descriptor (msg::ImageDescriptor); the receiver reads the pixels in place.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <horus/msg/image_descriptor.hpp>
#include <horus/msg/image_encoding.hpp>

#include "horus/detail/pool_backed.hpp"
#include "horus/pool_topic.hpp"
#include "horus/tensor_pool.hpp"

namespace horus {

using msg::ImageEncoding;

/// Bytes per pixel of an encoding (0 for a value outside the enum).
std::uint32_t bytes_per_pixel(ImageEncoding encoding) noexcept;
/// Channels per pixel of an encoding (0 for a value outside the enum).
std::uint32_t channel_count(ImageEncoding encoding) noexcept;

class Image : public detail::PoolBacked<msg::ImageDescriptor> {
 public:
  using Descriptor = msg::ImageDescriptor;

  /// A zeroed image of `height` rows of `width` pixels (the seed's argument order), rows packed
  /// (step = width * bytes per pixel), in `pool`. Throws horus::Error for a zero or oversized
  /// geometry, an unknown encoding, or an exhausted pool (PoolExhaustion says what then).
  static Image make(std::uint32_t height, std::uint32_t width, ImageEncoding encoding,
                    const TensorPool& pool = default_pool());

  std::uint32_t width() const noexcept { return descriptor_.width; }
  std::uint32_t height() const noexcept { return descriptor_.height; }
  ImageEncoding encoding() const noexcept { return descriptor_.encoding; }
  std::uint32_t channels() const noexcept { return descriptor_.channels; }
  /// Bytes per row.
  std::uint32_t step() const noexcept { return descriptor_.step; }
  std::uint32_t bytes_per_pixel() const noexcept;

  /// The bytes of pixel (x, y), or nullopt outside the image.
  std::optional<std::span<const std::uint8_t>> pixel(std::uint32_t x,
                                                     std::uint32_t y) const noexcept;
  /// Sets pixel (x, y) to `value` (bytes_per_pixel() bytes). Throws horus::Error outside the
  /// image, for another size, or on a received (read-only) image.
  Image& set_pixel(std::uint32_t x, std::uint32_t y, std::span<const std::uint8_t> value);
  /// Copies all pixel bytes (step * height of them) from `source`.
  Image& copy_from(std::span<const std::uint8_t> source);
  /// Every byte set to `value`.
  Image& fill(std::uint8_t value);
  /// Every pixel set to `value` (bytes_per_pixel() bytes).
  Image& fill(std::span<const std::uint8_t> value);
  /// A copy of the region (packed rows), or nullopt when it leaves the image or is empty.
  std::optional<std::vector<std::uint8_t>> roi(std::uint32_t x, std::uint32_t y, std::uint32_t w,
                                               std::uint32_t h) const;
  /// One line describing the image, not its pixels.
  std::string log_summary() const;

  /// Whether `descriptor` describes an image that fits in a block of `block_size` bytes.
  static bool valid_descriptor(const Descriptor& descriptor, std::size_t block_size) noexcept;
  /// A received image: read-only, holding the reference `ref`.
  static Image received(detail::BlockRef ref, const Descriptor& descriptor) noexcept {
    return Image(std::move(ref), descriptor, false);
  }

  Image() = default;

 private:
  Image(detail::BlockRef ref, const Descriptor& descriptor, bool writable) noexcept
      : PoolBacked(std::move(ref), descriptor, writable) {}
};

/// A topic of Image sends the descriptor type, so tools and other languages see
/// horus.msg.ImageDescriptor on it.
template <>
struct TypeInfo<Image> : TypeInfo<msg::ImageDescriptor> {
  static constexpr bool is_pool_backed = true;
};

}  // namespace horus
