// Helpers of horus::msg::Imu (fragment: included inside the generated struct body).

/// An IMU message without orientation: identity quaternion, orientation_covariance all -1
/// (the ROS "no estimate" marker), everything else zero.
static constexpr Imu make() noexcept {
  Imu imu{};
  imu.orientation = {0.0, 0.0, 0.0, 1.0};
  for (double& c : imu.orientation_covariance) c = -1.0;
  return imu;
}

/// Sets the orientation from roll (X), pitch (Y), yaw (Z) in radians, like
/// Quaternion::from_euler. Having an orientation now, a covariance still marked "no estimate"
/// (element 0 < 0) becomes all zeros ("covariance unknown"), so has_orientation() is true.
void set_orientation_from_euler(double roll, double pitch, double yaw) noexcept {
  const double cr = std::cos(roll / 2.0), sr = std::sin(roll / 2.0);
  const double cp = std::cos(pitch / 2.0), sp = std::sin(pitch / 2.0);
  const double cy = std::cos(yaw / 2.0), sy = std::sin(yaw / 2.0);
  orientation = {sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                 cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy};
  if (orientation_covariance[0] < 0.0) orientation_covariance.fill(0.0);
}

/// True unless orientation_covariance[0] < 0 marks the orientation as absent.
bool has_orientation() const noexcept { return orientation_covariance[0] >= 0.0; }

/// True when orientation, angular velocity and linear acceleration are all finite.
bool is_valid() const noexcept {
  for (double v : orientation)
    if (!std::isfinite(v)) return false;
  for (double v : angular_velocity)
    if (!std::isfinite(v)) return false;
  for (double v : linear_acceleration)
    if (!std::isfinite(v)) return false;
  return true;
}
