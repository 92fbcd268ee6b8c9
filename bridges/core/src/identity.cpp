#include "horus/bridge/identity.hpp"

#include <cstdio>

namespace horus::bridge {

std::string fingerprint_hex(std::uint64_t fingerprint) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(fingerprint));
  return text;
}

std::optional<std::string> identity_mismatch(const TopicIdentity& local,
                                             const TopicIdentity& remote,
                                             const std::string& remote_side,
                                             const std::string& carried_as) {
  if (local.same_type(remote)) {
    return std::nullopt;
  }
  return "the local topic has type " + local.type_name + " (fingerprint " +
         fingerprint_hex(local.fingerprint) + "), " + remote_side + " carries " + remote.type_name +
         " (fingerprint " + fingerprint_hex(remote.fingerprint) + ") as " + carried_as;
}

}  // namespace horus::bridge
