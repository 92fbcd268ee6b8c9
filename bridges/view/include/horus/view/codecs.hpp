// horus::view codecs: how the live view (bridges/view) shows a HORUS topic to a Foxglove viewer.
// For each topic a codec says what channel to advertise (Foxglove WebSocket protocol: encoding,
// schemaName, schemaEncoding, schema) and turns each frame of the topic (a POD message's bytes, a
// serialized message's MessagePack bytes, or a pool frame as horus::PoolFrames::record writes it)
// into the message payload a viewer decodes, and a payload a viewer publishes back into a frame.
//
// The decisions (which type becomes which Foxglove schema) are the recording export's
// (runtime/python/horus/foxglove.py); everything is built from the topic's type description, never
// from schema text.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "horus/raw_topic.hpp"

namespace horus::view {

/// What a channel advertisement carries about its messages (Foxglove ws-protocol "advertise").
struct ChannelSchema {
  /// The message encoding: "json" or "protobuf".
  std::string encoding;
  /// "horus.msg.Imu" for a type shown as JSON; "foxglove.RawImage" for a well-known schema.
  std::string schema_name;
  /// "jsonschema" or "protobuf".
  std::string schema_encoding;
  /// JSON Schema text, or a serialized google.protobuf.FileDescriptorSet.
  std::string schema;
  /// True when `schema` is binary (the protobuf descriptor set): the advertisement base64s it.
  bool schema_is_binary = false;
};

/// A type or a message the live view cannot convert, saying what and where.
class CodecError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One topic's conversion. Not thread-safe: one codec per topic per thread.
class MessageCodec {
 public:
  virtual ~MessageCodec() = default;
  virtual const ChannelSchema& schema() const = 0;
  /// One frame of the topic into the payload of a Foxglove message (the vector is overwritten;
  /// its capacity is reused). Throws CodecError on a frame that is not a message of the type.
  virtual void encode(std::span<const std::byte> frame, std::vector<std::byte>& payload) = 0;
  /// A payload a viewer published (clientPublish) into a frame of the topic. Throws CodecError on
  /// a payload that is not such a message, or when the codec does not take messages from viewers.
  virtual void decode(std::span<const std::byte> payload, std::vector<std::byte>& frame) = 0;
};

/// The codec for a topic of `type` called `topic`. Frame names a Foxglove schema needs and the
/// message lacks default to `topic`. Throws CodecError when the type carries no description or the
/// description cannot be read.
std::unique_ptr<MessageCodec> codec_for(const horus::TypeIdentity& type, const std::string& topic);

}  // namespace horus::view
