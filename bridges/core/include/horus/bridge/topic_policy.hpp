// Which topics a bridge carries, and how: the names and patterns every bridge (DDS, remote, a
// live view) is given. A pattern is a glob over the HORUS topic name, as Python's
// fnmatch.fnmatchcase reads it (`*`, `?`, `[seq]`, `[!seq]`; '*' also crosses '.'), so
// `horus bridge --export 'arm.*'` and `horus.Network(export=["arm.*"])` mean the same.
// Nothing is carried that no pattern names; a name both directions match is refused (a bridge
// carries a topic one way, so nothing it writes comes back to it); for per-topic settings the
// first matching pattern counts.
#pragma once

#include <chrono>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace horus::bridge {

/// Whether `name` matches the glob `pattern` (case-sensitive, no escapes, '*' crosses '.').
bool glob_matches(std::string_view name, std::string_view pattern) noexcept;

/// Whether any of `patterns` matches `name`.
bool any_matches(std::string_view name, const std::vector<std::string>& patterns) noexcept;

/// A per-topic setting given as (pattern, value) pairs: the value of the first pattern that
/// matches a name.
template <typename Value>
std::optional<Value> first_match(std::string_view name,
                                 const std::vector<std::pair<std::string, Value>>& rules) {
  for (const auto& [pattern, value] : rules) {
    if (glob_matches(name, pattern)) {
      return value;
    }
  }
  return std::nullopt;
}

/// What a bridge decides for a topic name it has met.
enum class Claim {
  New,       // carry it (the first time the name is met)
  Seen,      // carried or refused already: nothing to do
  BothWays,  // matched by an export and an import pattern: refused (say so once)
};

/// The topic patterns of a bridge, and the names it has carried or refused (each decided once).
class TopicPolicy {
 public:
  TopicPolicy(std::vector<std::string> exports, std::vector<std::string> imports,
              std::vector<std::string> transient_local = {},
              std::vector<std::pair<std::string, std::chrono::milliseconds>> deadlines = {});

  bool exported(std::string_view name) const noexcept { return any_matches(name, exports_); }
  bool imported(std::string_view name) const noexcept { return any_matches(name, imports_); }
  /// Whether `name` is latched (transient-local) by a pattern of the bridge's own.
  bool transient_local(std::string_view name) const noexcept {
    return any_matches(name, transient_local_);
  }
  /// The deadline of the first deadline pattern that matches `name`, if any.
  std::optional<std::chrono::milliseconds> deadline(std::string_view name) const {
    return first_match(name, deadlines_);
  }

  /// Decides `name` once: New the first time (and never again), BothWays the first time when
  /// both directions match it, Seen after.
  Claim claim(const std::string& name);
  /// Marks `name` decided without carrying it (refused for another reason, said by the caller).
  void settle(const std::string& name) { decided_.insert(name); }
  bool decided(const std::string& name) const { return decided_.contains(name); }
  /// The line saying a name was refused for BothWays.
  static std::string both_ways_refusal(std::string_view name);

 private:
  std::vector<std::string> exports_;
  std::vector<std::string> imports_;
  std::vector<std::string> transient_local_;
  std::vector<std::pair<std::string, std::chrono::milliseconds>> deadlines_;
  std::set<std::string, std::less<>> decided_;
};

}  // namespace horus::bridge
