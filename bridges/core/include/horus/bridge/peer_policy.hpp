// What each peer of a bridge may do, by the name it is known by (the remote link's peer
// certificate, a live view's token): lines "PEER read|write|call|param PATTERN" (globs as every
// bridge reads them, topic_policy.hpp: Python's fnmatchcase, '*' also crosses '.', a backslash is
// itself), from options and policy files. Everything not allowed is denied.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace horus::bridge {

/// What a peer asks to do with a name: read a topic, write a topic, call a service, or read and
/// write a parameter (the name "NODE.PARAMETER", so "motor.*" is every parameter of node motor).
enum class Access { Read, Write, Call, Param };

class PeerPolicy {
 public:
  /// Adds one rule; throws std::invalid_argument naming `where` (the option or file:line) when
  /// the line is not "PEER read|write|call|param PATTERN".
  void add(std::string_view line, const std::string& where);
  /// Adds the rules of a file: one a line, blank lines and lines starting with # skipped.
  void load(const std::string& path);

  /// Whether there is no rule at all: every peer is refused.
  bool empty() const noexcept { return rules_.empty(); }
  /// Whether any rule names `peer`: a peer no rule names is refused at the door.
  bool knows(const std::string& peer) const;
  bool allows(const std::string& peer, Access access, const std::string& name) const;

 private:
  struct Rule {
    std::string peer;
    Access access;
    std::string pattern;
  };
  std::vector<Rule> rules_;
};

}  // namespace horus::bridge
