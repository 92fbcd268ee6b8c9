#include "zero_message.hpp"

#include <cstdint>
#include <string>

#include "horus/type_description.hpp"

namespace horus::remote {

std::vector<std::byte> zero_message(const TopicInfo& type) {
  if (type.description.empty()) {
    throw TypeDescriptionError("cannot write a message of " + type.type_name + " (topic " +
                               type.name +
                               "): its type carries no type description (code generated "
                               "before descriptions: regenerate it)");
  }
  const TypeDescription description = TypeDescription::decode(type.description);
  const std::vector<std::uint8_t> bytes =
      horus::zero_message(description, description.message(type.type_name));
  const auto* data = reinterpret_cast<const std::byte*>(bytes.data());
  return std::vector<std::byte>(data, data + bytes.size());
}

}  // namespace horus::remote
