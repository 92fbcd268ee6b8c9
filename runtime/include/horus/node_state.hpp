// NodeState (lifecycle) and NodeHealthState (watchdog and safety health) of a scheduled node.
#pragma once

#include <cstdint>
#include <string_view>

namespace horus {

/// Where a node is in its lifecycle. Error: init() failed or the failure policy gave up on it
/// (the message is in NodeInfo::last_error). Crashed: tick() threw under a Fatal policy.
enum class NodeState : std::uint8_t {
  Uninitialized,
  Initializing,
  Running,
  Stopping,
  Stopped,
  Error,
  Crashed,
};

/// Graduated watchdog health. Warning: a tick ran past 1x the watchdog timeout (still ticks).
/// Unhealthy: past 2x (skipped until it has rested one timeout, then ticked on probation).
/// Isolated: a critical node past 3x, or a Miss::SafeMode miss: enter_safe_state() was called and
/// the node is skipped until is_safe_state() returns true.
enum class NodeHealthState : std::uint8_t {
  Healthy = 0,
  Warning = 1,
  Unhealthy = 2,
  Isolated = 3,
};

constexpr std::string_view to_string(NodeState s) noexcept {
  switch (s) {
    case NodeState::Uninitialized:
      return "Uninitialized";
    case NodeState::Initializing:
      return "Initializing";
    case NodeState::Running:
      return "Running";
    case NodeState::Stopping:
      return "Stopping";
    case NodeState::Stopped:
      return "Stopped";
    case NodeState::Error:
      return "Error";
    case NodeState::Crashed:
      return "Crashed";
  }
  return "?";
}

constexpr std::string_view to_string(NodeHealthState s) noexcept {
  switch (s) {
    case NodeHealthState::Healthy:
      return "Healthy";
    case NodeHealthState::Warning:
      return "Warning";
    case NodeHealthState::Unhealthy:
      return "Unhealthy";
    case NodeHealthState::Isolated:
      return "Isolated";
  }
  return "?";
}

}  // namespace horus
