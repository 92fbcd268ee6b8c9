// horus::FailurePolicy: what the scheduler does when init(), tick() or shutdown() throws.
#pragma once

#include <chrono>
#include <cstdint>
#include <string_view>
#include <variant>

namespace horus {

/// One of four strategies, written the way the seeds name them:
///   .failure_policy(horus::FailurePolicy::Restart{.max_restarts = 3, .initial_backoff = 1_ms})
class FailurePolicy {
 public:
  /// The node's failure stops the scheduler (default). With stop_on_failed_init false, a failed
  /// init() only excludes the node (Error state) and the others run on: seed 001's rule, which
  /// the Python scheduler applies to nodes added without a failure_policy.
  struct Fatal {
    bool stop_on_failed_init = true;
  };
  /// Re-run init() after initial_backoff, doubling the wait after each further failure; after
  /// max_restarts failed restarts the failure is treated as Fatal.
  struct Restart {
    std::uint32_t max_restarts = 3;
    std::chrono::nanoseconds initial_backoff = std::chrono::milliseconds(10);
  };
  /// Tolerate failures; after max_failures consecutive ones, skip the node for `cooldown`, then
  /// try again with the count reset.
  struct Skip {
    std::uint32_t max_failures = 5;
    std::chrono::nanoseconds cooldown = std::chrono::seconds(1);
  };
  /// Log and keep ticking regardless.
  struct Ignore {};

  enum class Kind : std::uint8_t { Fatal, Restart, Skip, Ignore };

  // Not "= default": GCC cannot use Fatal's member initialiser before this class is complete.
  FailurePolicy() : policy_(Fatal{}) {}
  FailurePolicy(Fatal p) : policy_(p) {}
  FailurePolicy(Restart p) : policy_(p) {}
  FailurePolicy(Skip p) : policy_(p) {}
  FailurePolicy(Ignore p) : policy_(p) {}

  Kind kind() const noexcept { return static_cast<Kind>(policy_.index()); }
  /// The parameters of a Fatal / Restart / Skip policy; nullptr for other kinds.
  const Fatal* fatal() const noexcept { return std::get_if<Fatal>(&policy_); }
  const Restart* restart() const noexcept { return std::get_if<Restart>(&policy_); }
  const Skip* skip() const noexcept { return std::get_if<Skip>(&policy_); }

 private:
  std::variant<Fatal, Restart, Skip, Ignore> policy_;
};

constexpr std::string_view to_string(FailurePolicy::Kind k) noexcept {
  switch (k) {
    case FailurePolicy::Kind::Fatal:
      return "Fatal";
    case FailurePolicy::Kind::Restart:
      return "Restart";
    case FailurePolicy::Kind::Skip:
      return "Skip";
    case FailurePolicy::Kind::Ignore:
      return "Ignore";
  }
  return "?";
}

}  // namespace horus
