// horus._core: session recording (docs/recording.md) as methods of horus._core.Scheduler.
// SchedulerConfig::recording(true) itself is a constructor keyword (scheduler.cpp).
#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "bindings.hpp"
#include "horus/scheduler.hpp"

namespace horus::python {

namespace py = pybind11;

namespace {

/// Adds `function` to the already bound class `cls` as a method called `name`.
template <class Function, class... Extra>
void add_method(py::object& cls, const char* name, Function&& function, const Extra&... extra) {
  cls.attr(name) = py::cpp_function(std::forward<Function>(function), py::name(name),
                                    py::is_method(cls), extra...);
}

std::vector<std::string> strings(const std::vector<std::filesystem::path>& paths) {
  std::vector<std::string> out;
  for (const auto& path : paths) out.push_back(path.string());
  return out;
}

}  // namespace

void bind_recording(py::module_& m) {
  py::object scheduler = m.attr("Scheduler");
  add_method(scheduler, "is_recording",
             [](const Scheduler& sched) { return sched.is_recording(); });
  // Joins the recording thread, which never needs the GIL.
  add_method(
      scheduler, "stop_recording", [](Scheduler& sched) { return strings(sched.stop_recording()); },
      py::call_guard<py::gil_scoped_release>());
  add_method(scheduler, "list_recordings",
             [](const Scheduler& sched) { return sched.list_recordings(); });
  add_method(scheduler, "delete_recording", [](Scheduler& sched, const std::string& name) {
    return sched.delete_recording(name);
  });
}

}  // namespace horus::python
