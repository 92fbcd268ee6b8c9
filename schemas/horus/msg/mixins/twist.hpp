// Helpers of horus::msg::Twist (fragment: included inside the generated struct body).

/// A twist of `linear` [x, y, z] m/s and `angular` [roll, pitch, yaw] rad/s, unstamped.
static constexpr Twist make(const std::array<double, 3>& linear,
                            const std::array<double, 3>& angular) noexcept {
  return Twist{.linear = linear, .angular = angular, .timestamp_ns = 0};
}

/// The planar twist of a mobile robot: `linear_x` m/s forward, `angular_z` rad/s about +Z.
static constexpr Twist new_2d(double linear_x, double angular_z) noexcept {
  return make({linear_x, 0.0, 0.0}, {0.0, 0.0, angular_z});
}

/// All velocities zero.
static constexpr Twist stop() noexcept { return Twist{}; }

/// True when every velocity component is finite (no NaN, no infinity).
bool is_valid() const noexcept {
  for (double v : linear)
    if (!std::isfinite(v)) return false;
  for (double v : angular)
    if (!std::isfinite(v)) return false;
  return true;
}
