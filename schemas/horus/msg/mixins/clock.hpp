// Helpers of horus::msg::Clock (fragment: included inside the generated struct body).

/// Simulation time `sim_ns` advancing at `speed` x real time (realtime_ns and timestamp_ns 0:
/// the publisher stamps them).
static constexpr Clock sim_time(std::uint64_t sim_ns, double speed) noexcept {
  Clock clock{};
  clock.clock_ns = sim_ns;
  clock.sim_speed = speed;
  clock.source = SOURCE_SIM;
  return clock;
}

/// Replay time `replay_ns` advancing at `speed` x real time.
static constexpr Clock replay_time(std::uint64_t replay_ns, double speed) noexcept {
  Clock clock = sim_time(replay_ns, speed);
  clock.source = SOURCE_REPLAY;
  return clock;
}

/// Clock time from `earlier` to this message in nanoseconds; 0 if `earlier` is later (a clock
/// reset or a replay seek), never a wrapped huge value.
constexpr std::uint64_t elapsed_since(const Clock& earlier) const noexcept {
  return clock_ns > earlier.clock_ns ? clock_ns - earlier.clock_ns : 0;
}

/// True while the clock is paused.
constexpr bool is_paused() const noexcept { return paused != 0; }
