// What a scheduler runs beside its nodes, on threads of its own, while it lives, from a library
// the program links: the DDS bridge of horus::dds (SchedulerConfig::network) and the live view of
// horus::view (SchedulerConfig::view). The runtime links neither: each library registers the
// factory of its companion when a program links it, and the scheduler starts what its
// configuration names through that factory, or says which library to link.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>

namespace horus {

class SchedulerCompanion {
 public:
  virtual ~SchedulerCompanion() = default;
  /// Stops it and returns once it has; idempotent.
  virtual void end() noexcept = 0;
};

/// Starts the companion configured by `options` in `namespace_name`; `on_failure` gets the
/// reason if it stops on its own (the scheduler then stops, and run() returns 1). Throws
/// horus::Error when it cannot start.
template <class Options>
using SchedulerCompanionFactory = std::unique_ptr<SchedulerCompanion> (*)(
    const Options& options, const std::string& namespace_name,
    std::function<void(const std::string&)> on_failure);

/// The factory registered for companions configured by `Options`, or nullptr.
template <class Options>
std::atomic<SchedulerCompanionFactory<Options>>& scheduler_companion_factory() noexcept {
  static std::atomic<SchedulerCompanionFactory<Options>> factory{nullptr};
  return factory;
}

}  // namespace horus
