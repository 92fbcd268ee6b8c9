// horus::Action: what horus-gen generates for an action of a `.haction` file, and the values
// every action shares: goal ids, goal states, cancel answers and the server's goal policies.
// The wire (three services and three topics per action): runtime/src/action/README.md.
#pragma once

#include <array>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>

#include "horus/service_type.hpp"
#include "horus/type_info.hpp"

namespace horus {

/// A generated action: its three blocks, the three services that carry goals, cancels and
/// results, and the three messages of its topics (feedback, status, result).
template <class A>
concept Action =
    Message<typename A::Goal> && Message<typename A::Result> && Message<typename A::Feedback> &&
    Service<typename A::SendGoal> && Service<typename A::CancelGoal> &&
    Service<typename A::GetResult> && Message<typename A::FeedbackMessage> &&
    Message<typename A::Status> && Message<typename A::ResultMessage> && requires {
  { A::name() } -> std::convertible_to<std::string_view>;
  { A::type_name() } -> std::convertible_to<std::string_view>;
  { A::feedback_topic() } -> std::convertible_to<std::string_view>;
  { A::status_topic() } -> std::convertible_to<std::string_view>;
  { A::result_topic() } -> std::convertible_to<std::string_view>;
  { A::fingerprint() } -> std::convertible_to<std::uint64_t>;
};

/// A goal's id: the sending client's id (its send_goal ServiceClient's, pid << 32 | n) and a
/// count from 1, so ids are unique among live processes without randomness. On the wire it is
/// the 16 bytes of ROS 2's goal UUID, each half little-endian. All zero names every goal (in a
/// cancel only).
struct GoalId {
  std::uint64_t client_id = 0;
  std::uint64_t sequence = 0;

  using Bytes = std::array<std::uint8_t, 16>;

  Bytes to_bytes() const noexcept {
    Bytes bytes{};
    for (std::size_t i = 0; i < 8; ++i) {
      bytes[i] = static_cast<std::uint8_t>(client_id >> (8 * i));
      bytes[8 + i] = static_cast<std::uint8_t>(sequence >> (8 * i));
    }
    return bytes;
  }
  static GoalId from_bytes(std::span<const std::uint8_t, 16> bytes) noexcept {
    GoalId id;
    for (std::size_t i = 0; i < 8; ++i) {
      id.client_id |= std::uint64_t{bytes[i]} << (8 * i);
      id.sequence |= std::uint64_t{bytes[8 + i]} << (8 * i);
    }
    return id;
  }
  /// The 32 lowercase hex digits of the wire bytes, in their order.
  std::string to_string() const;
  /// The all-zero id: every live goal, in a cancel.
  bool is_all() const noexcept { return client_id == 0 && sequence == 0; }

  bool operator==(const GoalId&) const = default;
};

/// Where a goal is. 0-6 are ROS 2's action_msgs/GoalStatus values; Rejected is HORUS's own
/// (ROS answers a refused goal with accepted = false only) and never goes to ROS.
/// Accepted -> Executing | Canceled | Aborted; Executing -> Canceling | Succeeded | Aborted;
/// Canceling -> Canceled | Succeeded | Aborted. Succeeded and after are terminal.
enum class GoalState : std::uint8_t {
  Unknown = 0,
  Accepted = 1,
  Executing = 2,
  Canceling = 3,
  Succeeded = 4,
  Canceled = 5,
  Aborted = 6,
  Rejected = 7,
};

constexpr bool is_terminal(GoalState state) noexcept {
  return static_cast<std::uint8_t>(state) >= static_cast<std::uint8_t>(GoalState::Succeeded) &&
         static_cast<std::uint8_t>(state) <= static_cast<std::uint8_t>(GoalState::Rejected);
}

/// "unknown", "accepted", "executing", "canceling", "succeeded", "canceled", "aborted",
/// "rejected" ("invalid" for a value outside the enum, as from a foreign peer).
std::string_view to_string(GoalState state) noexcept;

/// A cancel's answer: ROS 2's CancelGoal return codes.
enum class CancelCode : std::uint8_t {
  /// The goals are canceling (or were canceled at once, having not started).
  Accepted = 0,
  /// The server's on_cancel refused.
  Rejected = 1,
  UnknownGoal = 2,
  /// The goal had already ended.
  AlreadyDone = 3,
};

/// "accepted", "rejected", "unknown goal", "already done".
std::string_view to_string(CancelCode code) noexcept;

/// What a server does with a goal that arrives while another executes (one executes at a time).
enum class ActionPolicy : std::uint8_t {
  /// Refuses it: `busy: goal <id> is executing`.
  Reject,
  /// Accepts it and asks the executing goal to cancel (`preempted by goal <id>`); a goal still
  /// waiting is canceled with that reason. The new goal starts when the old one has ended.
  Preempt,
  /// Queues it (first in, first out) behind at most queue_capacity() waiting goals; beyond them:
  /// `queue full (<n> goals waiting)`.
  Queue,
};

std::string_view to_string(ActionPolicy policy) noexcept;

}  // namespace horus

template <>
struct std::hash<horus::GoalId> {
  std::size_t operator()(const horus::GoalId& id) const noexcept {
    return std::hash<std::uint64_t>{}(id.client_id * 0x9e3779b97f4a7c15ULL ^ id.sequence);
  }
};
