// What the action server and client share about the wire: goal ids and texts in generated
// messages, stamps, the client's wait on its three topics, and the fixed texts of the protocol.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "horus/action_type.hpp"

namespace horus::detail {

/// The goal id of a generated message's `goal_id: [u8; 16]`.
template <class M>
GoalId goal_id_of(const M& message) noexcept {
  return GoalId::from_bytes(std::span<const std::uint8_t, 16>(message.goal_id.data(), 16));
}

template <class M>
void set_goal_id(M& message, const GoalId& id) noexcept {
  const GoalId::Bytes bytes = id.to_bytes();
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    message.goal_id[i] = bytes[i];
  }
}

/// `text` cut at a character boundary to what `field` holds (a string<N> or a String).
template <class Field>
void set_text(Field& field, std::string_view text) {
  if constexpr (requires { Field::capacity(); }) {
    std::size_t length = std::min(text.size(), Field::capacity());
    // Never end inside a UTF-8 sequence: back up over continuation bytes.
    while (length < text.size() && length > 0 &&
           (static_cast<unsigned char>(text[length]) & 0xC0) == 0x80) {
      --length;
    }
    field.try_assign(text.substr(0, length));
  } else {
    field = std::string(text);
  }
}

template <class Field>
std::string text_of(const Field& field) {
  return std::string(std::string_view(field));
}

/// Stamps of goals' answers and statuses: the system clock, in nanoseconds since the epoch.
inline std::uint64_t action_stamp_ns() noexcept {
  return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                        std::chrono::system_clock::now().time_since_epoch())
                                        .count());
}

/// The texts both ends write, in one place (runtime/src/action/README.md lists them).
std::string busy_reason(const GoalId& executing);
std::string preempted_reason(const GoalId& newer);
std::string queue_full_reason(std::size_t waiting);
std::string client_exited_reason(std::uint64_t pid);
std::string server_exited_reason(std::uint64_t pid);
inline constexpr std::string_view kServerStoppedReason = "the action server stopped";
inline constexpr std::string_view kServerRestartedReason = "the action server restarted";
inline constexpr std::string_view kClientClosedReason = "the action client closed";
inline constexpr std::string_view kGoalDroppedReason = "the goal was dropped without an outcome";
inline constexpr std::string_view kExecuteReturnedReason = "on_execute returned without an outcome";
inline constexpr std::string_view kCanceledByClientReason = "canceled by a client";
inline constexpr std::string_view kUnknownGoalReason = "no such goal on this server";

/// How many ended goals a server keeps for get_result, and feedback messages a handle keeps.
inline constexpr std::size_t kEndedGoalsKept = 64;
inline constexpr std::size_t kFeedbackKept = 64;
/// How often the server looks for goals whose clients' processes exited.
inline constexpr std::chrono::milliseconds kClientCheckInterval{50};
/// How long a server's service threads sleep in one wait (stop() wakes them at once).
inline constexpr std::chrono::milliseconds kServeSlice{50};
/// The client's pump: its wait while a goal is live (the server check's interval, too), and idle.
inline constexpr std::chrono::milliseconds kPumpLiveSlice{10};
inline constexpr std::chrono::milliseconds kPumpIdleSlice{250};
/// How long a closing client waits for each cancel of its live goals.
inline constexpr std::chrono::milliseconds kCloseCancelTimeout{100};

/// The action client's sleep on its three topics: one futex_waitv over their control words.
class ActionTopicWait {
 public:
  /// Throws horus::Error for an invalid name or a corrupt segment.
  ActionTopicWait(const std::vector<std::string>& topic_names, std::string_view namespace_name);
  ~ActionTopicWait();
  ActionTopicWait(const ActionTopicWait&) = delete;
  ActionTopicWait& operator=(const ActionTopicWait&) = delete;

  /// Until a message arrives on one of the topics, `timeout` passes or interrupt() is called.
  void wait(std::chrono::nanoseconds timeout) noexcept;
  void interrupt() noexcept;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace horus::detail
