// Helpers of horus::msg::PathPlan (fragment: included inside the generated struct body).

/// Appends waypoint (`x` m, `y` m, `theta` rad); false (and unchanged) when full.
[[nodiscard]] constexpr bool add_waypoint(float x, float y, float theta) noexcept {
  if (waypoint_count >= MAX_WAYPOINTS) return false;
  const std::size_t at = std::size_t{waypoint_count} * 3;
  waypoint_data[at] = x;
  waypoint_data[at + 1] = y;
  waypoint_data[at + 2] = theta;
  ++waypoint_count;
  return true;
}

/// Waypoint `index` as {x, y, theta}; empty past the valid waypoints.
constexpr std::optional<std::array<float, 3>> waypoint(std::size_t index) const noexcept {
  if (index >= waypoint_count || index >= MAX_WAYPOINTS) return std::nullopt;
  return std::array<float, 3>{waypoint_data[index * 3], waypoint_data[index * 3 + 1],
                              waypoint_data[index * 3 + 2]};
}

/// True when the plan has no waypoint.
constexpr bool is_empty() const noexcept { return waypoint_count == 0; }
