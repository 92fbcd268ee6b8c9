// Node health: the graduated watchdog (Warning, Unhealthy, Isolated) and safe states.
#include <algorithm>
#include <limits>
#include <string>

#include "scheduler_impl.hpp"

namespace horus::detail {

void SchedulerImpl::escalate(NodeSlot& slot, std::uint8_t level) noexcept {
  std::uint8_t previous = slot.watchdog_level.load(std::memory_order_acquire);
  while (previous < level &&
         !slot.watchdog_level.compare_exchange_weak(previous, level, std::memory_order_acq_rel)) {
  }
  if (previous >= level) return;
  if (previous == 0) {
    slot.watchdog_expirations.fetch_add(1, std::memory_order_relaxed);
    total_watchdog_.fetch_add(1, std::memory_order_relaxed);
  }
  record(BlackboxEventKind::WatchdogExpired, slot, level);
  const NodeHealthState target = level >= 3 && slot.critical.load() ? NodeHealthState::Isolated
                                 : level >= 2                       ? NodeHealthState::Unhealthy
                                                                    : NodeHealthState::Warning;
  NodeHealthState current = slot.health.load(std::memory_order_acquire);
  while (current < target &&
         !slot.health.compare_exchange_weak(current, target, std::memory_order_acq_rel)) {
  }
  if (current >= target) return;
  record(BlackboxEventKind::HealthChange, slot, static_cast<std::int64_t>(target),
         to_string(target));
  if (target == NodeHealthState::Warning) slot.warnings.fetch_add(1, std::memory_order_relaxed);
  if (target == NodeHealthState::Isolated) {
    // A frozen critical node puts the whole system in its safe state. Each node enters it on its
    // own thread at its next release, never concurrently with its own tick().
    log(LogLevel::Error,
        "critical node '%s' frozen (3x watchdog): isolating it, all nodes to safe state",
        slot.name.c_str());
    slot.pending_safe_state.store(true, std::memory_order_release);
    // Every node, those added while running too: a rare path, where the lock costs nothing.
    std::lock_guard lock(mutex_);
    for (const SlotPtr& other : slots_) {
      if (other.get() != &slot) other->pending_safe_state.store(true, std::memory_order_release);
    }
  } else if (config_.verbose() || target == NodeHealthState::Unhealthy) {
    log(LogLevel::Warn, "node '%s' exceeded %dx its watchdog timeout: %s", slot.name.c_str(), level,
        std::string(to_string(target)).c_str());
  }
}

void SchedulerImpl::set_health(NodeSlot& slot, NodeHealthState health) noexcept {
  const NodeHealthState previous = slot.health.exchange(health, std::memory_order_acq_rel);
  if (previous != health) {
    record(BlackboxEventKind::HealthChange, slot, static_cast<std::int64_t>(health),
           to_string(health));
  }
}

void SchedulerImpl::enter_safe(NodeSlot& slot) noexcept {
  if (slot.state.load() != NodeState::Running) return;
  try {
    TickContextScope scope(&slot.context);
    slot.node->enter_safe_state();
  } catch (...) {
    log(LogLevel::Error, "node '%s': enter_safe_state() threw", slot.name.c_str());
  }
  set_health(slot, NodeHealthState::Isolated);
  record(BlackboxEventKind::SafeStateEntered, slot);
}

void SchedulerImpl::run_watchdog(const std::vector<SlotPtr>& watched, std::int64_t end) noexcept {
  std::int64_t shortest = std::numeric_limits<std::int64_t>::max();
  for (const SlotPtr& s : watched) shortest = std::min(shortest, s->watchdog_ns.load());
  const std::int64_t interval = std::clamp<std::int64_t>(shortest / 4, 1'000'000, 50'000'000);
  std::int64_t next = monotonic_ns() + interval;
  while (sleep_until(std::min(next, end))) {
    const std::int64_t now = monotonic_ns();
    if (now >= end) break;
    for (const SlotPtr& s : watched) {
      const std::int64_t started = s->tick_started_ns.load(std::memory_order_acquire);
      const std::int64_t timeout = s->watchdog_ns.load(std::memory_order_relaxed);
      if (started == 0 || now - started < timeout) continue;
      escalate(*s, static_cast<std::uint8_t>(std::min<std::int64_t>((now - started) / timeout, 3)));
    }
    next = next_on_grid(next, interval, now);
  }
}

}  // namespace horus::detail
