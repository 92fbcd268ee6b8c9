// horus::Node: the unit of work the scheduler runs (init once, tick repeatedly, shutdown once).
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "horus/topic_metadata.hpp"

namespace horus {

namespace detail {
class SchedulerImpl;
}  // namespace detail

/// Derive from Node and implement tick(); everything else has a sensible default.
///
/// The scheduler never calls two methods of the same node at once, and it calls them from the
/// thread that runs the node's execution class (so a node may keep unsynchronised state). An
/// exception escaping init(), tick() or shutdown() is caught, handed to on_error() and then to the
/// node's FailurePolicy. Language bindings subclass Node with trampolines, so every method is an
/// ordinary virtual and the scheduler holds no lock while calling one.
class Node {
 public:
  Node() = default;
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;
  virtual ~Node() = default;

  /// Unique within a scheduler and stable across runs. Default: the dynamic type's name without
  /// its namespaces (`robot::ImuReader` gives "ImuReader").
  virtual std::string_view name() const;

  /// One-time set-up on the first run()/tick_once(): open hardware, load calibration. Throw on
  /// failure.
  virtual void init() {}

  /// One cycle of work. Must not block, sleep or allocate in the common case.
  virtual void tick() = 0;

  /// Clean-up on stop, Ctrl+C or SIGTERM (reverse order of registration; at most 3 s each).
  /// Actuators should be zeroed here.
  virtual void shutdown() {}

  /// Asked at every release while the node is Isolated; true lets it tick again.
  virtual bool is_safe_state() const { return true; }

  /// Put outputs into a safe configuration (stop motors, hold position). Called after a
  /// Miss::SafeMode deadline miss or a watchdog isolation, on the node's own thread.
  virtual void enter_safe_state() {}

  /// An exception escaped init(), tick() or shutdown(); `error` is its what(). Default: logs it.
  virtual void on_error(std::string_view error);

  /// Topics this node publishes / subscribes to, for monitoring (generated nodes fill these).
  virtual std::vector<TopicMetadata> publishers() const { return {}; }
  virtual std::vector<TopicMetadata> subscribers() const { return {}; }

  /// Asks the scheduler running this node to stop (as Ctrl+C would): the loop ends and every
  /// node is shut down in reverse order. Safe from any thread, inside or outside a callback; a
  /// node that no scheduler holds ignores it.
  void request_stop() noexcept;

 private:
  friend class detail::SchedulerImpl;
  mutable std::string default_name_;
  std::weak_ptr<detail::SchedulerImpl> scheduler_;  // set when a scheduler adds the node
};

}  // namespace horus
