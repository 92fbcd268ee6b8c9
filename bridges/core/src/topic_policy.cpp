#include "horus/bridge/topic_policy.hpp"

#include <fnmatch.h>

#include <string>

namespace horus::bridge {

bool glob_matches(std::string_view name, std::string_view pattern) noexcept {
  // fnmatch without FNM_PATHNAME or FNM_PERIOD lets '*' cross '.' and '/' as fnmatchcase does;
  // FNM_NOESCAPE: a backslash is itself, as in Python's globs. Both need NUL-ended strings.
  try {
    const std::string name_text(name);
    const std::string pattern_text(pattern);
    return ::fnmatch(pattern_text.c_str(), name_text.c_str(), FNM_NOESCAPE) == 0;
  } catch (...) {  // out of memory for two short strings: treat as no match
    return false;
  }
}

bool any_matches(std::string_view name, const std::vector<std::string>& patterns) noexcept {
  for (const std::string& pattern : patterns) {
    if (glob_matches(name, pattern)) {
      return true;
    }
  }
  return false;
}

TopicPolicy::TopicPolicy(std::vector<std::string> exports, std::vector<std::string> imports,
                         std::vector<std::string> transient_local,
                         std::vector<std::pair<std::string, std::chrono::milliseconds>> deadlines)
    : exports_(std::move(exports)),
      imports_(std::move(imports)),
      transient_local_(std::move(transient_local)),
      deadlines_(std::move(deadlines)) {}

Claim TopicPolicy::claim(const std::string& name) {
  if (!decided_.insert(name).second) {
    return Claim::Seen;
  }
  return exported(name) && imported(name) ? Claim::BothWays : Claim::New;
}

std::string TopicPolicy::both_ways_refusal(std::string_view name) {
  return "refusing topic '" + std::string(name) +
         "': it matches both --export and --import (a bridge carries a topic one way)";
}

}  // namespace horus::bridge
