// The topic dependency order of deterministic mode (see topic_order.cpp).
#pragma once

#include <string>
#include <vector>

#include "node_slot.hpp"

namespace horus::detail {

/// `slots` (in order(), then registration) reordered so that every node comes after the nodes
/// publishing a topic it subscribes to; order() breaks ties. A cycle is broken by running its
/// first node in order() first; such nodes are appended to `cycle_breaks`.
std::vector<SlotPtr> order_by_topics(const std::vector<SlotPtr>& slots,
                                     std::vector<std::string>& cycle_breaks);

}  // namespace horus::detail
