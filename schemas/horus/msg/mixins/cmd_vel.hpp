// Helpers of horus::msg::CmdVel (fragment: included inside the generated struct body).

/// A command of `linear` m/s forward and `angular` rad/s, unstamped (stamp_nanos = 0).
static constexpr CmdVel make(float linear, float angular) noexcept {
  return CmdVel{.stamp_nanos = 0, .linear = linear, .angular = angular};
}

/// The stop command: zero velocities, unstamped.
static constexpr CmdVel zero() noexcept { return CmdVel{}; }

/// A command stamped with `stamp_nanos` (nanoseconds since epoch).
static constexpr CmdVel with_timestamp(float linear, float angular,
                                       std::uint64_t stamp_nanos) noexcept {
  return CmdVel{.stamp_nanos = stamp_nanos, .linear = linear, .angular = angular};
}
