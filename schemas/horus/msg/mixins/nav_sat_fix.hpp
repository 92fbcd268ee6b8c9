// Helpers of horus::msg::NavSatFix (fragment: included inside the generated struct body).

/// A fix (STATUS_FIX) at `latitude`, `longitude` degrees and `altitude` metres.
static constexpr NavSatFix from_coordinates(double latitude, double longitude,
                                            double altitude) noexcept {
  NavSatFix fix{};
  fix.latitude = latitude;
  fix.longitude = longitude;
  fix.altitude = altitude;
  fix.status = STATUS_FIX;
  return fix;
}

/// True for any fix status (plain, SBAS or GBAS).
constexpr bool has_fix() const noexcept { return status >= STATUS_FIX; }

/// True when the coordinates are finite and latitude/longitude within their ranges.
bool is_valid() const noexcept {
  return std::isfinite(latitude) && std::isfinite(longitude) && std::isfinite(altitude) &&
         latitude >= -90.0 && latitude <= 90.0 && longitude >= -180.0 && longitude <= 180.0;
}

/// Rough horizontal accuracy in metres: HDOP times a 5 m user range error.
constexpr float horizontal_accuracy() const noexcept { return hdop * 5.0f; }

/// Great-circle distance in metres to `other` (haversine, mean Earth radius 6371 km).
double distance_to(const NavSatFix& other) const noexcept {
  constexpr double earth_radius = 6371000.0;
  constexpr double to_rad = 3.14159265358979323846 / 180.0;
  const double lat1 = latitude * to_rad, lat2 = other.latitude * to_rad;
  const double dlat = (other.latitude - latitude) * to_rad;
  const double dlon = (other.longitude - longitude) * to_rad;
  const double a = std::sin(dlat / 2.0) * std::sin(dlat / 2.0) +
                   std::cos(lat1) * std::cos(lat2) * std::sin(dlon / 2.0) * std::sin(dlon / 2.0);
  return 2.0 * earth_radius * std::atan2(std::sqrt(a), std::sqrt(1.0 - a));
}
