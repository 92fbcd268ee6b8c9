#include "py_node.hpp"

#include <sched.h>

#include <cstdint>
#include <cstdio>
#include <ctime>
#include <stdexcept>
#include <thread>
#include <utility>

#include "gil_probe.hpp"
#include "horus/clock.hpp"

namespace py = pybind11;

namespace horus::python {

namespace {

double seconds(std::chrono::nanoseconds ns) { return static_cast<double>(ns.count()) * 1e-9; }

std::int64_t monotonic_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// Marks this thread as inside a Python callback and, on the way out, keeps the clock it saw.
class CallbackScope {
 public:
  CallbackScope() : clock_(thread_clock()), outer_(clock_.in_callback) {
    clock_.in_callback = true;
  }
  ~CallbackScope() {
    clock_.now_ns = horus::timestamp_now();
    clock_.now_s = seconds(std::chrono::nanoseconds(clock_.now_ns));
    clock_.dt_s = seconds(horus::dt());
    clock_.elapsed_s = seconds(horus::elapsed());
    clock_.tick = horus::tick_index();
    clock_.valid = true;
    clock_.in_callback = outer_;
  }
  CallbackScope(const CallbackScope&) = delete;
  CallbackScope& operator=(const CallbackScope&) = delete;

 private:
  ClockSnapshot& clock_;
  bool outer_;
};

/// Whether Python code may still run here. Once the interpreter is finalizing (a scheduler
/// destroyed at exit, say by a failed test's traceback), CPython ends any other thread that takes
/// the GIL with pthread_exit, whose unwinding the scheduler's catch (...) swallows: the process
/// aborts ("exception not rethrown"). Such a thread skips its Python callbacks instead.
bool python_may_run() noexcept {
  return Py_IsInitialized() != 0 && (_Py_IsFinalizing() == 0 || PyGILState_Check() != 0);
}

/// A scheduler thread about to run Python spins while another thread holds the GIL, for at most
/// this long: the holder is most often another node's tick of a few microseconds, and blocking
/// on CPython's condition variable instead costs a wake-up once it is released (tens of
/// microseconds on a VM, more when its CPU went idle). A longer holder gets the usual wait. Each
/// turn yields, so a holder of the same priority waiting for this CPU gets it; with one CPU
/// there is no spinning at all.
constexpr std::int64_t kGilSpinNs = 100'000;

void spin_while_gil_taken() noexcept {
  static const bool spin = std::thread::hardware_concurrency() > 1;
  if (!spin || !gil_taken()) return;
  const std::int64_t give_up = monotonic_ns() + kGilSpinNs;
  do {
    sched_yield();
  } while (gil_taken() && monotonic_ns() < give_up);
}

/// Takes the GIL for one callback. A scheduler thread that Python does not know gets a Python
/// thread state once, kept until the thread ends: making and destroying one per callback (what a
/// PyGILState_Ensure/Release pair does there) costs microseconds. A thread Python started (the
/// one that called run() or tick_once()) uses its own state, which Python owns.
class CallbackGil {
 public:
  CallbackGil() {
    if (PyGILState_Check() != 0) {
      return;  // this thread holds it already
    }
    spin_while_gil_taken();
    if (PyThreadState* state = PyGILState_GetThisThreadState()) {
      PyEval_RestoreThread(state);
    } else {
      keeper_of_this_thread().adopt();
    }
    taken_ = true;
  }
  ~CallbackGil() {
    if (taken_) {
      PyEval_SaveThread();
    }
  }
  CallbackGil(const CallbackGil&) = delete;
  CallbackGil& operator=(const CallbackGil&) = delete;

