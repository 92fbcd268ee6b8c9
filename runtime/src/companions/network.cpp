// SchedulerConfig::network(): the options checked, and the DDS bridge started through the
// factory horus::dds registers (README.md).
#include <cmath>
#include <cstdio>
#include <string_view>

#include "horus/error.hpp"
#include "horus/network.hpp"

namespace horus::detail {
namespace {

/// Seconds to the nanosecond and without trailing zeros.
std::string seconds_text(std::chrono::duration<double> seconds) {
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", seconds.count());
  return text;
}

void check_patterns(const std::vector<std::string>& patterns, std::string_view field) {
  for (const std::string& pattern : patterns) {
    if (pattern.empty()) {
      throw Error(std::string(field) + " has an empty pattern, which names nothing");
    }
  }
}

}  // namespace

void check_network(const Network& network) {
  if (network.export_.empty() && network.import_.empty() && network.export_services.empty() &&
      network.import_services.empty() && network.export_frames.empty() &&
      network.import_frames.empty() && network.export_actions.empty() &&
      network.import_actions.empty()) {
    throw Error(
        "a Network carries nothing: give export_ and/or import_ patterns (or export_services, "
        "import_services, export_frames, import_frames, export_actions, import_actions)");
  }
  check_patterns(network.export_, "export_");
  check_patterns(network.import_, "import_");
  check_patterns(network.transient_local, "transient_local");
  check_patterns(network.export_services, "export_services");
  check_patterns(network.import_services, "import_services");
  check_patterns(network.ros2_types, "ros2_types");
  check_patterns(network.export_frames, "export_frames");
  check_patterns(network.import_frames, "import_frames");
  check_patterns(network.export_actions, "export_actions");
  check_patterns(network.import_actions, "import_actions");
  if (network.domain < 0 || network.domain > 232) {
    throw Error("domain must be a DDS domain id (0..232), got " + std::to_string(network.domain));
  }
  if (network.depth < 1) {
    throw Error("depth must be at least 1, got " + std::to_string(network.depth));
  }
  if (!(network.service_timeout.count() > 0.0) || std::isinf(network.service_timeout.count())) {
    throw Error("service_timeout must be a finite number of seconds above 0, got " +
                seconds_text(network.service_timeout) + " s");
  }
  for (const auto& [pattern, period] : network.deadlines) {
    if (pattern.empty()) throw Error("deadlines has an empty pattern, which names nothing");
    if (period.count() < 1) {
      throw Error("the deadline of '" + pattern + "' must be at least 1 ms, got " +
                  std::to_string(period.count()) + " ms");
    }
  }
}

std::unique_ptr<SchedulerCompanion> start_network(
    const Network& network, const std::string& namespace_name,
    std::function<void(const std::string&)> on_failure) {
  check_network(network);
  const auto factory = scheduler_companion_factory<Network>().load(std::memory_order_acquire);
  if (factory == nullptr) {
    throw Error(
        "this program has no DDS bridge: link it with horus::dds (target_link_libraries(... "
        "horus::dds), built where Cyclone DDS is installed)");
  }
  return factory(network, namespace_name, std::move(on_failure));
}

}  // namespace horus::detail
