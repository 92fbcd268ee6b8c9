// Helpers of horus::msg::RegionOfInterest (fragment: included inside the generated struct body).

/// The region at (`x`, `y`) of `width` x `height` pixels, not rectified.
static constexpr RegionOfInterest make(std::uint32_t x, std::uint32_t y, std::uint32_t width,
                                       std::uint32_t height) noexcept {
  return RegionOfInterest{
      .x_offset = x, .y_offset = y, .width = width, .height = height, .do_rectify = false};
}

/// True when pixel (`x`, `y`) lies inside (right and bottom edges excluded). Written without
/// x_offset + width, which could overflow.
constexpr bool contains(std::uint32_t x, std::uint32_t y) const noexcept {
  return x >= x_offset && x - x_offset < width && y >= y_offset && y - y_offset < height;
}

/// Area in pixels (64-bit: width * height can exceed 32 bits).
constexpr std::uint64_t area() const noexcept { return static_cast<std::uint64_t>(width) * height; }
