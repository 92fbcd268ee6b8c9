// Helpers of horus::msg::Waypoint (fragment: included inside the generated struct body).

/// A waypoint at `pose` with zero velocity and no stop required.
static constexpr Waypoint make(const Pose2D& pose) noexcept {
  Waypoint wp{};
  wp.pose = pose;
  return wp;
}

/// A copy with `desired` velocity at this waypoint.
constexpr Waypoint with_velocity(const Twist& desired) const noexcept {
  Waypoint copy = *this;
  copy.velocity = desired;
  return copy;
}

/// A copy that requires a stop here (stop_required = 1, zero velocity).
constexpr Waypoint with_stop() const noexcept {
  Waypoint copy = *this;
  copy.stop_required = 1;
  copy.velocity = Twist::stop();
  return copy;
}
