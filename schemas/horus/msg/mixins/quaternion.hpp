// Helpers of horus::msg::Quaternion (fragment: included inside the generated struct body).

/// The quaternion (x, y, z, w), taken as given (not normalised).
static constexpr Quaternion make(double x, double y, double z, double w) noexcept {
  return Quaternion{.x = x, .y = y, .z = z, .w = w};
}

/// No rotation.
static constexpr Quaternion identity() noexcept {
  return Quaternion{.x = 0.0, .y = 0.0, .z = 0.0, .w = 1.0};
}

/// The rotation of `roll` about X, then `pitch` about Y, then `yaw` about Z (radians; the
/// aerospace/ROS convention R = Rz(yaw) * Ry(pitch) * Rx(roll)).
static Quaternion from_euler(double roll, double pitch, double yaw) noexcept {
  const double cr = std::cos(roll / 2.0), sr = std::sin(roll / 2.0);
  const double cp = std::cos(pitch / 2.0), sp = std::sin(pitch / 2.0);
  const double cy = std::cos(yaw / 2.0), sy = std::sin(yaw / 2.0);
  return Quaternion{.x = sr * cp * cy - cr * sp * sy,
                    .y = cr * sp * cy + sr * cp * sy,
                    .z = cr * cp * sy - sr * sp * cy,
                    .w = cr * cp * cy + sr * sp * sy};
}

/// Scales to unit norm. A zero (or non-finite) quaternion is not a rotation and is left
/// unchanged; is_valid() reports a non-finite one.
void normalize() noexcept {
  const double norm = std::sqrt(x * x + y * y + z * z + w * w);
  if (!(norm > 0.0) || !std::isfinite(norm)) return;
  x /= norm;
  y /= norm;
  z /= norm;
  w /= norm;
}

/// True when all four components are finite.
bool is_valid() const noexcept {
  return std::isfinite(x) && std::isfinite(y) && std::isfinite(z) && std::isfinite(w);
}
