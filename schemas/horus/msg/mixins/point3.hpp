// Helpers of horus::msg::Point3 (fragment: included inside the generated struct body).

/// The point (x, y, z) in metres.
static constexpr Point3 make(double x, double y, double z) noexcept {
  return Point3{.x = x, .y = y, .z = z};
}

/// The origin.
static constexpr Point3 origin() noexcept { return Point3{}; }

/// Euclidean distance in metres.
double distance_to(const Point3& other) const noexcept {
  return std::sqrt((x - other.x) * (x - other.x) + (y - other.y) * (y - other.y) +
                   (z - other.z) * (z - other.z));
}
