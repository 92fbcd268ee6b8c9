// Helpers of horus::msg::Vector3 (fragment: included inside the generated struct body).

/// The vector (x, y, z).
static constexpr Vector3 make(double x, double y, double z) noexcept {
  return Vector3{.x = x, .y = y, .z = z};
}

/// The zero vector.
static constexpr Vector3 zero() noexcept { return Vector3{}; }

/// Euclidean length.
double magnitude() const noexcept { return std::sqrt(x * x + y * y + z * z); }

/// Scales to unit length; the zero vector (which has no direction) is left unchanged.
void normalize() noexcept {
  const double m = magnitude();
  if (!(m > 0.0)) return;
  x /= m;
  y /= m;
  z /= m;
}

/// A unit-length copy; the zero vector for the zero vector.
Vector3 normalized() const noexcept {
  Vector3 copy = *this;
  copy.normalize();
  return copy;
}

/// Dot product.
constexpr double dot(const Vector3& other) const noexcept {
  return x * other.x + y * other.y + z * other.z;
}

/// Cross product (right-handed): this x other.
constexpr Vector3 cross(const Vector3& other) const noexcept {
  return Vector3{.x = y * other.z - z * other.y,
                 .y = z * other.x - x * other.z,
                 .z = x * other.y - y * other.x};
}
