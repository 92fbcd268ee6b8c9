// horus::Tensor: shape, strides and the bounds every received descriptor must keep.
#include "horus/tensor.hpp"

#include <cstring>
#include <limits>

namespace horus {

Tensor Tensor::make(std::span<const std::uint64_t> shape, msg::TensorDtype dtype,
                    const TensorPool& pool) {
  const std::size_t unit = detail::dtype_size(dtype);
  if (unit == 0) {
    throw Error("Tensor::make: unknown dtype " + std::to_string(static_cast<unsigned>(dtype)));
  }
  if (shape.size() > kMaxDimensions) {
    throw Error("Tensor::make: " + std::to_string(shape.size()) + " dimensions, at most " +
                std::to_string(kMaxDimensions));
  }
  Descriptor descriptor{};
  descriptor.ndim = static_cast<std::uint8_t>(shape.size());
  descriptor.dtype = dtype;
  std::uint64_t size = unit;
  for (std::size_t i = shape.size(); i-- > 0;) {
    descriptor.shape[i] = shape[i];
    descriptor.strides[i] = size;
    if (shape[i] != 0 && size > pool.block_size() / shape[i]) {
      throw Error("Tensor::make: the tensor does not fit in a block of pool " + pool.name() + " (" +
                  std::to_string(pool.block_size()) + " bytes)");
    }
    size *= shape[i];
  }
  descriptor.data_size = size;
  // An empty tensor still takes a block: every Tensor names one, so that it can be sent.
  Tensor tensor(detail::allocate_block(pool, size), descriptor, true);
  std::memset(tensor.bytes(), 0, size);
  return tensor;
}

std::uint64_t Tensor::element_count() const noexcept {
  std::uint64_t count = 1;
  for (const std::uint64_t extent : shape()) {
    count *= extent;
  }
  return count;
}

bool Tensor::valid_descriptor(const Descriptor& descriptor, std::size_t block_size) noexcept {
  const std::size_t unit = detail::dtype_size(descriptor.dtype);
  if (unit == 0 || descriptor.ndim > kMaxDimensions || descriptor.data_size > block_size) {
    return false;
  }
  // Every element any stride reaches lies inside data_size.
  std::uint64_t last = 0;
  for (std::size_t i = 0; i < descriptor.ndim; ++i) {
    const std::uint64_t extent = descriptor.shape[i];
    if (extent == 0) {
      return descriptor.data_size == 0;
    }
    if (descriptor.strides[i] > block_size || extent - 1 > block_size) {
      return false;
    }
    last += (extent - 1) * descriptor.strides[i];
    if (last > block_size) {
      return false;
    }
  }
  return last + unit <= descriptor.data_size;
}

Tensor& Tensor::copy_from(std::span<const std::uint8_t> source) {
  copy_bytes(source, "Tensor");
  return *this;
}

std::string Tensor::log_summary() const {
  std::string text = "Tensor([";
  for (std::size_t i = 0; i < ndim(); ++i) {
    text += (i > 0 ? ", " : "") + std::to_string(shape()[i]);
  }
  text += "] " + std::string(TypeInfo<msg::TensorDtype>::to_string(dtype())) + ", " +
          std::to_string(size()) + " bytes in pool block " + std::to_string(block().index) +
          ", frame \"" + std::string(frame_id()) + "\", t " + std::to_string(timestamp_ns()) +
          " ns)";
  return text;
}

}  // namespace horus
