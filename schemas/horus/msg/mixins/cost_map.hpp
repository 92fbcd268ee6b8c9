// Helpers of horus::msg::CostMap (fragment: included inside the generated struct body).
// Base cost of a cell: 255 when unknown (negative, or missing from a short data vector),
// lethal_cost when occupied (>= 65), else 2 * occupancy. Then every cell within
// inflation_radius of a cell costing at least lethal_cost gets at least
//   floor((lethal_cost - 1) * (1 - d / inflation_radius) ^ cost_scaling_factor)
// with d the centre-to-centre distance in metres (double precision, the same in Python).

/// The cost map of `grid` with obstacles inflated by `inflation_radius` metres (the default
/// scaling factor and lethal cost).
static CostMap from_occupancy_grid(OccupancyGrid grid, float inflation_radius) {
  CostMap map{};
  map.occupancy_grid = std::move(grid);
  map.inflation_radius = inflation_radius;
  map.compute_costs();
  return map;
}

/// Recomputes costs from occupancy_grid (after the grid or the parameters changed).
void compute_costs() {
  const OccupancyGrid& grid = occupancy_grid;
  const std::size_t width = grid.width, height = grid.height;
  costs.assign(width * height, 0);
  for (std::size_t i = 0; i < costs.size(); ++i) {
    const int occ = i < grid.data.size() ? grid.data[i] : -1;
    costs[i] = occ < 0 ? 255 : (occ >= 65 ? lethal_cost : static_cast<std::uint8_t>(occ * 2));
  }
  const double res = grid.resolution, radius = inflation_radius;
  if (!(res > 0.0) || !(radius > 0.0) || !std::isfinite(radius) || costs.empty()) return;
  // The window is capped at the grid's size: a tiny resolution must not make it explode.
  const double wanted = std::ceil(radius / res);
  const std::size_t limit = width > height ? width : height;
  const std::ptrdiff_t reach = static_cast<std::ptrdiff_t>(
      wanted < static_cast<double>(limit) ? wanted : static_cast<double>(limit));
  // Squared distance, in cells, to the nearest obstacle; -1 = none within reach.
  std::vector<std::int64_t> nearest(costs.size(), -1);
  for (std::size_t oy = 0; oy < height; ++oy) {
    for (std::size_t ox = 0; ox < width; ++ox) {
      if (costs[oy * width + ox] < lethal_cost) continue;
      for (std::ptrdiff_t dy = -reach; dy <= reach; ++dy) {
        const std::ptrdiff_t ny = static_cast<std::ptrdiff_t>(oy) + dy;
        if (ny < 0 || ny >= static_cast<std::ptrdiff_t>(height)) continue;
        for (std::ptrdiff_t dx = -reach; dx <= reach; ++dx) {
          const std::ptrdiff_t nx = static_cast<std::ptrdiff_t>(ox) + dx;
          if (nx < 0 || nx >= static_cast<std::ptrdiff_t>(width)) continue;
          const std::int64_t d2 = std::int64_t{dx} * dx + std::int64_t{dy} * dy;
          std::int64_t& best =
              nearest[static_cast<std::size_t>(ny) * width + static_cast<std::size_t>(nx)];
          if (best < 0 || d2 < best) best = d2;
        }
      }
    }
  }
  const double top = static_cast<double>(lethal_cost) - 1.0;
  for (std::size_t i = 0; i < costs.size(); ++i) {
    if (nearest[i] < 0 || costs[i] >= lethal_cost) continue;
    const double distance = std::sqrt(static_cast<double>(nearest[i])) * res;
    if (distance > radius) continue;
    double inflated =
        top * std::pow(1.0 - distance / radius, static_cast<double>(cost_scaling_factor));
    if (inflated > top) inflated = top;
    const auto value = static_cast<std::uint8_t>(inflated > 0.0 ? inflated : 0.0);
    if (value > costs[i]) costs[i] = value;
  }
}

/// The cost at world point (`x`, `y`): lethal_cost off the map (never plan through the
/// unknown beyond it); empty when costs were not computed for that cell.
std::optional<std::uint8_t> cost(double x, double y) const noexcept {
  const auto cell = occupancy_grid.world_to_grid(x, y);
  if (!cell) return lethal_cost;
  const std::size_t index = std::size_t{cell->second} * occupancy_grid.width + cell->first;
  if (index >= costs.size()) return std::nullopt;
  return costs[index];
}
