// horus::TopicMetadata: which topic a node publishes or subscribes to, for monitoring tools.
#pragma once

#include <string>

namespace horus {

/// One topic connection of a node, as its publishers()/subscribers() report it. Generated node
/// code fills it, so it stays a plain aggregate.
struct TopicMetadata {
  std::string topic_name;
  std::string type_name;

  bool operator==(const TopicMetadata&) const = default;
};

}  // namespace horus
