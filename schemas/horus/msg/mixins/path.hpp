// Helpers of horus::msg::Path (fragment: included inside the generated struct body).

/// Appends `waypoint` and adds its distance from the previous one to total_length; false (and
/// unchanged) when the path already holds MAX_WAYPOINTS.
[[nodiscard]] bool add_waypoint(const Waypoint& waypoint) noexcept {
  if (waypoint_count >= MAX_WAYPOINTS) return false;
  waypoints[waypoint_count] = waypoint;
  if (waypoint_count > 0)
    total_length += waypoints[waypoint_count - 1].pose.distance_to(waypoint.pose);
  ++waypoint_count;
  return true;
}

/// The index of the valid waypoint closest to `current` (the first of equals); empty for an
/// empty path.
std::optional<std::size_t> closest_waypoint_index(const Pose2D& current) const noexcept {
  std::optional<std::size_t> best;
  double best_distance = 0.0;
  const std::size_t count = waypoint_count < MAX_WAYPOINTS ? waypoint_count : MAX_WAYPOINTS;
  for (std::size_t i = 0; i < count; ++i) {
    const double d = current.distance_to(waypoints[i].pose);
    if (!best || d < best_distance) {
      best = i;
      best_distance = d;
    }
  }
  return best;
}
