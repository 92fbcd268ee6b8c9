// What Image, DepthImage, PointCloud and Tensor share: a reference on a pool block, the
// descriptor a topic sends for it, and whether this handle may write the data.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>

#include <horus/msg/tensor_dtype.hpp>

#include "horus/detail/pool_mapping.hpp"
#include "horus/error.hpp"
#include "horus/tensor_pool.hpp"

namespace horus::detail {

/// Bytes of one element of `dtype` (0 for a value outside the enum).
constexpr std::size_t dtype_size(msg::TensorDtype dtype) noexcept {
  switch (dtype) {
    case msg::TensorDtype::U8:
    case msg::TensorDtype::I8:
      return 1;
    case msg::TensorDtype::U16:
    case msg::TensorDtype::I16:
    case msg::TensorDtype::F16:
      return 2;
    case msg::TensorDtype::F32:
    case msg::TensorDtype::I32:
    case msg::TensorDtype::U32:
      return 4;
    case msg::TensorDtype::F64:
    case msg::TensorDtype::I64:
    case msg::TensorDtype::U64:
      return 8;
  }
  return 0;
}

/// Allocates a block of `size` bytes from `pool` (throws horus::Error when it cannot).
inline BlockRef allocate_block(const TensorPool& pool, std::size_t size) {
  return BlockRef(pool.mapping(), pool.mapping()->allocate(size));
}

/// Base of the pool-backed types (not used on its own). Copies share the block (one more
/// reference), so a copy of a received frame is as cheap as the frame.
template <class Descriptor>
class PoolBacked {
 public:
  /// The descriptor a topic carries for this value.
  const Descriptor& descriptor() const noexcept { return descriptor_; }
  /// The pool block holding the data (pool id, index, generation).
  const msg::PoolBlock& block() const noexcept { return descriptor_.block; }
  /// False only for a moved-from value.
  bool valid() const noexcept { return static_cast<bool>(ref_); }
  /// Whether data_mut() may be used: true for a value this process made, false for one it
  /// received (others may be reading the same bytes).
  bool writable() const noexcept { return writable_; }
  /// The pool this value lives in.
  TensorPool pool() const { return TensorPool(ref_.shared_pool()); }
  PoolMapping* pool_mapping() const noexcept { return ref_.pool(); }
  const std::shared_ptr<PoolMapping>& shared_pool_mapping() const noexcept {
    return ref_.shared_pool();
  }

  /// The bytes, in place in shared memory.
  std::span<const std::uint8_t> data() const noexcept {
    return {reinterpret_cast<const std::uint8_t*>(ref_.data()), size()};
  }
  /// The bytes for writing; throws horus::Error on a received (read-only) value.
  std::span<std::uint8_t> data_mut() {
    require_writable();
    return {reinterpret_cast<std::uint8_t*>(ref_.data()), size()};
  }
  std::size_t size() const noexcept {
    return ref_ ? static_cast<std::size_t>(descriptor_.data_size) : 0;
  }

  std::string_view frame_id() const noexcept { return descriptor_.frame_id.view(); }
  /// Throws horus::Error when longer than 31 bytes.
  void set_frame_id(std::string_view frame) { descriptor_.frame_id.assign(frame); }
  std::uint64_t timestamp_ns() const noexcept { return descriptor_.timestamp_ns; }
  void set_timestamp_ns(std::uint64_t timestamp) noexcept { descriptor_.timestamp_ns = timestamp; }

 protected:
  PoolBacked() = default;
  PoolBacked(BlockRef ref, const Descriptor& descriptor, bool writable) noexcept
      : ref_(std::move(ref)), descriptor_(descriptor), writable_(writable) {
    descriptor_.block = ref_.block();
  }

  void require_writable() const {
    if (!writable_) {
      throw Error(
          "this value was received from a topic and is read-only (its sender and other "
          "receivers read the same shared memory); copy it into a new one to change it");
    }
  }
  std::uint8_t* bytes() noexcept { return reinterpret_cast<std::uint8_t*>(ref_.data()); }
  const std::uint8_t* bytes() const noexcept {
    return reinterpret_cast<const std::uint8_t*>(ref_.data());
  }
  /// Copies `source` over the whole data; throws horus::Error when the sizes differ.
  void copy_bytes(std::span<const std::uint8_t> source, std::string_view what);

  BlockRef ref_;
  Descriptor descriptor_{};
  bool writable_ = false;
};

template <class Descriptor>
void PoolBacked<Descriptor>::copy_bytes(std::span<const std::uint8_t> source,
                                        std::string_view what) {
  require_writable();
  if (source.size() != size()) {
    throw Error(std::string(what) + ": copy_from got " + std::to_string(source.size()) +
                " bytes, the data is " + std::to_string(size()));
  }
  std::copy(source.begin(), source.end(), bytes());
}

}  // namespace horus::detail
