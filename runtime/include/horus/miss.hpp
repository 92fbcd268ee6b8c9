// horus::Miss: what the scheduler does when a node's tick ends after its deadline.
#pragma once

#include <cstdint>
#include <string_view>

namespace horus {

enum class Miss : std::uint8_t {
  Warn,      // count it, log it, carry on (default)
  Skip,      // skip the node's next release so it can catch up
  SafeMode,  // call enter_safe_state(); the node is Isolated until is_safe_state() is true
  Stop,      // stop the whole scheduler (last resort)
};

constexpr std::string_view to_string(Miss m) noexcept {
  switch (m) {
    case Miss::Warn:
      return "Warn";
    case Miss::Skip:
      return "Skip";
    case Miss::SafeMode:
      return "SafeMode";
    case Miss::Stop:
      return "Stop";
  }
  return "?";
}

}  // namespace horus
