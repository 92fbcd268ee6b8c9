// Helpers of horus::msg::BoundingBox2D (fragment: included inside the generated struct body).

/// Area in square pixels (0 for a degenerate box).
constexpr float area() const noexcept {
  return width > 0.0f && height > 0.0f ? width * height : 0.0f;
}

/// Intersection over union with `other`, 0-1; 0 when the union is empty.
constexpr float iou(const BoundingBox2D& other) const noexcept {
  const float left = std::max(x, other.x), top = std::max(y, other.y);
  const float right = std::min(x + width, other.x + other.width);
  const float bottom = std::min(y + height, other.y + other.height);
  const float inter = right > left && bottom > top ? (right - left) * (bottom - top) : 0.0f;
  const float uni = area() + other.area() - inter;
  return uni > 0.0f ? inter / uni : 0.0f;
}
