// A msgpack-cxx output stream over a fixed buffer (a topic slot), so sending a serialized
// message encodes straight into shared memory without allocating.
#pragma once

#include <cstddef>
#include <cstring>

namespace horus::detail {

class FixedBufferStream {
 public:
  FixedBufferStream(std::byte* data, std::size_t capacity) noexcept
      : data_(data), capacity_(capacity) {}

  /// The msgpack::packer interface. Past the capacity it only records the overflow, so the
  /// encoder runs to completion and the caller reports one clear error.
  void write(const char* bytes, std::size_t count) noexcept {
    if (overflowed_ || count > capacity_ - size_) {
      overflowed_ = true;
      return;
    }
    std::memcpy(data_ + size_, bytes, count);
    size_ += count;
  }

  std::size_t size() const noexcept { return size_; }
  bool overflowed() const noexcept { return overflowed_; }

 private:
  std::byte* data_;
  std::size_t capacity_;
  std::size_t size_ = 0;
  bool overflowed_ = false;
};

}  // namespace horus::detail
