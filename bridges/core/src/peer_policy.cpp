#include "horus/bridge/peer_policy.hpp"

#include "horus/bridge/topic_policy.hpp"

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace horus::bridge {

void PeerPolicy::add(std::string_view line, const std::string& where) {
  std::istringstream words{std::string(line)};
  std::string peer;
  std::string access;
  std::string pattern;
  std::string extra;
  words >> peer >> access >> pattern;
  if (pattern.empty() || (words >> extra)) {
    throw std::invalid_argument(where + ": '" + std::string(line) +
                                "' is not 'PEER read|write|call|param PATTERN'");
  }
  Access kind = Access::Read;
  if (access == "read") {
    kind = Access::Read;
  } else if (access == "write") {
    kind = Access::Write;
  } else if (access == "call") {
    kind = Access::Call;
  } else if (access == "param") {
    kind = Access::Param;
  } else {
    throw std::invalid_argument(where + ": '" + access + "' is not read, write, call or param");
  }
  rules_.push_back(Rule{peer, kind, pattern});
}

void PeerPolicy::load(const std::string& path) {
  std::ifstream file(path);
  if (!file) {
    throw std::invalid_argument("cannot read the policy file " + path);
  }
  std::string line;
  for (int number = 1; std::getline(file, line); ++number) {
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') {
      continue;
    }
    add(line, path + ":" + std::to_string(number));
  }
}

bool PeerPolicy::knows(const std::string& peer) const {
  return std::any_of(rules_.begin(), rules_.end(),
                     [&](const Rule& rule) { return glob_matches(peer, rule.peer); });
}

bool PeerPolicy::allows(const std::string& peer, Access access, const std::string& name) const {
  return std::any_of(rules_.begin(), rules_.end(), [&](const Rule& rule) {
    return rule.access == access && glob_matches(peer, rule.peer) &&
           glob_matches(name, rule.pattern);
  });
}

}  // namespace horus::bridge
