// Helpers of horus::msg::JointState (fragment: included inside the generated struct body).

/// Appends a joint; false (and unchanged) when all MAX_JOINTS slots are used. Throws
/// horus::Error when `name` is longer than 32 bytes (a truncated name could match another joint).
bool add_joint(std::string_view name, double position, double velocity, double effort) {
  if (joint_count >= MAX_JOINTS) return false;
  if (!names[joint_count].try_assign(name)) {
    throw horus::Error("JointState::add_joint: joint name '" + std::string(name) +
                       "' is longer than 32 bytes");
  }
  positions[joint_count] = position;
  velocities[joint_count] = velocity;
  efforts[joint_count] = effort;
  ++joint_count;
  return true;
}

/// The index of joint `name` among the first joint_count joints; empty when absent.
std::optional<std::size_t> index_of(std::string_view name) const noexcept {
  const std::size_t count = joint_count < MAX_JOINTS ? joint_count : MAX_JOINTS;
  for (std::size_t i = 0; i < count; ++i)
    if (names[i].view() == name) return i;
  return std::nullopt;
}

/// The position of joint `name`; empty when absent.
std::optional<double> position_of(std::string_view name) const noexcept {
  const auto i = index_of(name);
  return i ? std::optional<double>(positions[*i]) : std::nullopt;
}
