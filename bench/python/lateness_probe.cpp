// horus_bench_probe: a C++ node for bench_lateness.py that records how late each of its ticks
// began after its release (horus::lateness()), beside Python nodes in the same scheduler. Built
// without the runtime: bench_lateness.py loads horus._core's symbols globally first.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <horus/clock.hpp>
#include <horus/node.hpp>

namespace {

class LatenessProbe final : public horus::Node {
 public:
  LatenessProbe(std::string name, std::size_t capacity) : name_(std::move(name)) {
    samples_.reserve(capacity);  // a tick never allocates
  }
  std::string_view name() const override { return name_; }
  void tick() override {
    if (samples_.size() < samples_.capacity()) samples_.push_back(horus::lateness().count());
  }
  /// Each tick's lateness in nanoseconds, the first tick first.
  const std::vector<std::int64_t>& samples() const { return samples_; }

 private:
  std::string name_;
  std::vector<std::int64_t> samples_;
};

}  // namespace

PYBIND11_MODULE(horus_bench_probe, m) {
  // The base class horus._core.Node must be registered before a subclass of it.
  pybind11::module_::import("horus._core");
  pybind11::class_<LatenessProbe, horus::Node, std::shared_ptr<LatenessProbe>>(m, "LatenessProbe")
      .def(pybind11::init<std::string, std::size_t>(), pybind11::arg("name"),
           pybind11::arg("capacity"))
      .def_property_readonly("samples", &LatenessProbe::samples);
}
