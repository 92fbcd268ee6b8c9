// horus::PointCloud: packed points in a shared-memory TensorPool. A Topic<PointCloud> sends only
// its descriptor (msg::PointCloudDescriptor).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <horus/msg/point_cloud_descriptor.hpp>
#include <horus/msg/tensor_dtype.hpp>

#include "horus/detail/pool_backed.hpp"
#include "horus/pool_topic.hpp"
#include "horus/tensor_pool.hpp"

namespace horus {

class PointCloud : public detail::PoolBacked<msg::PointCloudDescriptor> {
 public:
  using Descriptor = msg::PointCloudDescriptor;

  /// A zeroed cloud of `point_count` points of `fields_per_point` components of `dtype`.
  static PointCloud make(std::uint64_t point_count, std::uint32_t fields_per_point,
                         msg::TensorDtype dtype, const TensorPool& pool = default_pool());
  /// F32 clouds copied from points: XYZ, XYZ + intensity, XYZ + RGB (6 floats).
  static PointCloud from_xyz(std::span<const std::array<float, 3>> points,
                             const TensorPool& pool = default_pool());
  static PointCloud from_xyzi(std::span<const std::array<float, 4>> points,
                              const TensorPool& pool = default_pool());
  static PointCloud from_xyzrgb(std::span<const std::array<float, 6>> points,
                                const TensorPool& pool = default_pool());

  std::uint64_t point_count() const noexcept { return descriptor_.point_count; }
  std::uint32_t fields_per_point() const noexcept { return descriptor_.fields_per_point; }
  msg::TensorDtype dtype() const noexcept { return descriptor_.dtype; }
  bool is_xyz() const noexcept { return descriptor_.fields_per_point == 3; }
  bool has_intensity() const noexcept { return descriptor_.fields_per_point == 4; }
  bool has_color() const noexcept { return descriptor_.fields_per_point == 6; }
  /// Bytes per point.
  std::size_t point_size() const noexcept;

  /// The bytes of point `index`, or nullopt past the end.
  std::optional<std::span<const std::uint8_t>> point_at(std::uint64_t index) const noexcept;
  /// The XYZ of every point (F32 clouds only; nullopt otherwise).
  std::optional<std::vector<std::array<float, 3>>> extract_xyz() const;
  /// Copies all point bytes from `source`.
  PointCloud& copy_from(std::span<const std::uint8_t> source);
  std::string log_summary() const;

  static bool valid_descriptor(const Descriptor& descriptor, std::size_t block_size) noexcept;
  static PointCloud received(detail::BlockRef ref, const Descriptor& descriptor) noexcept {
    return PointCloud(std::move(ref), descriptor, false);
  }

  PointCloud() = default;

 private:
  PointCloud(detail::BlockRef ref, const Descriptor& descriptor, bool writable) noexcept
      : PoolBacked(std::move(ref), descriptor, writable) {}
  template <std::size_t Fields>
  static PointCloud from_points(std::span<const std::array<float, Fields>> points,
                                const TensorPool& pool);
};

template <>
struct TypeInfo<PointCloud> : TypeInfo<msg::PointCloudDescriptor> {
  static constexpr bool is_pool_backed = true;
};

}  // namespace horus
