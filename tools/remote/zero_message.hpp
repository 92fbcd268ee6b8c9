// A serialized message with every field zero, written from its type's canonical schema text:
// horus-remote carries types it was not compiled with, and answering a call it could not get
// answered takes a response frame, whose payload must decode as the response type.
#pragma once

#include <cstddef>
#include <string_view>
#include <vector>

namespace horus::remote {

/// The MessagePack encoding of a `type` whose numbers are 0, bools false, strings, sequences and
/// bytes empty, options none, enums 0, fixed arrays full of such elements: what C++'s and
/// Python's decoders read back. `schema` is the canonical schema text that holds `type` and
/// every type it uses (what a topic segment records). Throws std::runtime_error naming a type
/// the text does not define.
std::vector<std::byte> zero_message(std::string_view schema, std::string_view type);

}  // namespace horus::remote
