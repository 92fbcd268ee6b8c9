// Helpers of horus::msg::GoalResult (fragment: included inside the generated struct body).

/// The result of goal `id` with `status` (a GoalStatus; a template because the field is a u8 of
/// the original layout, so this header does not include goal_status.hpp).
template <class GoalStatusT>
static constexpr GoalResult make(std::uint32_t id, GoalStatusT status) noexcept {
  GoalResult result{};
  result.goal_id = id;
  result.status = static_cast<std::uint8_t>(status);
  return result;
}

/// A copy with `message` as error_message. A human-readable message, not an identifier, so a
/// long one is cut to the 64 bytes that fit, at a UTF-8 character boundary (never mid-character).
GoalResult with_error(std::string_view message) const noexcept {
  std::size_t n =
      message.size() < error_message.capacity() ? message.size() : error_message.capacity();
  while (n > 0 && n < message.size() && (static_cast<unsigned char>(message[n]) & 0xC0) == 0x80) {
    --n;
  }
  GoalResult copy = *this;
  copy.error_message.try_assign(message.substr(0, n));
  return copy;
}
