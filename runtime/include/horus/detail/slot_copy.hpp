// How a POD message is copied into its slot.
#pragma once

#include <cstddef>
#include <cstring>

namespace horus::detail {

/// Copies a POD message of N bytes into a slot. Small fixed-size copies compile to a few vector
/// moves, but GCC expands fixed sizes from a few hundred bytes up to 8 KB as an inline
/// `rep movsq`, which made a 1.5 KB one-way message about 0.1x of the floor slower than glibc's
/// memcpy does when the slot's lines sit in a subscriber's cache (bench/topic/RESULTS.md).
/// Past kInlineCopyLimit the size is hidden from the compiler, so the library copy runs.
inline constexpr std::size_t kInlineCopyLimit = 256;
template <std::size_t N>
inline void copy_to_slot(std::byte* payload, const void* msg) noexcept {
  std::size_t size = N;
  if constexpr (N > kInlineCopyLimit) {
    asm("" : "+r"(size));
  }
  std::memcpy(payload, msg, size);
}

}  // namespace horus::detail
