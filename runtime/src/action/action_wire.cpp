// The action wire's shared pieces (horus/detail/action_wire.hpp): the protocol's texts and the
// client's wait on its topics.
#include "horus/detail/action_wire.hpp"

#include "horus/internal/topic_wait_set.hpp"

namespace horus::detail {

std::string busy_reason(const GoalId& executing) {
  return "busy: goal " + executing.to_string() + " is executing";
}

std::string preempted_reason(const GoalId& newer) {
  return "preempted by goal " + newer.to_string();
}

std::string queue_full_reason(std::size_t waiting) {
  return "queue full (" + std::to_string(waiting) + " goals waiting)";
}

std::string client_exited_reason(std::uint64_t pid) {
  return "the client (pid " + std::to_string(pid) + ") exited";
}

std::string server_exited_reason(std::uint64_t pid) {
  return "the action server (pid " + std::to_string(pid) + ") exited mid-goal";
}

struct ActionTopicWait::State {
  State(const std::vector<std::string>& names, std::string_view namespace_name)
      : topics(names, namespace_name) {}
  TopicWaitSet topics;
};

ActionTopicWait::ActionTopicWait(const std::vector<std::string>& topic_names,
                                 std::string_view namespace_name)
    : state_(std::make_unique<State>(topic_names, namespace_name)) {}

ActionTopicWait::~ActionTopicWait() = default;

void ActionTopicWait::wait(std::chrono::nanoseconds timeout) noexcept {
  // The client drains all three topics after any wake, so which one woke it does not matter.
  static_cast<void>(state_->topics.wait(timeout));
}

void ActionTopicWait::interrupt() noexcept { state_->topics.interrupt(); }

}  // namespace horus::detail
