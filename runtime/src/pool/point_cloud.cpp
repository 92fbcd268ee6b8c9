// horus::PointCloud: construction from points, per-point access and XYZ extraction.
#include "horus/point_cloud.hpp"

#include <cstring>
#include <limits>

namespace horus {

PointCloud PointCloud::make(std::uint64_t point_count, std::uint32_t fields_per_point,
                            msg::TensorDtype dtype, const TensorPool& pool) {
  const std::size_t unit = detail::dtype_size(dtype);
  if (unit == 0) {
    throw Error("PointCloud::make: unknown dtype " + std::to_string(static_cast<unsigned>(dtype)));
  }
  if (point_count == 0 || fields_per_point == 0) {
    throw Error("PointCloud::make: a cloud needs at least one point of one field");
  }
  const std::uint64_t point_size = std::uint64_t{fields_per_point} * unit;
  if (point_count > pool.block_size() / point_size) {
    throw Error("PointCloud::make: " + std::to_string(point_count) + " points of " +
                std::to_string(point_size) + " bytes do not fit in a block of pool " + pool.name() +
                " (" + std::to_string(pool.block_size()) + " bytes)");
  }
  Descriptor descriptor{};
  descriptor.point_count = point_count;
  descriptor.fields_per_point = fields_per_point;
  descriptor.dtype = dtype;
  descriptor.data_size = point_count * point_size;
  PointCloud cloud(detail::allocate_block(pool, descriptor.data_size), descriptor, true);
  std::memset(cloud.bytes(), 0, descriptor.data_size);
  return cloud;
}

template <std::size_t Fields>
PointCloud PointCloud::from_points(std::span<const std::array<float, Fields>> points,
                                   const TensorPool& pool) {
  PointCloud cloud = make(points.size(), Fields, msg::TensorDtype::F32, pool);
  std::memcpy(cloud.bytes(), points.data(), points.size_bytes());
  return cloud;
}

PointCloud PointCloud::from_xyz(std::span<const std::array<float, 3>> points,
                                const TensorPool& pool) {
  return from_points<3>(points, pool);
}
PointCloud PointCloud::from_xyzi(std::span<const std::array<float, 4>> points,
                                 const TensorPool& pool) {
  return from_points<4>(points, pool);
}
PointCloud PointCloud::from_xyzrgb(std::span<const std::array<float, 6>> points,
                                   const TensorPool& pool) {
  return from_points<6>(points, pool);
}

bool PointCloud::valid_descriptor(const Descriptor& descriptor, std::size_t block_size) noexcept {
  const std::uint64_t point_size =
      std::uint64_t{descriptor.fields_per_point} * detail::dtype_size(descriptor.dtype);
  return point_size != 0 && descriptor.point_count <= block_size / point_size &&
         descriptor.data_size == descriptor.point_count * point_size;
}

std::size_t PointCloud::point_size() const noexcept {
  return std::size_t{fields_per_point()} * detail::dtype_size(dtype());
}

std::optional<std::span<const std::uint8_t>> PointCloud::point_at(
    std::uint64_t index) const noexcept {
  if (!valid() || index >= point_count()) {
    return std::nullopt;
  }
  return std::span<const std::uint8_t>(bytes() + index * point_size(), point_size());
}

std::optional<std::vector<std::array<float, 3>>> PointCloud::extract_xyz() const {
  if (!valid() || dtype() != msg::TensorDtype::F32 || fields_per_point() < 3) {
    return std::nullopt;
  }
  std::vector<std::array<float, 3>> xyz(point_count());
  for (std::uint64_t i = 0; i < point_count(); ++i) {
    std::memcpy(xyz[i].data(), bytes() + i * point_size(), sizeof(float) * 3);
  }
  return xyz;
}

PointCloud& PointCloud::copy_from(std::span<const std::uint8_t> source) {
  copy_bytes(source, "PointCloud");
  return *this;
}

std::string PointCloud::log_summary() const {
  return "PointCloud(" + std::to_string(point_count()) + " points x " +
         std::to_string(fields_per_point()) + " " +
         std::string(TypeInfo<msg::TensorDtype>::to_string(dtype())) + ", " +
         std::to_string(size()) + " bytes in pool block " + std::to_string(block().index) +
         ", frame \"" + std::string(frame_id()) + "\", t " + std::to_string(timestamp_ns()) +
         " ns)";
}

}  // namespace horus
