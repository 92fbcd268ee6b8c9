// Compiled into each program that links horus::view (an interface source of the target): it
// registers the live view as SchedulerConfig::view()'s before main() runs, and its reference
// pulls the view out of the static library, which a program otherwise never names.
#include "horus/live_view.hpp"

namespace {

[[maybe_unused]] const bool scheduler_view_registered =
    (horus::view::enable_scheduler_view(), true);

}  // namespace
