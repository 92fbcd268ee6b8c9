// The topic segments this process created, so that a scheduler's shutdown can remove the ones no
// live process uses any more (seed 001, shutdown step 4) and leave everybody else's alone.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "horus/detail/shm_segment.hpp"

namespace horus::detail {

/// Records that this process created (or re-created) segment `name` of a namespace (empty: the
/// current one), for segments of `mode`. Slow path only.
void remember_created_segment(std::string_view namespace_name, const std::string& name,
                              unsigned mode);

/// Removes segment `name` of `folder` when no live process has it open (a flock keeps openers
/// out meanwhile); whether it was removed.
bool remove_if_abandoned(const NamespaceFolder& folder, const std::string& name);

/// Removes every segment this process created that no live process uses any more, and forgets
/// those that are gone; returns how many it removed. Segments still in use stay remembered, for
/// a later call.
std::size_t remove_created_segments_nobody_uses();

}  // namespace horus::detail