 private:
  /// The thread state made for this (non-Python) thread, released when the thread ends.
  struct Keeper {
    PyThreadState* state = nullptr;
    PyGILState_STATE gil_state{};
    Keeper() = default;
    Keeper(const Keeper&) = delete;
    Keeper& operator=(const Keeper&) = delete;
    /// Makes the state and takes the GIL with it.
    void adopt() {
      gil_state = PyGILState_Ensure();
      state = PyThreadState_Get();
    }
    ~Keeper() {
      if (state != nullptr && python_may_run()) {
        PyEval_RestoreThread(state);
        PyGILState_Release(gil_state);
      }
    }
  };
  static Keeper& keeper_of_this_thread() {
    thread_local Keeper keeper;
    return keeper;
  }
  bool taken_ = false;
};

/// The exception's own line ("RuntimeError: encoder lost"), then the whole traceback: what
/// keeps only a headline (the blackbox's 64 bytes, a one-line summary) keeps what went wrong.
std::string python_traceback(py::error_already_set& error) {
  try {
    py::module_ traceback = py::module_::import("traceback");
    py::list headline = traceback.attr("format_exception_only")(error.type(), error.value());
    py::list lines = traceback.attr("format_exception")(error.type(), error.value(), error.trace());
    std::string text =
        headline.empty() ? std::string() : headline[headline.size() - 1].cast<std::string>();
    for (const auto& line : lines) {
      text += line.cast<std::string>();
    }
    while (!text.empty() && text.back() == '\n') {
      text.pop_back();
    }
    return text;
  } catch (const py::error_already_set&) {
    return error.what();
  }
}

}  // namespace

ClockSnapshot& thread_clock() noexcept {
  thread_local ClockSnapshot clock;
  return clock;
}

PyNode::PyNode(std::string name, py::tuple callbacks, std::vector<TopicMetadata> publishers,
               std::vector<TopicMetadata> subscribers)
    : name_(std::move(name)),
      publishers_(std::move(publishers)),
      subscribers_(std::move(subscribers)) {
  if (callbacks.size() != 6) {
    throw std::invalid_argument(
        "PyNode needs (init, tick, shutdown, enter_safe_state, is_safe_state, "
        "on_param_change)");
  }
  init_ = callbacks[0];
  tick_ = callbacks[1];
  shutdown_ = callbacks[2];
  enter_safe_state_ = callbacks[3];
  is_safe_state_ = callbacks[4];
  on_param_change_ = callbacks[5];
}

PyNode::~PyNode() {
  if (!python_may_run()) {
    // At exit the callables are left to the interpreter rather than end this thread.
    for (py::object* callback :
         {&init_, &tick_, &shutdown_, &enter_safe_state_, &is_safe_state_, &on_param_change_}) {
      callback->release();
    }
    return;
  }
  // The scheduler may drop its last reference on one of its threads.
  py::gil_scoped_acquire gil;
  init_ = py::object();
  tick_ = py::object();
  shutdown_ = py::object();
  enter_safe_state_ = py::object();
  is_safe_state_ = py::object();
  on_param_change_ = py::object();
}

void PyNode::call(const py::object& callback) const {
  if (callback.is_none() || !python_may_run()) {
    return;
  }
  CallbackScope scope;
  CallbackGil gil;
  // The C API's no-argument call (vectorcall): pybind11's call operator would build an argument
  // tuple first, on every tick.
  PyObject* result = PyObject_CallNoArgs(callback.ptr());
  if (result == nullptr) {
    py::error_already_set error;
    throw std::runtime_error(python_traceback(error));
  }
  Py_DECREF(result);
}

bool PyNode::is_safe_state() const {
  if (!python_may_run()) {
    return true;
  }
  CallbackGil gil;
  if (is_safe_state_.is_none()) {
    return true;
  }
  try {
    return is_safe_state_().cast<bool>();
  } catch (py::error_already_set& error) {
    // The scheduler asks this outside any failure policy: an error keeps the node isolated.
    std::fprintf(stderr, "[horus] node '%s': is_safe_state() raised:\n%s\n", name_.c_str(),
                 python_traceback(error).c_str());
    return false;
  }
}

ParamVerdict PyNode::on_param_change(const ParamChange& change) {
  if (!python_may_run()) {
    return ParamVerdict::refuse("node '" + name_ + "': the Python interpreter is exiting");
  }
  CallbackScope scope;
  CallbackGil gil;
  if (on_param_change_.is_none()) {
    return ParamVerdict::accept();
  }
  try {
    py::object answer = on_param_change_(change.name(), py::bytes(change.value), change.source);
    if (answer.is_none()) {
      return ParamVerdict::accept();
    }
    auto [accepted, reason] = answer.cast<std::pair<bool, std::string>>();
    return accepted ? ParamVerdict::accept() : ParamVerdict::refuse(std::move(reason));
  } catch (py::error_already_set& error) {
    // The node did not say yes: the write is refused with what went wrong, and the node runs on.
    std::string text = python_traceback(error);
    std::fprintf(stderr, "[horus] node '%s': on_param_change() raised:\n%s\n", name_.c_str(),
                 text.c_str());
    return ParamVerdict::refuse("on_param_change() raised " + text.substr(0, text.find('\n')));
  }
}

}  // namespace horus::python
