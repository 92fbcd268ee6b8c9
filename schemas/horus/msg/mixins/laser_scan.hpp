// Helpers of horus::msg::LaserScan (fragment: included inside the generated struct body).
// A reading is valid when it is finite and within [range_min, range_max]; a zero reading is
// invalid whenever range_min > 0 (the default 0.1 m).

/// The angle in radians of reading `index`: angle_min + index * angle_increment (f32
/// arithmetic); NaN for an index past the 360 readings (there is no such reading).
float angle_at(std::size_t index) const noexcept {
  if (index >= ranges.size()) return std::numeric_limits<float>::quiet_NaN();
  return angle_min + static_cast<float>(index) * angle_increment;
}

/// True when reading `index` exists and is valid.
bool is_range_valid(std::size_t index) const noexcept {
  return index < ranges.size() && reading_is_valid(ranges[index]);
}

/// The number of valid readings.
std::size_t valid_count() const noexcept {
  std::size_t count = 0;
  for (float r : ranges)
    if (reading_is_valid(r)) ++count;
  return count;
}

/// The closest valid reading in metres; empty when no reading is valid (an empty scan).
std::optional<float> min_range() const noexcept {
  std::optional<float> closest;
  for (float r : ranges)
    if (reading_is_valid(r) && (!closest || r < *closest)) closest = r;
  return closest;
}

/// The validity rule shared by the helpers above.
bool reading_is_valid(float r) const noexcept {
  return std::isfinite(r) && r >= range_min && r <= range_max;
}
