// The texts of goal ids, goal states, cancel answers and policies (horus/action_type.hpp).
#include "horus/action_type.hpp"

namespace horus {

std::string GoalId::to_string() const {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string text;
  text.reserve(32);
  for (const std::uint8_t byte : to_bytes()) {
    text += kDigits[byte >> 4];
    text += kDigits[byte & 0xf];
  }
  return text;
}

std::string_view to_string(GoalState state) noexcept {
  switch (state) {
    case GoalState::Unknown:
      return "unknown";
    case GoalState::Accepted:
      return "accepted";
    case GoalState::Executing:
      return "executing";
    case GoalState::Canceling:
      return "canceling";
    case GoalState::Succeeded:
      return "succeeded";
    case GoalState::Canceled:
      return "canceled";
    case GoalState::Aborted:
      return "aborted";
    case GoalState::Rejected:
      return "rejected";
  }
  return "invalid";
}

std::string_view to_string(CancelCode code) noexcept {
  switch (code) {
    case CancelCode::Accepted:
      return "accepted";
    case CancelCode::Rejected:
      return "rejected";
    case CancelCode::UnknownGoal:
      return "unknown goal";
    case CancelCode::AlreadyDone:
      return "already done";
  }
  return "invalid";
}

std::string_view to_string(ActionPolicy policy) noexcept {
  switch (policy) {
    case ActionPolicy::Reject:
      return "reject";
    case ActionPolicy::Preempt:
      return "preempt";
    case ActionPolicy::Queue:
      return "queue";
  }
  return "invalid";
}

}  // namespace horus
