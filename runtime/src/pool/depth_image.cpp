// horus::DepthImage: metres and millimetres, per-pixel access and statistics.
#include "horus/depth_image.hpp"

#include <cmath>
#include <cstring>
#include <limits>

namespace horus {

namespace {
constexpr float kMillimetre = 0.001F;
}  // namespace

DepthImage DepthImage::meters(std::uint32_t height, std::uint32_t width, const TensorPool& pool) {
  return make(height, width, TensorDtype::F32, 1.0F, pool);
}

DepthImage DepthImage::millimeters(std::uint32_t height, std::uint32_t width,
                                   const TensorPool& pool) {
  return make(height, width, TensorDtype::U16, kMillimetre, pool);
}

DepthImage DepthImage::make(std::uint32_t height, std::uint32_t width, TensorDtype dtype,
                            float scale, const TensorPool& pool) {
  if (width == 0 || height == 0) {
    throw Error("DepthImage: an image needs at least one pixel (got " + std::to_string(width) +
                "x" + std::to_string(height) + ")");
  }
  const std::uint64_t size =
      std::uint64_t{width} * height * (dtype == TensorDtype::F32 ? sizeof(float) : 2);
  if (size > pool.block_size()) {
    throw Error("DepthImage: " + std::to_string(width) + "x" + std::to_string(height) + " needs " +
                std::to_string(size) + " bytes, a block of pool " + pool.name() + " holds " +
                std::to_string(pool.block_size()));
  }
  Descriptor descriptor{};
  descriptor.width = width;
  descriptor.height = height;
  descriptor.dtype = dtype;
  descriptor.depth_scale = scale;
  descriptor.data_size = size;
  DepthImage image(detail::allocate_block(pool, size), descriptor, true);
  std::memset(image.bytes(), 0, size);
  return image;
}

bool DepthImage::valid_descriptor(const Descriptor& descriptor, std::size_t block_size) noexcept {
  const std::uint64_t unit = descriptor.dtype == TensorDtype::F32   ? 4
                             : descriptor.dtype == TensorDtype::U16 ? 2
                                                                    : 0;
  return unit != 0 &&
         descriptor.data_size == std::uint64_t{descriptor.width} * descriptor.height * unit &&
         descriptor.data_size <= block_size && std::isfinite(descriptor.depth_scale) &&
         descriptor.depth_scale > 0;
}

std::size_t DepthImage::offset(std::uint32_t x, std::uint32_t y) const noexcept {
  return (std::size_t{y} * width() + x) * (is_meters() ? sizeof(float) : 2);
}

std::optional<float> DepthImage::get_depth(std::uint32_t x, std::uint32_t y) const noexcept {
  if (!valid() || x >= width() || y >= height()) {
    return std::nullopt;
  }
  if (is_meters()) {
    float value = 0;
    std::memcpy(&value, bytes() + offset(x, y), sizeof value);
    return value;
  }
  std::uint16_t raw = 0;
  std::memcpy(&raw, bytes() + offset(x, y), sizeof raw);
  return static_cast<float>(raw) * depth_scale();
}

DepthImage& DepthImage::set_depth(std::uint32_t x, std::uint32_t y, float meters) {
  require_writable();
  if (x >= width() || y >= height()) {
    throw Error("DepthImage::set_depth: (" + std::to_string(x) + ", " + std::to_string(y) +
                ") is outside the " + std::to_string(width()) + "x" + std::to_string(height()) +
                " image");
  }
  if (is_meters()) {
    std::memcpy(bytes() + offset(x, y), &meters, sizeof meters);
  } else {
    const float units = std::isfinite(meters) ? std::round(meters / depth_scale()) : 0.0F;
    const auto raw = static_cast<std::uint16_t>(
        std::clamp(units, 0.0F, static_cast<float>(std::numeric_limits<std::uint16_t>::max())));
    std::memcpy(bytes() + offset(x, y), &raw, sizeof raw);
  }
  return *this;
}

std::optional<std::uint16_t> DepthImage::get_depth_u16(std::uint32_t x,
                                                       std::uint32_t y) const noexcept {
  if (!valid() || !is_millimeters() || x >= width() || y >= height()) {
    return std::nullopt;
  }
  std::uint16_t raw = 0;
  std::memcpy(&raw, bytes() + offset(x, y), sizeof raw);
  return raw;
}

DepthStatistics DepthImage::depth_statistics() const noexcept {
  DepthStatistics stats;
  double sum = 0;
  std::size_t count = 0;
  float low = std::numeric_limits<float>::max();
  float high = 0;
  const std::size_t pixels = valid() ? std::size_t{width()} * height() : 0;
  for (std::size_t i = 0; i < pixels; ++i) {
    float depth = 0;
    if (is_meters()) {
      std::memcpy(&depth, bytes() + i * sizeof(float), sizeof depth);
    } else {
      std::uint16_t raw = 0;
      std::memcpy(&raw, bytes() + i * 2, sizeof raw);
      depth = static_cast<float>(raw) * depth_scale();
    }
    if (std::isfinite(depth) && depth > 0) {
      low = std::min(low, depth);
      high = std::max(high, depth);
      sum += depth;
      ++count;
    }
  }
  if (count > 0) {
    stats.min = low;
    stats.max = high;
    stats.mean = static_cast<float>(sum / static_cast<double>(count));
  }
  return stats;
}

DepthImage& DepthImage::copy_from(std::span<const std::uint8_t> source) {
  copy_bytes(source, "DepthImage");
  return *this;
}

std::string DepthImage::log_summary() const {
  return "DepthImage(" + std::to_string(width()) + "x" + std::to_string(height()) + " " +
         (is_meters() ? "F32 m" : "U16 mm") + ", " + std::to_string(size()) +
         " bytes in pool block " + std::to_string(block().index) + ", frame \"" +
         std::string(frame_id()) + "\", t " + std::to_string(timestamp_ns()) + " ns)";
}

}  // namespace horus
