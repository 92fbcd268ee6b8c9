// A serialized message with every field zero: horus-remote carries types it was not compiled
// with, and answering a call it could not get answered takes a response frame, whose payload
// must decode as the response type. Written from the type's description
// (horus/type_description.hpp), which every generated type and every service frame carries.
#pragma once

#include <cstddef>
#include <vector>

#include "horus/topic_registry.hpp"

namespace horus::remote {

/// The encoding of a message of the type of a topic whose numbers are 0, bools false, strings,
/// sequences and bytes empty, options none, enums 0, fixed arrays full of such elements: what
/// C++'s and Python's decoders read back. Throws horus::TypeDescriptionError when
/// `type.description` is empty (code generated before descriptions) or not a description holding
/// `type.type_name`.
std::vector<std::byte> zero_message(const TopicInfo& type);

}  // namespace horus::remote
