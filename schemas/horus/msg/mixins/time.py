"""Helpers of the clock and time messages (horus/msg/time.hmsg), mirroring the C++ mixins."""

_U64_MAX = (1 << 64) - 1


class ClockMixin:
    @classmethod
    def sim_time(cls, sim_ns: int, speed: float):
        """Simulation time `sim_ns` advancing at `speed` x real time."""
        return cls(clock_ns=sim_ns, sim_speed=speed, source=cls.SOURCE_SIM)

    @classmethod
    def replay_time(cls, replay_ns: int, speed: float):
        """Replay time `replay_ns` advancing at `speed` x real time."""
        return cls(clock_ns=replay_ns, sim_speed=speed, source=cls.SOURCE_REPLAY)

    def elapsed_since(self, earlier) -> int:
        """Nanoseconds from `earlier` to this message; 0 if `earlier` is later."""
        return max(self.clock_ns - earlier.clock_ns, 0)

    def is_paused(self) -> bool:
        """True while the clock is paused."""
        return self.paused != 0


class TimeReferenceMixin:
    def correct_timestamp(self, local_ns: int) -> int:
        """`local_ns` in the reference's time (local - offset), saturating at 0 and 2^64 - 1."""
        return min(max(local_ns - self.offset_ns, 0), _U64_MAX)
