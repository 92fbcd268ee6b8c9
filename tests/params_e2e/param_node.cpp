// The C++ side of the parameter suite (test_params_e2e.py): test_nodes::ParamNodeBase, generated
// from tests/schemas/test_nodes/param_node.hnode, run as a program of its own under the name
// given, ticking at 100 Hz until it is stopped or killed.
//
//   horus_param_e2e_node NAME [PARAMS.yaml]
//
// It prints, one line each and flushed at once (the test reads them):
//   ready VALUES        after its first tick;
//   tick VALUES         when a tick reads values that differ from the previous tick's;
//   change NAME VALUE SOURCE   for each write offered to on_param_change(), accepted or not;
// VALUES as `max_speed=1 gain=0.5 ... gains=1,0.5,0`, read through the generated accessors
// (py_param_node.py prints the same). It refuses a gain above 5 (a veto of its own, beyond the
// declaration's range).
#include <array>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <memory>
#include <sstream>
#include <string>
#include <string_view>

#include "horus/params.hpp"
#include "horus/scheduler.hpp"
#include "test_nodes/param_node.hpp"

namespace {

std::string shown(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

std::string shown(bool value) { return value ? "true" : "false"; }

std::string shown(test_msgs::Mode mode) { return mode == test_msgs::Mode::Idle ? "Idle" : "Run"; }

template <class T, std::size_t N>
std::string shown(const std::array<T, N>& values) {
  std::string text;
  for (const T& value : values) {
    if (!text.empty()) text += ',';
    text += shown(value);
  }
  return text;
}

class E2eParamNode : public test_nodes::ParamNodeBase {
 public:
  explicit E2eParamNode(std::string name) : name_(std::move(name)) {}

  std::string_view name() const override { return name_; }

  void tick() override {
    const std::string values = current_values();
    if (values == last_values_) return;
    std::printf("%s %s\n", last_values_.empty() ? "ready" : "tick", values.c_str());
    std::fflush(stdout);
    last_values_ = values;
  }

  horus::ParamVerdict on_param_change(const horus::ParamChange& change) override {
    std::printf("change %s %s %s\n", change.name().c_str(), proposed(change).c_str(),
                change.source.c_str());
    std::fflush(stdout);
    if (change.name() == "gain" && change.as<float>() > 5.0F) {
      return horus::ParamVerdict::refuse("a gain above 5 makes the speed loop oscillate");
    }
    return horus::ParamVerdict::accept();
  }

 private:
  std::string current_values() const {
    const Params& p = params();
    std::ostringstream text;
    text << "max_speed=" << shown(p.max_speed()) << " gain=" << shown(double{p.gain()})
         << " offset=" << p.offset() << " wheel_count=" << unsigned{p.wheel_count()}
         << " enabled=" << shown(p.enabled()) << " profile=" << p.profile()
         << " mode=" << shown(p.mode()) << " gains=" << shown(p.gains())
         << " mask=" << shown(p.mask()) << " ticks=" << p.ticks();
    return text.str();
  }

  static std::string proposed(const horus::ParamChange& change) {
    const std::string& type = change.declaration->spelling;
    if (type == "f64") return shown(change.as<double>());
    if (type == "f32") return shown(double{change.as<float>()});
    if (type == "i32") return std::to_string(change.as<std::int32_t>());
    if (type == "u8") return std::to_string(change.as<std::uint8_t>());
    if (type == "u64") return std::to_string(change.as<std::uint64_t>());
    if (type == "bool") return shown(change.as<bool>());
    if (type == "String") return change.as<std::string>();
    if (type == "[f64; 3]") return shown(change.as<std::array<double, 3>>());
    if (type == "[bool; 2]") return shown(change.as<std::array<bool, 2>>());
    return shown(change.as<test_msgs::Mode>());
  }

  std::string name_;
  std::string last_values_;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    std::fprintf(stderr, "usage: %s NAME [PARAMS.yaml]\n", argv[0]);
    return 2;
  }
  horus::SchedulerConfig config;
  config.name(std::string(argv[1]) + "_program");
  if (argc == 3) config.params(argv[2]);
  try {
    horus::Scheduler scheduler(config);
    test_nodes::ParamNodeBase::add_to(scheduler, std::make_shared<E2eParamNode>(argv[1])).build();
    return scheduler.run();
  } catch (const std::exception& error) {
    std::fprintf(stderr, "%s\n", error.what());
    return 1;
  }
}
