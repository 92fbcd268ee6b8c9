// Helpers of horus::msg::StereoInfo (fragment: included inside the generated struct body).
// depth = baseline * fx / disparity, with fx the left camera's focal length in pixels; computed
// in double and rounded once to float, so C++ and Python agree exactly.

/// Depth in metres of a point seen with `disparity` pixels; +infinity for a disparity <= 0
/// (no parallax: the point is at infinity or unmatched).
float depth_from_disparity(float disparity) const noexcept {
  if (disparity <= 0.0f) return std::numeric_limits<float>::infinity();
  return static_cast<float>(baseline * left_camera.camera_matrix[0] / disparity);
}

/// Disparity in pixels of a point `depth` metres away; NaN for a depth <= 0 (no such point in
/// front of the camera).
float disparity_from_depth(float depth) const noexcept {
  if (depth <= 0.0f) return std::numeric_limits<float>::quiet_NaN();
  return static_cast<float>(baseline * left_camera.camera_matrix[0] / depth);
}
