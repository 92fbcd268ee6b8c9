// Helpers of horus::msg::OccupancyGrid (fragment: included inside the generated struct body).
// World coordinates are metres in the map frame; grid coordinates are cell indices, cell
// (gx, gy) covering [origin + g * resolution, origin + (g + 1) * resolution) on each axis.
// Every lookup checks its bounds: outside the grid there is no cell, never a wrapped index.

/// A `width` x `height` grid of `resolution` m cells with cell (0, 0)'s corner at `origin`,
/// every cell UNKNOWN.
static OccupancyGrid make(std::uint32_t width, std::uint32_t height, float resolution,
                          const Pose2D& origin) {
  OccupancyGrid grid{};
  grid.resolution = resolution;
  grid.width = width;
  grid.height = height;
  grid.origin = origin;
  grid.data.assign(std::size_t{width} * height, UNKNOWN);
  return grid;
}

/// The cell containing world point (`x`, `y`); empty outside the grid, for a non-finite point
/// or a resolution that is not positive. A 1e-6 cell slack keeps points on a cell boundary
/// (0.5 m at 0.1 m resolution) in the cell they start, despite rounding.
std::optional<std::pair<std::uint32_t, std::uint32_t>> world_to_grid(double x,
                                                                     double y) const noexcept {
  const double res = resolution;
  if (!(res > 0.0)) return std::nullopt;
  const double gx = std::floor((x - origin.x) / res + 1e-6);
  const double gy = std::floor((y - origin.y) / res + 1e-6);
  if (!(gx >= 0.0 && gx < static_cast<double>(width) && gy >= 0.0 &&
        gy < static_cast<double>(height))) {
    return std::nullopt;
  }
  return std::pair{static_cast<std::uint32_t>(gx), static_cast<std::uint32_t>(gy)};
}

/// The world point at the centre of cell (`gx`, `gy`); empty outside the grid.
std::optional<std::pair<double, double>> grid_to_world(std::uint32_t gx,
                                                       std::uint32_t gy) const noexcept {
  if (gx >= width || gy >= height) return std::nullopt;
  const double res = resolution;
  return std::pair{origin.x + (gx + 0.5) * res, origin.y + (gy + 0.5) * res};
}

/// The value of cell (`gx`, `gy`); empty outside the grid (or past a short data vector).
std::optional<std::int8_t> occupancy(std::uint32_t gx, std::uint32_t gy) const noexcept {
  if (gx >= width || gy >= height) return std::nullopt;
  const std::size_t index = std::size_t{gy} * width + gx;
  if (index >= data.size()) return std::nullopt;
  return data[index];
}

/// Sets cell (`gx`, `gy`) to `value` clamped to [-1, 100]; false (and unchanged) outside the
/// grid.
bool set_occupancy(std::uint32_t gx, std::uint32_t gy, std::int8_t value) noexcept {
  if (gx >= width || gy >= height) return false;
  const std::size_t index = std::size_t{gy} * width + gx;
  if (index >= data.size()) return false;
  data[index] = value < UNKNOWN ? UNKNOWN : (value > OCCUPIED ? OCCUPIED : value);
  return true;
}

/// True when world point (`x`, `y`) is in a known cell below 50 % occupancy. Unknown cells and
/// points off the map are neither free nor occupied.
bool is_free(double x, double y) const noexcept {
  const auto cell = world_to_grid(x, y);
  if (!cell) return false;
  const auto value = occupancy(cell->first, cell->second);
  return value && *value >= 0 && *value < 50;
}

/// True when world point (`x`, `y`) is in a cell of at least 50 % occupancy.
bool is_occupied(double x, double y) const noexcept {
  const auto cell = world_to_grid(x, y);
  if (!cell) return false;
  const auto value = occupancy(cell->first, cell->second);
  return value && *value >= 50;
}
