// Compiled into each program that links horus::dds (an interface source of the target): it
// registers the DDS bridge as SchedulerConfig::network()'s before main() runs, and its reference
// pulls the bridge out of the static library, which a program otherwise never names.
#include "horus/dds_bridge.hpp"

namespace {

[[maybe_unused]] const bool network_bridge_registered = (horus::dds::enable_network_bridge(), true);

}  // namespace
