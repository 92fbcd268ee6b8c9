// horus::literals: units written where they are used: 100_hz, 2.5_hz, 200_us, 1_ms, 3_s.
#pragma once

#include <chrono>

#include "horus/rate.hpp"

namespace horus {
inline namespace literals {

constexpr Rate operator""_hz(unsigned long long hz) { return Rate::hz(static_cast<double>(hz)); }
constexpr Rate operator""_hz(long double hz) { return Rate::hz(static_cast<double>(hz)); }

constexpr std::chrono::nanoseconds operator""_ns(unsigned long long v) {
  return std::chrono::nanoseconds(v);
}
constexpr std::chrono::microseconds operator""_us(unsigned long long v) {
  return std::chrono::microseconds(v);
}
constexpr std::chrono::milliseconds operator""_ms(unsigned long long v) {
  return std::chrono::milliseconds(v);
}
constexpr std::chrono::seconds operator""_s(unsigned long long v) {
  return std::chrono::seconds(v);
}

}  // namespace literals
}  // namespace horus
