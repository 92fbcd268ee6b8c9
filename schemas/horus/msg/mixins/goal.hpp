// Helpers of horus::msg::Goal (fragment: included inside the generated struct body).

/// A goal at `target` reached within `position_tolerance` metres and `angle_tolerance`
/// radians; no timeout, normal priority (1), goal_id 0, unstamped.
static constexpr Goal make(const Pose2D& target, double position_tolerance,
                           double angle_tolerance) noexcept {
  return Goal{.target_pose = target,
              .tolerance_position = position_tolerance,
              .tolerance_angle = angle_tolerance,
              .timeout_seconds = 0.0,
              .priority = 1,
              .goal_id = 0,
              .timestamp_ns = 0};
}

/// A copy with `timeout` to reach the goal (zero: no limit).
constexpr Goal with_timeout(std::chrono::duration<double> timeout) const noexcept {
  Goal copy = *this;
  copy.timeout_seconds = timeout.count();
  return copy;
}

/// A copy with `new_priority` (0 = highest).
constexpr Goal with_priority(std::uint8_t new_priority) const noexcept {
  Goal copy = *this;
  copy.priority = new_priority;
  return copy;
}

/// True when `current` is within tolerance_position metres of the target.
bool is_position_reached(const Pose2D& current) const noexcept {
  return target_pose.distance_to(current) <= tolerance_position;
}

/// True when the heading of `current` is within tolerance_angle of the target's, measured the
/// short way round (so 3.1 and -3.1 rad are 0.08 rad apart), whatever multiple of 2*pi apart.
bool is_orientation_reached(const Pose2D& current) const noexcept {
  const double diff =
      std::remainder(target_pose.theta - current.theta, 2.0 * 3.14159265358979323846);
  return std::fabs(diff) <= tolerance_angle;
}

/// True when both position and orientation are within tolerance.
bool is_reached(const Pose2D& current) const noexcept {
  return is_position_reached(current) && is_orientation_reached(current);
}
