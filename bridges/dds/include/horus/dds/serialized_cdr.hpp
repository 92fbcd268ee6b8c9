// A serialized (MessagePack) message type's CDR (XCDR1, the IDL horus-gen emits), both ways,
// from the type description: out through the description's walker (walk_message), in by reading
// the CDR member by member into the MessagePack HORUS decoders read (arrays of fields, enums as
// integers, byte blocks as bin, none as nil). The same bytes as the Python bridge's dds_cdr.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "horus/type_description.hpp"

namespace horus::dds_bridge {

class SerializedCdr {
 public:
  /// For the message `type_name` of `description` (kept by the caller while this lives).
  SerializedCdr(const TypeDescription& description, const MessageType& type);

  const std::string& type_name() const noexcept { return type_->name; }

  /// The DDS sample of an encoded message (CDR_LE, padded to a multiple of 4); throws DecodeError
  /// when the bytes are not such a message.
  void encode(std::span<const std::uint8_t> message, std::vector<std::byte>& sample) const;

  /// The encoded message of a DDS sample (little- or big-endian CDR) into `message`; an empty
  /// string when it decoded, else why not (one line).
  std::string decode(std::span<const std::byte> sample, std::vector<std::uint8_t>& message) const;

 private:
  const TypeDescription* description_;
  const MessageType* type_;
};

}  // namespace horus::dds_bridge
