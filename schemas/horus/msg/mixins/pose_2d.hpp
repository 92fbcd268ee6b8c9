// Helpers of horus::msg::Pose2D (fragment: included inside the generated struct body).

/// The pose (`x` m, `y` m, `theta` rad), unstamped.
static constexpr Pose2D make(double x, double y, double theta) noexcept {
  return Pose2D{.x = x, .y = y, .theta = theta, .timestamp_ns = 0};
}

/// The pose at the origin, heading along +X.
static constexpr Pose2D origin() noexcept { return Pose2D{}; }

/// Euclidean distance in metres between the two positions (headings ignored).
double distance_to(const Pose2D& other) const noexcept {
  return std::hypot(x - other.x, y - other.y);
}

/// Wraps theta into [-pi, pi] (IEEE remainder by 2*pi: exact, and the same in C++ and Python).
/// A non-finite theta is left as it is: there is no angle to wrap, and is_valid() reports it.
void normalize_angle() noexcept {
  if (std::isfinite(theta)) theta = std::remainder(theta, 2.0 * 3.14159265358979323846);
}

/// True when x, y and theta are all finite.
bool is_valid() const noexcept {
  return std::isfinite(x) && std::isfinite(y) && std::isfinite(theta);
}
