// Helpers of horus::msg::Range (fragment: included inside the generated struct body).

/// A reading of `range` metres from a sensor of `sensor_type` (ULTRASONIC or INFRARED) with
/// typical limits: 0.1 rad field of view, 0.02-4.0 m; adjust them for the actual sensor.
static constexpr Range make(std::uint8_t sensor_type, float range) noexcept {
  return Range{.sensor_type = sensor_type,
               .field_of_view = 0.1f,
               .min_range = 0.02f,
               .max_range = 4.0f,
               .range = range,
               .timestamp_ns = 0};
}

/// True when the reading is finite and within [min_range, max_range].
bool is_valid() const noexcept {
  return std::isfinite(range) && range >= min_range && range <= max_range;
}
