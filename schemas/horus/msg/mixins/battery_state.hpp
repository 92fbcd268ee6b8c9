// Helpers of horus::msg::BatteryState (fragment: included inside the generated struct body).

/// A reading of `voltage` V at `percentage` % with everything not measured marked unknown:
/// charge, capacity and temperature NaN, status STATUS_UNKNOWN, no cells.
static BatteryState make(float voltage, float percentage) noexcept {
  constexpr float unknown = std::numeric_limits<float>::quiet_NaN();
  BatteryState state{};
  state.voltage = voltage;
  state.charge = unknown;
  state.capacity = unknown;
  state.percentage = percentage;
  state.temperature = unknown;
  return state;
}

/// True when the charge is below `threshold_percent` (0-100).
constexpr bool is_low(float threshold_percent) const noexcept {
  return percentage < threshold_percent;
}

/// True below 10 % charge.
constexpr bool is_critical() const noexcept { return percentage < 10.0f; }

/// Time until empty at the present discharge current: charge (Ah) / -current (A). Empty when
/// not discharging (current >= -1e-9 A) or when the charge is unknown (not finite).
std::optional<std::chrono::duration<float>> time_remaining() const noexcept {
  if (!(current < -1e-9f) || !std::isfinite(charge)) return std::nullopt;
  return std::chrono::duration<float>(charge / -current * 3600.0f);
}
