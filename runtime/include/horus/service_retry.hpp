// horus::RetryConfig: how ServiceClient::call_resilient_with() retries transient failures.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

#include "horus/error.hpp"

namespace horus {

/// Retries after a transient error (Timeout, Transport), sleeping initial_backoff(), then
/// multiplier() times longer each time, never longer than max_backoff(). Each attempt gets the
/// full timeout again, so a resilient call can take longer than its timeout.
class RetryConfig {
 public:
  /// The default of call_resilient(): 3 retries, 10 ms backoff doubling up to 1 s.
  RetryConfig() = default;
  RetryConfig(std::uint32_t max_retries, std::chrono::nanoseconds initial_backoff) {
    this->max_retries(max_retries).initial_backoff(initial_backoff);
  }

  /// Retries after the first attempt (0: a single attempt).
  RetryConfig& max_retries(std::uint32_t n) noexcept {
    max_retries_ = n;
    return *this;
  }
  RetryConfig& initial_backoff(std::chrono::nanoseconds d) {
    require(d >= std::chrono::nanoseconds::zero(), "initial_backoff must not be negative");
    initial_backoff_ = d;
    return *this;
  }
  /// Growth of the backoff per retry; at least 1.
  RetryConfig& multiplier(double m) {
    require(m >= 1.0, "multiplier must be at least 1, got " + std::to_string(m));
    multiplier_ = m;
    return *this;
  }
  RetryConfig& max_backoff(std::chrono::nanoseconds d) {
    require(d >= std::chrono::nanoseconds::zero(), "max_backoff must not be negative");
    max_backoff_ = d;
    return *this;
  }

  std::uint32_t max_retries() const noexcept { return max_retries_; }
  std::chrono::nanoseconds initial_backoff() const noexcept { return initial_backoff_; }
  double multiplier() const noexcept { return multiplier_; }
  std::chrono::nanoseconds max_backoff() const noexcept { return max_backoff_; }

  /// The sleep before retry number `retry` (0 for the first retry).
  std::chrono::nanoseconds backoff(std::uint32_t retry) const noexcept {
    double nanos = static_cast<double>(initial_backoff_.count());
    const auto cap = static_cast<double>(max_backoff_.count());
    for (std::uint32_t i = 0; i < retry && nanos < cap; ++i) {
      nanos *= multiplier_;
    }
    return std::chrono::nanoseconds(static_cast<std::int64_t>(nanos < cap ? nanos : cap));
  }

 private:
  static void require(bool ok, const std::string& what) {
    if (!ok) {
      throw Error("RetryConfig: " + what);
    }
  }

  std::uint32_t max_retries_ = 3;
  std::chrono::nanoseconds initial_backoff_ = std::chrono::milliseconds(10);
  double multiplier_ = 2.0;
  std::chrono::nanoseconds max_backoff_ = std::chrono::seconds(1);
};

}  // namespace horus
