// Deterministic mode's order: a subscriber ticks after its publishers within a pass (seed 001:
// "execution order is determined by the dependency graph"), inferred from the topics nodes
// report in publishers() / subscribers().
#include "topic_order.hpp"

#include <algorithm>
#include <map>
#include <set>

namespace horus::detail {
namespace {

/// Whether `start` reaches itself through the waits of unplaced nodes.
bool on_cycle(std::size_t start, const std::vector<std::set<std::size_t>>& waits_for,
              const std::vector<bool>& placed) {
  std::vector<bool> seen(waits_for.size(), false);
  std::vector<std::size_t> stack(waits_for[start].begin(), waits_for[start].end());
  while (!stack.empty()) {
    const std::size_t node = stack.back();
    stack.pop_back();
    if (node == start) return true;
    if (placed[node] || seen[node]) continue;
    seen[node] = true;
    stack.insert(stack.end(), waits_for[node].begin(), waits_for[node].end());
  }
  return false;
}

}  // namespace

std::vector<SlotPtr> order_by_topics(const std::vector<SlotPtr>& slots,
                                     std::vector<std::string>& cycle_breaks) {
  // `slots` comes in (order, registration) sequence: an index into it is the tie-breaker.
  std::map<std::string, std::vector<std::size_t>> publishers_of;
  for (std::size_t i = 0; i < slots.size(); ++i) {
    for (const TopicMetadata& topic : slots[i]->publishers) {
      publishers_of[topic.topic_name].push_back(i);
    }
  }
  std::vector<std::set<std::size_t>> waits_for(slots.size());
  for (std::size_t i = 0; i < slots.size(); ++i) {
    for (const TopicMetadata& topic : slots[i]->subscribers) {
      const auto it = publishers_of.find(topic.topic_name);
      if (it == publishers_of.end()) continue;
      for (const std::size_t publisher : it->second) {
        if (publisher != i) waits_for[i].insert(publisher);
      }
    }
  }
  std::vector<SlotPtr> ordered;
  std::vector<bool> placed(slots.size(), false);
  while (ordered.size() < slots.size()) {
    // The first node in (order, registration) whose publishers are all placed. When none is
    // ready, every unplaced node waits for another, so some of them form a cycle: the first
    // node on one goes next (not a node merely waiting behind a cycle).
    std::size_t next = slots.size();
    for (std::size_t i = 0; i < slots.size() && next == slots.size(); ++i) {
      if (!placed[i] && std::all_of(waits_for[i].begin(), waits_for[i].end(),
                                    [&](std::size_t p) { return placed[p]; })) {
        next = i;
      }
    }
    for (std::size_t i = 0; i < slots.size() && next == slots.size(); ++i) {
      if (!placed[i] && on_cycle(i, waits_for, placed)) {
        next = i;
        cycle_breaks.push_back(slots[i]->name);
      }
    }
    placed[next] = true;
    ordered.push_back(slots[next]);
  }
  return ordered;
}

}  // namespace horus::detail
