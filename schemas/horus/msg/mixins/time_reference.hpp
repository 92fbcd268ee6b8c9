// Helpers of horus::msg::TimeReference (fragment: included inside the generated struct body).

/// `local_ns` converted to the reference's time (local - offset), saturating at 0 and at the
/// largest u64 instead of wrapping.
constexpr std::uint64_t correct_timestamp(std::uint64_t local_ns) const noexcept {
  if (offset_ns >= 0) {
    const auto offset = static_cast<std::uint64_t>(offset_ns);
    return local_ns > offset ? local_ns - offset : 0;
  }
  // -(offset_ns + 1) + 1 avoids negating INT64_MIN.
  const std::uint64_t behind = static_cast<std::uint64_t>(-(offset_ns + 1)) + 1;
  return local_ns > UINT64_MAX - behind ? UINT64_MAX : local_ns + behind;
}
