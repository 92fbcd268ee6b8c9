// Helpers of horus::msg::CameraInfo (fragment: included inside the generated struct body).

/// A distortion-free pinhole camera of `width` x `height` pixels with focal lengths `fx`, `fy`
/// and principal point (`cx`, `cy`) in pixels; identity rectification.
static constexpr CameraInfo make(std::uint32_t width, std::uint32_t height, double fx, double fy,
                                 double cx, double cy) noexcept {
  CameraInfo info{};
  info.width = width;
  info.height = height;
  info.camera_matrix = {fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0};
  info.rectification_matrix = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  info.projection_matrix = {fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0};
  return info;
}

/// {fx, fy} in pixels.
constexpr std::array<double, 2> focal_lengths() const noexcept {
  return {camera_matrix[0], camera_matrix[4]};
}

/// {cx, cy} in pixels.
constexpr std::array<double, 2> principal_point() const noexcept {
  return {camera_matrix[2], camera_matrix[5]};
}
