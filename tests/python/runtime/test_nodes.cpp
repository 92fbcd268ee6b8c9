// horus_test_nodes: a C++ node exposed to Python the way any extension exposes its own, so a test
// can run it in one scheduler with Python nodes.
#include <pybind11/pybind11.h>

#include <memory>
#include <string>

#include <horus/msg.hpp>
#include <horus/node.hpp>
#include <horus/topic.hpp>

namespace {

/// Forwards every CmdVel from one topic to another with its linear speed doubled.
class CmdVelDoubler final : public horus::Node {
 public:
  CmdVelDoubler(std::string name, const std::string& input, const std::string& output)
      : name_(std::move(name)), input_(input), output_(output) {}
  std::string_view name() const override { return name_; }
  void tick() override {
    while (auto msg = input_.try_recv()) {
      msg->linear *= 2.0F;
      output_.send(*msg);
      ++forwarded_;
    }
  }
  std::uint64_t forwarded() const { return forwarded_; }

 private:
  std::string name_;
  horus::Topic<horus::msg::CmdVel> input_;
  horus::Topic<horus::msg::CmdVel> output_;
  std::uint64_t forwarded_ = 0;
};

}  // namespace

PYBIND11_MODULE(horus_test_nodes, m) {
  // The base class horus._core.Node must be registered before a subclass of it.
  pybind11::module_::import("horus._core");
  pybind11::class_<CmdVelDoubler, horus::Node, std::shared_ptr<CmdVelDoubler>>(m, "CmdVelDoubler")
      .def(pybind11::init<std::string, const std::string&, const std::string&>(),
           pybind11::arg("name"), pybind11::arg("input"), pybind11::arg("output"))
      .def_property_readonly("forwarded", &CmdVelDoubler::forwarded);
}
