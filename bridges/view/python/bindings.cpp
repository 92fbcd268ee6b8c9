// horus._core.view: the live view's library (bridges/view/) as `horus record replay --view` uses
// it, built into horus._core so the process has one copy of the runtime and its process-wide
// state. A LiveView whose time, the protocol's `time` and each message's timestamp, is whatever
// set_time() said last (the recording's time), or the wall clock until it is first called.
#include <pybind11/pybind11.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>

#include "horus/error.hpp"
#include "horus/live_view.hpp"

namespace py = pybind11;

namespace horus::python {
namespace {

/// Read by the view's threads, written by Python's.
class SettableClock {
 public:
  /// The set time, or the wall clock while none was set.
  std::int64_t now() const noexcept {
    const std::int64_t set = time_ns_.load(std::memory_order_acquire);
    if (set != kUnset) return set;
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
  }
  void set(std::int64_t time_ns) noexcept { time_ns_.store(time_ns, std::memory_order_release); }

 private:
  static constexpr std::int64_t kUnset = -1;
  std::atomic<std::int64_t> time_ns_{kUnset};
};

class PythonLiveView {
 public:
  PythonLiveView(std::string namespace_name, std::string listen, std::uint16_t port)
      : clock_(std::make_shared<SettableClock>()),
        view_(view_options(std::move(namespace_name), std::move(listen), port, clock_)) {}

  void start() {
    const py::gil_scoped_release released;
    view_.start();
  }
  void stop() {
    const py::gil_scoped_release released;
    view_.stop();
  }
  std::uint16_t port() const noexcept { return view_.port(); }
  std::string status_json() const { return view_.status_json(); }
  void set_time(std::int64_t time_ns) {
    if (time_ns < 0) {
      throw Error("set_time takes nanoseconds since the epoch (0 or more), not " +
                  std::to_string(time_ns));
    }
    clock_->set(time_ns);
  }

 private:
  static LiveViewOptions view_options(std::string namespace_name, std::string listen,
                                      std::uint16_t port,
                                      const std::shared_ptr<SettableClock>& clock) {
    LiveViewOptions options;
    options.namespace_name = std::move(namespace_name);
    options.listen_address = std::move(listen);
    options.port = port;
    // Shared with the view's threads, which read it until the view has stopped.
    options.clock = [clock] { return clock->now(); };
    detail::check_live_view(options);
    return options;
  }

  std::shared_ptr<SettableClock> clock_;
  LiveView view_;
};

}  // namespace

void bind_view(py::module_& m) {
  py::class_<PythonLiveView>(m, "LiveView",
                             "The namespace served over the Foxglove WebSocket protocol "
                             "(horus::LiveView), with a time set from Python.")
      .def(py::init<std::string, std::string, std::uint16_t>(), py::arg("namespace"),
           py::arg("listen") = "127.0.0.1", py::arg("port") = 8765,
           "Checks the options (horus.HorusError names a bad one); serves nothing before "
           "start(). An empty namespace is the current one; port 0: any free one.")
      .def("start", &PythonLiveView::start,
           "Listens and serves on threads of its own; returns once listening. Raises HorusError "
           "when the address cannot be listened on.")
      .def("stop", &PythonLiveView::stop, "Closes every connection. Idempotent.")
      .def_property_readonly("port", &PythonLiveView::port,
                             "The port listened on (the chosen one when 0 was asked for).")
      .def("status_json", &PythonLiveView::status_json,
           "Clients, subscriptions, sent and dropped, as `horus view status --json` shows them.")
      .def("set_time", &PythonLiveView::set_time, py::arg("time_ns"),
           "The time told to viewers from now on, and stamped on the messages read after it "
           "(nanoseconds since the epoch); the wall clock until the first call.");
}

}  // namespace horus::python
