// horus::Node: the unit of work the scheduler runs (init once, tick repeatedly, shutdown once).
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "horus/params.hpp"
#include "horus/topic_metadata.hpp"

namespace horus {

namespace detail {
class SchedulerImpl;
class ParamOwner;
/// Checks a declaration (name, default within its own range and choices, size) and keeps it;
/// throws ParamError.
std::shared_ptr<ParamSlot> declare_node_param(std::vector<ParamDeclaration>& declarations,
                                              std::vector<std::shared_ptr<ParamSlot>>& slots,
                                              ParamDeclaration declaration,
                                              std::uint64_t default_word,
                                              std::string default_bytes);
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

  /// The parameters this node declared, in declaration order.
  const std::vector<ParamDeclaration>& param_declarations() const noexcept {
    return param_declarations_;
  }

  /// Offered every write of one of this node's parameters, between two ticks (never during
  /// one); only an accepted value is stored. The default accepts. It runs on the thread that
  /// ticks the node when the write arrives while that thread is busy with the node, and on the
  /// owner's service thread when it arrives while that thread sleeps: either way never during
  /// init(), tick() or shutdown() nor beside another call of this node by the scheduler, and
  /// with a happens-before from the call before it and to the call after, so it may touch the
  /// node's state without locks. Do not assume a thread identity (thread-locals, a thread id).
  virtual ParamVerdict on_param_change(const ParamChange& change);

 protected:
  /// Declares a parameter whose type is known only at run time (a language binding's node, the
  /// mirror of a remote node): the declaration complete, its default and choices as MessagePack
  /// VALUE bytes. Throws ParamError as declare_param<T> does, and for a default of another type.
  ParamHandle declare_param(ParamDeclaration declaration);

  /// Declares a parameter (in the constructor, before a scheduler adds the node). T: bool, the
  /// fixed-width integers, float, double, a generated enum (TypeInfo<E>::is_enum), std::string,
  /// std::array<number or bool, N>. Throws ParamError for a bad declaration (a bad name, a
  /// duplicate, a default outside its own range or choices, a value over kMaxParamValueBytes).
  template <class T>
  Param<T> declare_param(std::string name, T default_value, ParamOptions<T> options = {}) {
    ParamDeclaration declaration;
    declaration.name = std::move(name);
    detail::describe_param_type<T>(declaration);
    declaration.min = options.min;
    declaration.max = options.max;
    declaration.unit = std::move(options.unit);
    declaration.doc = std::move(options.doc);
    declaration.read_only = options.read_only;
    declaration.default_value = detail::encode_param_value(declaration, default_value);
    for (const T& choice : options.choices) {
      declaration.choices.push_back(detail::encode_param_value(declaration, choice));
    }
    std::uint64_t word = 0;
    std::string bytes;
    if constexpr (detail::kParamScalar<T>) {
      word = detail::param_word_of(default_value);
    } else {
      bytes = detail::param_bytes_of(default_value);
    }
    return Param<T>(detail::declare_node_param(param_declarations_, param_slots_,
                                               std::move(declaration), word, std::move(bytes)));
  }

 private:
  friend class detail::SchedulerImpl;
  friend class detail::ParamOwner;
  std::vector<ParamDeclaration> param_declarations_;
  std::vector<std::shared_ptr<detail::ParamSlot>> param_slots_;
  mutable std::string default_name_;
  std::weak_ptr<detail::SchedulerImpl> scheduler_;  // set when a scheduler adds the node
};

}  // namespace horus
