// Helpers of horus::msg::TransformStamped (fragment: included inside the generated struct body).

/// The transform of `translation` [x, y, z] m and `rotation` quaternion [x, y, z, w], unstamped.
static constexpr TransformStamped make(const std::array<double, 3>& translation,
                                       const std::array<double, 4>& rotation) noexcept {
  return TransformStamped{.translation = translation, .rotation = rotation, .timestamp_ns = 0};
}

/// No translation, identity rotation.
static constexpr TransformStamped identity() noexcept {
  return make({0.0, 0.0, 0.0}, {0.0, 0.0, 0.0, 1.0});
}

/// The planar transform of a Pose2D (z = 0, yaw-only rotation), keeping its timestamp.
/// A template so that this header need not include pose_2d.hpp.
template <class Pose2DT>
static TransformStamped from_pose_2d(const Pose2DT& pose) noexcept {
  const double half = pose.theta / 2.0;
  return TransformStamped{.translation = {pose.x, pose.y, 0.0},
                          .rotation = {0.0, 0.0, std::sin(half), std::cos(half)},
                          .timestamp_ns = pose.timestamp_ns};
}

/// Scales the rotation to unit length. A zero (or non-finite) quaternion has no direction to
/// keep and is left unchanged; is_valid() reports it.
void normalize_rotation() noexcept {
  const double norm = std::sqrt(rotation[0] * rotation[0] + rotation[1] * rotation[1] +
                                rotation[2] * rotation[2] + rotation[3] * rotation[3]);
  if (!(norm > 0.0) || !std::isfinite(norm)) return;
  for (double& v : rotation) v /= norm;
}

/// True when every value is finite and the rotation has unit norm (within 0.01).
bool is_valid() const noexcept {
  for (double v : translation)
    if (!std::isfinite(v)) return false;
  double sum = 0.0;
  for (double v : rotation) {
    if (!std::isfinite(v)) return false;
    sum += v * v;
  }
  return std::fabs(std::sqrt(sum) - 1.0) < 0.01;
}
