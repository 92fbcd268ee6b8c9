// Helpers of horus::msg::Odometry (fragment: included inside the generated struct body).

/// At the origin, not moving, no frames, zero covariances (the same as Odometry{}).
static constexpr Odometry make() noexcept { return Odometry{}; }

/// Names the pose frame (e.g. "odom") and the twist frame (e.g. "base_link"). Throws
/// horus::Error, changing nothing, when a name is longer than 32 bytes: a truncated frame name
/// would silently refer to another frame.
void set_frames(std::string_view frame, std::string_view child_frame) {
  if (frame.size() > frame_id.capacity() || child_frame.size() > child_frame_id.capacity()) {
    throw horus::Error("Odometry::set_frames: frame names are at most 32 bytes, got '" +
                       std::string(frame) + "' and '" + std::string(child_frame) + "'");
  }
  frame_id.assign(frame);
  child_frame_id.assign(child_frame);
}

/// Takes a new estimate; the message is stamped with the later of the two inputs' stamps.
void update(const Pose2D& new_pose, const Twist& new_twist) noexcept {
  pose = new_pose;
  twist = new_twist;
  timestamp_ns = new_pose.timestamp_ns > new_twist.timestamp_ns ? new_pose.timestamp_ns
                                                                : new_twist.timestamp_ns;
}

/// True when the pose and the twist are finite.
bool is_valid() const noexcept { return pose.is_valid() && twist.is_valid(); }
