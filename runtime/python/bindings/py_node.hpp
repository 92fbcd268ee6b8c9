// horus::python::PyNode: a horus::Node whose callbacks are Python callables. The scheduler calls
// them on its own threads; each call takes the GIL only while Python runs, so C++ nodes of the
// same scheduler never wait for it.
#pragma once

#include <pybind11/pybind11.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "horus/node.hpp"
#include "py_params.hpp"

namespace horus::python {

class PyNode final : public Node {
 public:
  /// `callbacks` is the Python node's (init, tick, shutdown, enter_safe_state, is_safe_state),
  /// each a callable taking no argument or None, then its on_param_change: a callable taking
  /// (name, value as MessagePack VALUE bytes, source) and returning None (accept) or
  /// (accepted, reason), or None.
  PyNode(std::string name, pybind11::tuple callbacks, std::vector<TopicMetadata> publishers,
         std::vector<TopicMetadata> subscribers);
  ~PyNode() override;
  PyNode(const PyNode&) = delete;
  PyNode& operator=(const PyNode&) = delete;

  std::string_view name() const override { return name_; }
  void init() override { call(init_); }
  void tick() override { call(tick_); }
  void shutdown() override { call(shutdown_); }
  void enter_safe_state() override { call(enter_safe_state_); }
  bool is_safe_state() const override;
  std::vector<TopicMetadata> publishers() const override { return publishers_; }
  std::vector<TopicMetadata> subscribers() const override { return subscribers_; }
  /// Offers the change to the Python node under the GIL; an exception refuses it, saying why.
  ParamVerdict on_param_change(const ParamChange& change) override;

  /// Declares one of the Python node's parameters (before a scheduler adds the node); throws
  /// ParamError for a bad declaration or a duplicate.
  ParamHandle declare_param(ParamDeclaration declaration) {
    return Node::declare_param(std::move(declaration));
  }

 private:
  /// Runs `callback` under the GIL; a Python exception becomes a C++ one whose text is the
  /// Python traceback, which the scheduler logs and hands to the failure policy.
  void call(const pybind11::object& callback) const;

  std::string name_;
  pybind11::object init_;
  pybind11::object tick_;
  pybind11::object shutdown_;
  pybind11::object enter_safe_state_;
  pybind11::object is_safe_state_;
  pybind11::object on_param_change_;
  std::vector<TopicMetadata> publishers_;
  std::vector<TopicMetadata> subscribers_;
};

/// The framework clock as Python sees it: inside a Python callback the scheduler's values; outside
/// one, those of the last callback this thread ran (so a test can read horus.dt() right after
/// tick_once()), or "no tick" when there was none.
struct ClockSnapshot {
  double now_s = 0.0;
  std::uint64_t now_ns = 0;
  double dt_s = 0.0;
  double elapsed_s = 0.0;
  std::uint64_t tick = 0;
  bool in_callback = false;
  bool valid = false;
};
ClockSnapshot& thread_clock() noexcept;

}  // namespace horus::python
