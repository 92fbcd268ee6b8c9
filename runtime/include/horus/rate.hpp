// horus::Rate: a frequency (ticks per second) with its period as a std::chrono duration.
#pragma once

#include <chrono>
#include <cmath>
#include <compare>

namespace horus {

/// A tick rate. `100_hz` (horus::literals) or Rate::hz(2.5); period() is the release interval.
class Rate {
 public:
  constexpr Rate() = default;
  static constexpr Rate hz(double hz) { return Rate(hz); }
  /// The rate whose period is `period` (e.g. every 40 ms is 25 Hz).
  static Rate every(std::chrono::nanoseconds period) {
    return Rate(1e9 / static_cast<double>(period.count()));
  }

  constexpr double hz() const { return hz_; }
  /// True for a positive, finite rate: the only kind the scheduler accepts.
  bool valid() const { return std::isfinite(hz_) && hz_ > 0.0; }
  /// 1 / rate, rounded to the nearest nanosecond (at least 1 ns).
  std::chrono::nanoseconds period() const {
    const long long ns = std::llround(1e9 / hz_);
    return std::chrono::nanoseconds(ns < 1 ? 1 : ns);
  }

  constexpr auto operator<=>(const Rate&) const = default;

 private:
  constexpr explicit Rate(double hz) : hz_(hz) {}
  double hz_ = 0.0;
};

}  // namespace horus
