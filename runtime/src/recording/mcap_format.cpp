// CRC-32 and the bounds-checked reads of mcap_format.hpp.
#include "mcap_format.hpp"

#include <zlib.h>

#include <limits>

#include "horus/error.hpp"

namespace horus::detail::mcap {

std::uint32_t crc32(std::uint32_t crc, const void* data, std::size_t size) noexcept {
  // zlib's CRC-32 is the one MCAP specifies, and faster than a table of our own.
  const auto* bytes = static_cast<const Bytef*>(data);
  while (size > 0) {
    const std::size_t step = std::min<std::size_t>(size, std::numeric_limits<uInt>::max());
    crc = static_cast<std::uint32_t>(::crc32(crc, bytes, static_cast<uInt>(step)));
    bytes += step;
    size -= step;
  }
  return crc;
}

const std::uint8_t* Cursor::take(std::size_t size) {
  if (size > size_ - at_) {
    throw Error(what_ + ": a record ends early (needs " + std::to_string(size) + " bytes, " +
                std::to_string(size_ - at_) + " left)");
  }
  const std::uint8_t* at = data_ + at_;
  at_ += size;
  return at;
}

}  // namespace horus::detail::mcap
