// horus._core: session recording (docs/recording.md) as methods of horus._core.Scheduler.
// SchedulerConfig::recording(true) itself is a constructor keyword (scheduler.cpp). Also the
// frames of a recorded pool-backed topic made again for `horus record replay`.
#include <pybind11/stl.h>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "bindings.hpp"
#include "horus/pool_frames.hpp"
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

/// PoolFrames of one recorded topic, for a replay written in Python.
class ReplayFrames {
 public:
  ReplayFrames(const std::string& type_name, std::uint64_t fingerprint,
               const std::string& namespace_name, std::size_t keep)
      : frames_(make_pool_frames(type_name, fingerprint, namespace_name, keep)) {
    if (!frames_) {
      throw py::value_error(type_name + " (fingerprint " + std::to_string(fingerprint) +
                            ") is not a pool-backed type of this horus build");
    }
  }
  /// The descriptor naming a new block that holds the recorded data, or None for a malformed
  /// recorded message.
  py::object replay(const py::bytes& recorded) {
    const std::string_view bytes(recorded);
    const std::span<const std::byte> descriptor =
        frames_->replay({reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()});
    if (descriptor.empty()) return py::none();
    return py::bytes(reinterpret_cast<const char*>(descriptor.data()), descriptor.size());
  }

 private:
  std::unique_ptr<PoolFrames> frames_;
};

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
  py::class_<ReplayFrames>(m, "ReplayFrames",
                           "Frames of a recorded Image/DepthImage/PointCloud/Tensor topic made "
                           "again in the namespace's pool (docs/recording.md); the last `keep` "
                           "stay alive, as a sending topic's ring keeps them.")
      .def(py::init<const std::string&, std::uint64_t, const std::string&, std::size_t>(),
           py::arg("type_name"), py::arg("fingerprint"), py::arg("namespace_name"), py::arg("keep"))
      .def("replay", &ReplayFrames::replay, py::arg("recorded"));
}

}  // namespace horus::python
