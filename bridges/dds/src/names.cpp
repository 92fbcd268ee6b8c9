#include "horus/dds/names.hpp"

#include <algorithm>
#include <stdexcept>

namespace horus::dds_bridge {
namespace {

std::string replaced(std::string_view text, char from, char to) {
  std::string out(text);
  std::replace(out.begin(), out.end(), from, to);
  return out;
}

// What the runtime accepts for a topic's name: 1 to 200 of [A-Za-z0-9_.-], not "." or "..".
bool horus_name(std::string_view name) {
  if (name.empty() || name.size() > 200 || name == "." || name == "..") {
    return false;
  }
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '.' || c == '-';
  });
}

}  // namespace

std::string dds_topic_name(std::string_view name) {
  if (name.find('-') != std::string_view::npos) {
    throw std::invalid_argument(
        "DDS topic names cannot hold its '-' (DDS and ROS 2 allow letters, digits, '_' and '/' "
        "only, and '_' and '/' already stand for HORUS's '_' and '.')");
  }
  return std::string(kTopicPrefix) + replaced(name, '.', '/');
}

std::string dotted(std::string_view dds_name) {
  return replaced(dds_name.substr(std::min(dds_name.size(), kTopicPrefix.size())), '/', '.');
}

std::string horus_topic_name(std::string_view dds_name) {
  const std::string_view rest = dds_name.substr(std::min(dds_name.size(), kTopicPrefix.size()));
  if (rest.find('.') != std::string_view::npos) {
    throw std::invalid_argument("its '.' makes it ambiguous: " + std::string(dds_name) + " and " +
                                std::string(kTopicPrefix) + replaced(rest, '.', '/') +
                                " would both be the local topic '" + replaced(rest, '/', '.') +
                                "'");
  }
  std::string name = replaced(rest, '/', '.');
  if (!horus_name(name)) {
    throw std::invalid_argument("it would be the local topic '" + name +
                                "', and a HORUS name is 1 to 200 of [A-Za-z0-9_.-] (and not . or "
                                "..)");
  }
  return name;
}

}  // namespace horus::dds_bridge
