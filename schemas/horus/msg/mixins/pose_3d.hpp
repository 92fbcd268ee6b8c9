// Helpers of horus::msg::Pose3D (fragment: included inside the generated struct body).

/// The pose at `position` with `orientation`, unstamped.
static constexpr Pose3D make(const Point3& position, const Quaternion& orientation) noexcept {
  return Pose3D{.position = position, .orientation = orientation, .timestamp_ns = 0};
}

/// At the origin, no rotation.
static constexpr Pose3D identity() noexcept { return Pose3D{}; }

/// The 3D pose of a Pose2D (z = 0, yaw-only rotation), keeping its timestamp.
/// A template so that this header need not include pose_2d.hpp.
template <class Pose2DT>
static Pose3D from_pose_2d(const Pose2DT& pose) noexcept {
  const double half = pose.theta / 2.0;
  return Pose3D{.position = {.x = pose.x, .y = pose.y, .z = 0.0},
                .orientation = {.x = 0.0, .y = 0.0, .z = std::sin(half), .w = std::cos(half)},
                .timestamp_ns = pose.timestamp_ns};
}

/// Euclidean distance in metres between the positions (orientations ignored).
double distance_to(const Pose3D& other) const noexcept {
  return position.distance_to(other.position);
}

/// True when the position and orientation are finite.
bool is_valid() const noexcept {
  return std::isfinite(position.x) && std::isfinite(position.y) && std::isfinite(position.z) &&
         orientation.is_valid();
}
