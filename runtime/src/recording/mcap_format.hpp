// The MCAP container (https://mcap.dev/spec) as far as HORUS recordings use it: opcodes, the
// magic, CRC-32 and the little-endian primitives that records are made of.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace horus::detail::mcap {

inline constexpr std::array<std::uint8_t, 8> kMagic = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum class Op : std::uint8_t {
  Header = 0x01,
  Footer = 0x02,
  Schema = 0x03,
  Channel = 0x04,
  Message = 0x05,
  Chunk = 0x06,
  MessageIndex = 0x07,
  ChunkIndex = 0x08,
  Statistics = 0x0B,
  Metadata = 0x0C,
  MetadataIndex = 0x0D,
  SummaryOffset = 0x0E,
  DataEnd = 0x0F,
};

/// Opcode and length prefix of every record.
inline constexpr std::size_t kRecordPrefix = 9;
/// Fixed part of a Message record's content before its data.
inline constexpr std::size_t kMessageFixed = 2 + 4 + 8 + 8;

/// CRC-32 (ISO-HDLC, as zlib computes it), continued from `crc` (0 to start).
std::uint32_t crc32(std::uint32_t crc, const void* data, std::size_t size) noexcept;

/// The channel metadata key of a topic's type description (docs/recording.md): the bytes in
/// base64, as channel metadata values are UTF-8 strings.
inline constexpr std::string_view kDescriptionKey = "horus.description";
/// Base64 (RFC 4648, standard alphabet, padded) of `bytes`.
std::string base64_encode(std::string_view bytes);
/// The bytes of base64 `text`; throws horus::Error naming `what` when it is not base64.
std::string base64_decode(std::string_view text, const std::string& what);

/// A growable byte buffer of little-endian records. Unlike std::vector, growing it leaves the
/// new bytes uninitialised: a 6 MB image is copied into it once, not zeroed first.
class Bytes {
 public:
  Bytes() = default;
  Bytes(Bytes&& other) noexcept
      : data_(std::move(other.data_)),
        size_(std::exchange(other.size_, 0)),
        capacity_(std::exchange(other.capacity_, 0)) {}
  Bytes& operator=(Bytes&& other) noexcept {
    data_ = std::move(other.data_);
    size_ = std::exchange(other.size_, 0);
    capacity_ = std::exchange(other.capacity_, 0);
    return *this;
  }
  Bytes(const Bytes&) = delete;
  Bytes& operator=(const Bytes&) = delete;
  ~Bytes() = default;

  std::uint8_t* data() noexcept { return data_.get(); }
  const std::uint8_t* data() const noexcept { return data_.get(); }
  std::size_t size() const noexcept { return size_; }
  void clear() noexcept { size_ = 0; }
  void truncate(std::size_t size) noexcept { size_ = size; }

  /// `size` more bytes at the end, uninitialised; where they start.
  std::uint8_t* grow(std::size_t size) {
    if (size_ + size > capacity_) {
      const std::size_t capacity = std::max(size_ + size, capacity_ * 2);
      std::unique_ptr<std::uint8_t[]> larger(new std::uint8_t[capacity]);
      if (size_ > 0) std::memcpy(larger.get(), data_.get(), size_);
      data_ = std::move(larger);
      capacity_ = capacity;
    }
    std::uint8_t* at = data_.get() + size_;
    size_ += size;
    return at;
  }
  template <class Int>
  void put(Int value) {
    std::memcpy(grow(sizeof(Int)), &value,
                sizeof(Int));  // little-endian hosts only (x86-64, arm64)
  }
  void raw(const void* bytes, std::size_t size) {
    if (size > 0) std::memcpy(grow(size), bytes, size);
  }
  void string(std::string_view text) {
    put(static_cast<std::uint32_t>(text.size()));
    raw(text.data(), text.size());
  }
  /// Starts a record; finish it with end_record(the returned position).
  std::size_t begin_record(Op op) {
    put(static_cast<std::uint8_t>(op));
    const std::size_t at = size_;
    put(std::uint64_t{0});
    return at;
  }
  void end_record(std::size_t at) { patch64(at, size_ - at - 8); }
  /// Starts a length-prefixed (u32 bytes) map or array; finish with end_block.
  std::size_t begin_block() {
    const std::size_t at = size_;
    put(std::uint32_t{0});
    return at;
  }
  void end_block(std::size_t at) {
    const auto length = static_cast<std::uint32_t>(size_ - at - 4);
    std::memcpy(data_.get() + at, &length, 4);
  }
  void patch64(std::size_t at, std::uint64_t value) { std::memcpy(data_.get() + at, &value, 8); }

 private:
  std::unique_ptr<std::uint8_t[]> data_;
  std::size_t size_ = 0;
  std::size_t capacity_ = 0;
};

/// Reads little-endian primitives from a byte range; every read is bounds-checked and throws
/// horus::Error naming `what` when the range is too short.
class Cursor {
 public:
  Cursor(const std::uint8_t* data, std::size_t size, std::string what)
      : data_(data), size_(size), what_(std::move(what)) {}

  template <class Int>
  Int get() {
    Int value;
    std::memcpy(&value, take(sizeof(Int)), sizeof(Int));
    return value;
  }
  std::string string() {
    const auto length = get<std::uint32_t>();
    const auto* bytes = take(length);
    return std::string(reinterpret_cast<const char*>(bytes), length);
  }
  const std::uint8_t* take(std::size_t size);
  std::size_t remaining() const noexcept { return size_ - at_; }
  std::size_t position() const noexcept { return at_; }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t at_ = 0;
  std::string what_;
};

}  // namespace horus::detail::mcap
