// horus::Image: geometry, pixel access and the log summary.
#include "horus/image.hpp"

#include <algorithm>
#include <cstring>
#include <limits>

namespace horus {

namespace {

struct EncodingShape {
  std::uint32_t bytes;
  std::uint32_t channels;
};

EncodingShape shape_of(ImageEncoding encoding) noexcept {
  switch (encoding) {
    case ImageEncoding::Mono8:
    case ImageEncoding::BayerRggb8:
      return {1, 1};
    case ImageEncoding::Mono16:
    case ImageEncoding::Depth16:
      return {2, 1};
    case ImageEncoding::Rgb8:
    case ImageEncoding::Bgr8:
      return {3, 3};
    case ImageEncoding::Rgba8:
    case ImageEncoding::Bgra8:
      return {4, 4};
    case ImageEncoding::Yuv422:
      return {2, 2};
    case ImageEncoding::Mono32F:
      return {4, 1};
    case ImageEncoding::Rgb32F:
      return {12, 3};
  }
  return {0, 0};
}

}  // namespace

std::uint32_t bytes_per_pixel(ImageEncoding encoding) noexcept { return shape_of(encoding).bytes; }
std::uint32_t channel_count(ImageEncoding encoding) noexcept { return shape_of(encoding).channels; }

Image Image::make(std::uint32_t height, std::uint32_t width, ImageEncoding encoding,
                  const TensorPool& pool) {
  const EncodingShape shape = shape_of(encoding);
  if (shape.bytes == 0) {
    throw Error("Image::make: unknown encoding " + std::to_string(static_cast<unsigned>(encoding)));
  }
  if (width == 0 || height == 0) {
    throw Error("Image::make: an image needs at least one pixel (got " + std::to_string(width) +
                "x" + std::to_string(height) + ")");
  }
  const std::uint64_t step = std::uint64_t{width} * shape.bytes;
  const std::uint64_t size = step * height;
  if (step > std::numeric_limits<std::uint32_t>::max() || size > pool.block_size()) {
    throw Error("Image::make: " + std::to_string(width) + "x" + std::to_string(height) + " " +
                std::string(TypeInfo<ImageEncoding>::to_string(encoding)) + " needs " +
                std::to_string(size) + " bytes, a block of pool " + pool.name() + " holds " +
                std::to_string(pool.block_size()) +
                " (open a pool with a larger TensorPoolOptions::block_size)");
  }
  Descriptor descriptor{};
  descriptor.width = width;
  descriptor.height = height;
  descriptor.encoding = encoding;
  descriptor.channels = static_cast<std::uint8_t>(shape.channels);
  descriptor.step = static_cast<std::uint32_t>(step);
  descriptor.data_size = size;
  Image image(detail::allocate_block(pool, size), descriptor, true);
  std::memset(image.bytes(), 0, size);
  return image;
}

bool Image::valid_descriptor(const Descriptor& descriptor, std::size_t block_size) noexcept {
  const EncodingShape shape = shape_of(descriptor.encoding);
  return shape.bytes != 0 && descriptor.channels == shape.channels &&
         std::uint64_t{descriptor.step} >= std::uint64_t{descriptor.width} * shape.bytes &&
         descriptor.data_size == std::uint64_t{descriptor.step} * descriptor.height &&
         descriptor.data_size <= block_size;
}

std::uint32_t Image::bytes_per_pixel() const noexcept {
  return shape_of(descriptor_.encoding).bytes;
}

std::optional<std::span<const std::uint8_t>> Image::pixel(std::uint32_t x,
                                                          std::uint32_t y) const noexcept {
  if (!valid() || x >= width() || y >= height()) {
    return std::nullopt;
  }
  const std::size_t offset = std::size_t{y} * step() + std::size_t{x} * bytes_per_pixel();
  return std::span<const std::uint8_t>(bytes() + offset, bytes_per_pixel());
}

Image& Image::set_pixel(std::uint32_t x, std::uint32_t y, std::span<const std::uint8_t> value) {
  require_writable();
  if (x >= width() || y >= height()) {
    throw Error("Image::set_pixel: (" + std::to_string(x) + ", " + std::to_string(y) +
                ") is outside the " + std::to_string(width()) + "x" + std::to_string(height()) +
                " image");
  }
  if (value.size() != bytes_per_pixel()) {
    throw Error("Image::set_pixel: a pixel is " + std::to_string(bytes_per_pixel()) +
                " bytes, got " + std::to_string(value.size()));
  }
  std::copy(value.begin(), value.end(),
            bytes() + std::size_t{y} * step() + std::size_t{x} * bytes_per_pixel());
  return *this;
}

Image& Image::copy_from(std::span<const std::uint8_t> source) {
  copy_bytes(source, "Image");
  return *this;
}

Image& Image::fill(std::uint8_t value) {
  require_writable();
  std::memset(bytes(), value, size());
  return *this;
}

Image& Image::fill(std::span<const std::uint8_t> value) {
  require_writable();
  if (value.size() != bytes_per_pixel()) {
    throw Error("Image::fill: a pixel is " + std::to_string(bytes_per_pixel()) + " bytes, got " +
                std::to_string(value.size()));
  }
  for (std::uint32_t y = 0; y < height(); ++y) {
    std::uint8_t* row = bytes() + std::size_t{y} * step();
    for (std::uint32_t x = 0; x < width(); ++x) {
      std::copy(value.begin(), value.end(), row + std::size_t{x} * value.size());
    }
  }
  return *this;
}

std::optional<std::vector<std::uint8_t>> Image::roi(std::uint32_t x, std::uint32_t y,
                                                    std::uint32_t w, std::uint32_t h) const {
  if (!valid() || w == 0 || h == 0 || std::uint64_t{x} + w > width() ||
      std::uint64_t{y} + h > height()) {
    return std::nullopt;
  }
  const std::size_t row_bytes = std::size_t{w} * bytes_per_pixel();
  std::vector<std::uint8_t> region(row_bytes * h);
  for (std::uint32_t row = 0; row < h; ++row) {
    const std::uint8_t* from =
        bytes() + std::size_t{y + row} * step() + std::size_t{x} * bytes_per_pixel();
    std::copy(from, from + row_bytes, region.data() + row * row_bytes);
  }
  return region;
}

std::string Image::log_summary() const {
  std::string text = "Image(" + std::to_string(width()) + "x" + std::to_string(height()) + " " +
                     std::string(TypeInfo<ImageEncoding>::to_string(encoding())) + ", " +
                     std::to_string(size()) + " bytes in pool block " +
                     std::to_string(block().index) + ", frame \"" + std::string(frame_id()) +
                     "\", t " + std::to_string(timestamp_ns()) + " ns)";
  return text;
}

}  // namespace horus
