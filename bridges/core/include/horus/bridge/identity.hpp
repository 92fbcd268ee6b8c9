// A topic's HORUS identity as a bridge sees it on both sides: its type's name, the type's
// fingerprint (docs/type-identity.md) and schema text. A bridge carries messages into a local
// topic only when the other side's identity is the local topic's; a mismatch is refused with one
// line naming both, never converted.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace horus::bridge {

struct TopicIdentity {
  std::string type_name;
  std::uint64_t fingerprint = 0;
  std::string schema;

  /// The same type: name and fingerprint (the schema text follows from the fingerprint).
  bool same_type(const TopicIdentity& other) const noexcept {
    return type_name == other.type_name && fingerprint == other.fingerprint;
  }
};

/// A fingerprint as the identity shows it everywhere: 16 lowercase hex digits.
std::string fingerprint_hex(std::uint64_t fingerprint);

/// Why messages of `remote` (carried `carried_as`, e.g. its DDS type name) cannot go into a local
/// topic of `local`, or nothing when they can:
/// `the local topic has type A (fingerprint ...), DDS carries B (fingerprint ...) as X`.
std::optional<std::string> identity_mismatch(const TopicIdentity& local,
                                             const TopicIdentity& remote,
                                             const std::string& remote_side,
                                             const std::string& carried_as);

}  // namespace horus::bridge
