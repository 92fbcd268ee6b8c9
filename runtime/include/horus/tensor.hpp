// horus::Tensor: an n-dimensional array (up to 8 dimensions) in a shared-memory TensorPool, for
// ML pipelines. A Topic<Tensor> sends only its descriptor (msg::TensorDescriptor).
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include <horus/msg/tensor_descriptor.hpp>
#include <horus/msg/tensor_dtype.hpp>

#include "horus/detail/pool_backed.hpp"
#include "horus/pool_topic.hpp"
#include "horus/tensor_pool.hpp"

namespace horus {

class Tensor : public detail::PoolBacked<msg::TensorDescriptor> {
 public:
  using Descriptor = msg::TensorDescriptor;
  static constexpr std::size_t kMaxDimensions = 8;

  /// A zeroed, row-major (C-contiguous) tensor of `shape` and `dtype`.
  static Tensor make(std::span<const std::uint64_t> shape, msg::TensorDtype dtype,
                     const TensorPool& pool = default_pool());
  static Tensor make(std::initializer_list<std::uint64_t> shape, msg::TensorDtype dtype,
                     const TensorPool& pool = default_pool()) {
    return make(std::span<const std::uint64_t>(shape.begin(), shape.size()), dtype, pool);
  }

  std::size_t ndim() const noexcept { return descriptor_.ndim; }
  std::span<const std::uint64_t> shape() const noexcept {
    return {descriptor_.shape.data(), ndim()};
  }
  /// Bytes between consecutive elements along each dimension.
  std::span<const std::uint64_t> strides() const noexcept {
    return {descriptor_.strides.data(), ndim()};
  }
  msg::TensorDtype dtype() const noexcept { return descriptor_.dtype; }
  std::size_t element_size() const noexcept { return detail::dtype_size(dtype()); }
  /// Elements (the product of the shape).
  std::uint64_t element_count() const noexcept;
  /// Copies all bytes from `source`.
  Tensor& copy_from(std::span<const std::uint8_t> source);
  std::string log_summary() const;

  static bool valid_descriptor(const Descriptor& descriptor, std::size_t block_size) noexcept;
  static Tensor received(detail::BlockRef ref, const Descriptor& descriptor) noexcept {
    return Tensor(std::move(ref), descriptor, false);
  }

  Tensor() = default;

 private:
  Tensor(detail::BlockRef ref, const Descriptor& descriptor, bool writable) noexcept
      : PoolBacked(std::move(ref), descriptor, writable) {}
};

template <>
struct TypeInfo<Tensor> : TypeInfo<msg::TensorDescriptor> {
  static constexpr bool is_pool_backed = true;
};

}  // namespace horus
