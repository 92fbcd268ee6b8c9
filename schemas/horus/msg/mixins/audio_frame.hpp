// Helpers of horus::msg::AudioFrame (fragment: included inside the generated struct body).

/// Frames (samples per channel); 0 without channels.
constexpr std::uint32_t frame_count() const noexcept {
  return channels == 0 ? 0 : valid_samples() / channels;
}

/// Duration of the valid samples in milliseconds; 0 without a sample rate or channels.
constexpr double duration_ms() const noexcept {
  if (sample_rate == 0 || channels == 0) return 0.0;
  return static_cast<double>(valid_samples()) / channels / sample_rate * 1000.0;
}

/// num_samples, capped at MAX_SAMPLES (a corrupt count must not read past the buffer).
constexpr std::uint32_t valid_samples() const noexcept {
  return num_samples < MAX_SAMPLES ? num_samples : MAX_SAMPLES;
}
