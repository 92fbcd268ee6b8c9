// Helpers of horus::msg::GenericMessage (fragment: included inside the generated struct body).
// Every way in and out checks the MAX_PAYLOAD limit and throws horus::Error naming the call and
// the size, so an oversized payload is refused where it is made, not dropped by a topic later.

/// A message holding the raw MessagePack bytes `payload`.
static GenericMessage make(std::vector<std::uint8_t> payload) {
  check_payload_size(payload.size(), "GenericMessage::make");
  GenericMessage msg;
  msg.data = std::move(payload);
  return msg;
}

/// A message holding `payload` and the metadata string `meta`.
static GenericMessage with_metadata(std::vector<std::uint8_t> payload, std::string meta) {
  check_payload_size(payload.size(), "GenericMessage::with_metadata");
  GenericMessage msg;
  msg.data = std::move(payload);
  msg.metadata = std::move(meta);
  return msg;
}

/// A message holding `value` packed as MessagePack: anything msgpack-cxx can pack (numbers,
/// strings, std::vector, std::map, MSGPACK_DEFINE_MAP structs, horus messages). Needs
/// <horus/msgpack.hpp> (and the msgpack-cxx adaptor of any other type packed).
template <class T>
static GenericMessage from_value(const T& value) {
  std::vector<std::uint8_t> payload = horus::detail::Msgpack<T>::pack(value);
  check_payload_size(payload.size(), "GenericMessage::from_value");
  GenericMessage msg;
  msg.data = std::move(payload);
  return msg;
}

/// The payload unpacked as a `T`. Throws horus::Error when the payload is over MAX_PAYLOAD and
/// horus::DecodeError when it is not one MessagePack value convertible to `T`. Needs
/// <horus/msgpack.hpp>.
template <class T>
T to_value() const {
  check_payload_size(data.size(), "GenericMessage::to_value");
  return horus::detail::Msgpack<T>::unpack(data, "GenericMessage::to_value");
}

/// Throws horus::Error when `size` bytes exceed MAX_PAYLOAD.
static void check_payload_size(std::size_t size, std::string_view where) {
  if (size > MAX_PAYLOAD) {
    throw horus::Error(std::string(where) + ": payload of " + std::to_string(size) +
                       " bytes exceeds the " + std::to_string(MAX_PAYLOAD) +
                       "-byte maximum of GenericMessage");
  }
}
