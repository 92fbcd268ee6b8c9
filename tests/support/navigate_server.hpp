// The test schema's Navigate server (tests/schemas/test_actions/navigate.haction) as the action
// tests describe it, which the C++ action tests and action_peer run.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <thread>

#include <horus/action.hpp>
#include <horus_test/action/navigate.hpp>

namespace action_test {

using horus_test::action::Navigate;

/// `feedback_count` feedbacks, one every `period_us` (`step` 1..N, `remaining_m` the distance to
/// (x, y) times (N - step) / N), then Succeeded with `feedback_sent` N; Aborted with
/// `abort_with` when it is set; Canceled, with the feedbacks sent so far, when asked to cancel.
inline void drive(horus::ServerGoal<Navigate>& goal) {
  const Navigate::Goal& wanted = goal.goal();
  if (!wanted.abort_with.empty()) {
    goal.abort(wanted.abort_with.str());
    return;
  }
  const double distance = std::hypot(wanted.x, wanted.y);
  const std::uint32_t count = wanted.feedback_count;
  for (std::uint32_t step = 1; step <= count; ++step) {
    std::this_thread::sleep_for(std::chrono::microseconds(wanted.period_us));
    if (goal.is_cancel_requested()) {
      goal.cancel({false, 0.0, 0.0, step - 1});
      return;
    }
    goal.publish_feedback({step, distance * (count - step) / count});
  }
  goal.succeed({true, wanted.x, wanted.y, count});
}

}  // namespace action_test
