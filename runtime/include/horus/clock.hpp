// The framework clock: time as the scheduler sees it, read from inside init/tick/shutdown.
//
// In normal mode these follow the wall clock; in deterministic mode
// (SchedulerConfig::deterministic) they follow a SimClock that advances by exactly one period per
// tick and a seeded random sequence, so a run reproduces bit for bit. Outside a scheduler callback
// they describe "no tick": now() is the wall clock, dt() and elapsed() are zero, budget_remaining()
// is unlimited. All of them are cheap (no allocation, no lock, no system call) and safe from any
// thread.
#pragma once

#include <chrono>
#include <cstdint>

namespace horus {

/// Current time: since the Unix epoch normally, since the scheduler started in deterministic mode.
std::chrono::nanoseconds now() noexcept;

/// now() as an integer count of nanoseconds, for a message's `timestamp_ns` field: since the Unix
/// epoch normally, simulated time in deterministic mode (so recorded stamps repeat run to run).
std::uint64_t timestamp_now() noexcept;

/// Time since this node's previous tick began; exactly 1/rate in deterministic mode. On a node's
/// first tick, its nominal period (so integrators never see a zero or garbage step).
std::chrono::nanoseconds dt() noexcept;

/// Time since the scheduler started (simulated time in deterministic mode).
std::chrono::nanoseconds elapsed() noexcept;

/// Index of the calling node's current tick: 0 for its first tick, then 1, 2, ... (Python's
/// horus.tick(); in C++ a plain tick() inside a node would name Node::tick()).
std::uint64_t tick_index() noexcept;

/// What is left of this tick's budget (negative once overrun); nanoseconds::max() when the node
/// has no budget. In deterministic mode simulated time does not move inside a tick, so this is
/// the whole budget.
std::chrono::nanoseconds budget_remaining() noexcept;

/// How late the current tick started after its release on the grid (time spent waiting for the
/// thread to wake or for earlier nodes to finish). Zero outside a tick and in deterministic mode.
std::chrono::nanoseconds lateness() noexcept;

/// A uniform random number in [0, 1). Seeded from system entropy normally; in deterministic mode
/// from the scheduler's seed and the node's name, so each node sees the same sequence every run.
double rng_float() noexcept;

}  // namespace horus
