// horus._core.Scheduler, horus._core.PyNode and the framework clock. Every call that can run
// node callbacks (run, tick_once, remove_node, destruction ...) releases the GIL first, so the
// scheduler's threads can take it for their Python callbacks.
#include <pybind11/stl.h>
#include <sys/mman.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "bindings.hpp"
#include "horus/clock.hpp"
#include "horus/log.hpp"
#include "horus/scheduler.hpp"
#include "py_node.hpp"

namespace py = pybind11;

namespace horus::python {

namespace {

std::chrono::nanoseconds from_seconds(double s) {
  if (!std::isfinite(s) || s < 0.0) {
    throw Error("a duration must be a finite number of seconds >= 0, got " + std::to_string(s));
  }
  // Rounded, not truncated: 100 * us is 9.999999999999999e-05 s, which must stay 100 us.
  return std::chrono::round<std::chrono::nanoseconds>(std::chrono::duration<double>(s));
}

std::optional<std::chrono::nanoseconds> from_seconds(std::optional<double> s) {
  if (!s) {
    return std::nullopt;
  }
  return from_seconds(*s);
}

double seconds(std::chrono::nanoseconds ns) { return static_cast<double>(ns.count()) * 1e-9; }

py::object seconds_or_none(const std::optional<std::chrono::nanoseconds>& ns) {
  return ns ? py::object(py::float_(seconds(*ns))) : py::object(py::none());
}

std::string lower(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return out;
}

/// on_miss as seed 001 spells it, both ways.
constexpr std::pair<std::string_view, Miss> kMissNames[] = {{"warn", Miss::Warn},
                                                            {"skip", Miss::Skip},
                                                            {"safe_mode", Miss::SafeMode},
                                                            {"stop", Miss::Stop}};

Miss parse_miss(const std::string& text) {
  for (const auto& [name, miss] : kMissNames) {
    if (text == name) return miss;
  }
  throw Error("on_miss must be one of 'warn', 'skip', 'safe_mode', 'stop', got '" + text + "'");
}

std::string_view miss_name(Miss miss) {
  for (const auto& [name, value] : kMissNames) {
    if (value == miss) return name;
  }
  return "?";
}

FailurePolicy parse_failure_policy(const std::string& text) {
  if (text == "fatal") return FailurePolicy::Fatal{};
  if (text == "restart") return FailurePolicy::Restart{};
  if (text == "skip") return FailurePolicy::Skip{};
  if (text == "ignore") return FailurePolicy::Ignore{};
  throw Error("failure_policy must be one of 'fatal', 'restart', 'skip', 'ignore', got '" + text +
              "'");
}

py::dict info_dict(const NodeInfo& info) {
  py::dict out;
  out["name"] = info.name;
  out["order"] = info.order;
  out["execution_class"] = std::string(to_string(info.execution_class));
  out["state"] = std::string(to_string(info.state));
  out["health"] = std::string(to_string(info.health));
  out["rate"] = info.rate ? py::object(py::float_(info.rate->hz())) : py::object(py::none());
  out["budget"] = seconds_or_none(info.budget);
  out["deadline"] = seconds_or_none(info.deadline);
  out["watchdog"] = seconds_or_none(info.watchdog);
  out["on_miss"] = std::string(miss_name(info.on_miss));
  out["failure_policy"] = lower(to_string(info.failure_policy));
  out["critical"] = info.critical;
  out["on"] = info.on_topic ? py::object(py::str(*info.on_topic)) : py::object(py::none());
  out["priority"] = info.priority ? py::object(py::int_(*info.priority)) : py::object(py::none());
  out["last_error"] = info.last_error;
  py::list pubs;
  for (const auto& topic : info.publishers)
    pubs.append(py::make_tuple(topic.topic_name, topic.type_name));
  py::list subs;
  for (const auto& topic : info.subscribers)
    subs.append(py::make_tuple(topic.topic_name, topic.type_name));
  out["publishers"] = pubs;
  out["subscribers"] = subs;
  return out;
}

/// A node's counters, and its priority (seed 001's get_node_stats() example prints it).
py::dict metrics_dict(const NodeMetrics& m, std::optional<int> priority) {
  py::dict out;
  out["name"] = m.name;
  out["order"] = m.order;
  out["priority"] = priority ? py::object(py::int_(*priority)) : py::object(py::none());
  out["total_ticks"] = m.total_ticks;
  out["successful_ticks"] = m.successful_ticks;
  out["failed_ticks"] = m.failed_ticks;
  out["skipped_ticks"] = m.skipped_ticks;
  out["avg_tick_duration"] = seconds(m.avg_tick_duration);
  out["max_tick_duration"] = seconds(m.max_tick_duration);
  out["min_tick_duration"] = seconds(m.min_tick_duration);
  out["last_tick_duration"] = seconds(m.last_tick_duration);
  out["budget_overruns"] = m.budget_overruns;
  out["deadline_misses"] = m.deadline_misses;
  out["watchdog_expirations"] = m.watchdog_expirations;
  out["errors_count"] = m.errors_count;
  out["warnings_count"] = m.warnings_count;
  out["restarts"] = m.restarts;
  out["messages_sent"] = m.messages_sent;
  out["messages_received"] = m.messages_received;
  out["achieved_rate_hz"] = m.achieved_rate_hz;
  out["uptime"] = seconds(m.uptime);
  return out;
}

/// Destroys a scheduler (which shuts initialised nodes down) with the GIL released.
struct ReleasingDeleter {
  void operator()(Scheduler* scheduler) const {
    if (PyGILState_Check() != 0) {
      py::gil_scoped_release released;
      delete scheduler;
    } else {
      delete scheduler;
    }
  }
};

using Release = py::call_guard<py::gil_scoped_release>;

/// A weak reference to a node, for its request_stop().
struct StopHandle {
  std::weak_ptr<Node> node;
  void request_stop() const noexcept {
    if (const auto held = node.lock()) {
      held->request_stop();
    }
  }
};

}  // namespace

void bind_scheduler(py::module_& m) {
  py::class_<Node, std::shared_ptr<Node>>(
      m, "Node", "A C++ horus::Node; extensions expose their C++ nodes as subclasses of it.")
      .def_property_readonly("name", [](const Node& node) { return std::string(node.name()); })
      .def("request_stop", &Node::request_stop)
      .def("stop_handle", [](const std::shared_ptr<Node>& node) { return StopHandle{node}; });

  py::class_<StopHandle>(m, "StopHandle",
                         "Node.request_stop() without owning the node (a Python node keeps one: "
                         "owning its C++ node would make a cycle the garbage collector cannot see)")
      .def("request_stop", &StopHandle::request_stop);

  py::class_<PyNode, Node, std::shared_ptr<PyNode>>(m, "PyNode")
      .def(py::init([](std::string name, py::tuple callbacks,
                       const std::vector<std::pair<std::string, std::string>>& pubs,
                       const std::vector<std::pair<std::string, std::string>>& subs) {
             std::vector<TopicMetadata> publishers;
             for (const auto& [topic, type] : pubs) publishers.push_back({topic, type});
             std::vector<TopicMetadata> subscribers;
             for (const auto& [topic, type] : subs) subscribers.push_back({topic, type});
             return std::make_shared<PyNode>(std::move(name), std::move(callbacks),
                                             std::move(publishers), std::move(subscribers));
           }),
           py::arg("name"), py::arg("callbacks"), py::arg("publishers"), py::arg("subscribers"))
      .def(
          "declare_param",
          [](PyNode& node, std::string name, const std::string& spelling,
             const std::string& default_value, std::optional<double> min, std::optional<double> max,
             const std::vector<std::string>& choices, std::string unit, std::string doc,
             bool read_only, const std::optional<std::string>& enum_description) {
            return node.declare_param(python_param_declaration(
                std::move(name), spelling, default_value, min, max, choices, std::move(unit),
                std::move(doc), read_only, enum_description));
          },
          py::arg("name"), py::arg("spelling"), py::arg("default"), py::arg("min"), py::arg("max"),
          py::arg("choices"), py::arg("unit"), py::arg("doc"), py::arg("read_only"),
          py::arg("enum_description"));

  py::class_<Scheduler, std::unique_ptr<Scheduler, ReleasingDeleter>>(m, "Scheduler")
      .def(py::init([](double tick_rate, bool rt, bool deterministic, double watchdog_ms,
                       std::size_t blackbox_mb, std::optional<std::string> name,
                       std::vector<int> cores, std::optional<std::uint64_t> max_deadline_misses,
                       bool verbose, std::optional<std::string> telemetry,
                       std::optional<std::uint64_t> seed, bool recording,
                       std::optional<std::string> replay,
                       std::optional<std::tuple<std::string, std::uint16_t, double>> view,
                       std::optional<std::string> params) {
             SchedulerConfig config;
             config.tick_rate(Rate::hz(tick_rate))
                 .rt(rt)
                 .deterministic(deterministic)
                 .watchdog(from_seconds(watchdog_ms * 1e-3))
                 .blackbox_mb(blackbox_mb)
                 .cores(std::move(cores))
                 .verbose(verbose)
                 .recording(recording);
             if (name) config.name(*name);
             config.max_deadline_misses(max_deadline_misses);  // None: no limit (seed 001)
             if (telemetry) config.telemetry(*telemetry);
             if (seed) config.seed(*seed);
             if (replay) config.replay(*replay);
             if (params) config.params(*params);
             if (view) {
               const auto& [listen_address, port, discovery_interval_s] = *view;
               config.view({.listen_address = listen_address,
                            .port = port,
                            .discovery_interval = std::chrono::milliseconds(
                                static_cast<std::int64_t>(discovery_interval_s * 1e3))});
             }
             std::unique_ptr<Scheduler, ReleasingDeleter> sched(new Scheduler(std::move(config)));
             if (sched->capabilities().memory_locking) {
               // Pages stay locked, but are locked as they are first touched: CPython maps and
               // unmaps its 1 MiB arenas as the heap breathes, and filling a whole new one in at
               // once (what rt's MCL_FUTURE alone does) costs ~0.3 ms inside a tick, under the
               // GIL every other Python node waits for. New threads' stacks likewise.
               mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT);
             }
             return sched;
           }),
           py::arg("tick_rate"), py::arg("rt"), py::arg("deterministic"), py::arg("watchdog_ms"),
           py::arg("blackbox_mb"), py::arg("name"), py::arg("cores"),
           py::arg("max_deadline_misses"), py::arg("verbose"), py::arg("telemetry"),
           py::arg("seed"), py::arg("recording") = false, py::arg("replay") = py::none(),
           py::arg("view") = py::none(), py::arg("params") = py::none())
      .def(
          "add",
          [](Scheduler& sched, std::shared_ptr<Node> node, std::int32_t order,
             std::optional<double> rate, std::optional<double> budget,
             std::optional<double> deadline, std::optional<std::string> on_miss,
             std::optional<std::string> failure_policy, bool compute, std::optional<std::string> on,
             bool async_io, std::optional<int> priority, std::optional<int> core,
             std::optional<double> watchdog) {
            NodeBuilder builder = sched.add(std::move(node));
            builder.order(order).compute(compute).async_io(async_io);
            if (rate) builder.rate(Rate::hz(*rate));
            if (auto b = from_seconds(budget)) builder.budget(*b);
            if (auto d = from_seconds(deadline)) builder.deadline(*d);
            if (on_miss) builder.on_miss(parse_miss(*on_miss));
            // Seed 001: without a policy, a failed init() excludes the node and the others
            // run on; a failing tick() still stops the scheduler (docs/seeds.md).
            builder.failure_policy(failure_policy
                                       ? parse_failure_policy(*failure_policy)
                                       : FailurePolicy::Fatal{.stop_on_failed_init = false});
            if (on) builder.on(*on);
            if (priority) builder.priority(*priority);
            if (core) builder.core(*core);
            if (auto w = from_seconds(watchdog)) builder.watchdog(*w);
            builder.build();
          },
          py::arg("node"), py::arg("order"), py::arg("rate"), py::arg("budget"),
          py::arg("deadline"), py::arg("on_miss"), py::arg("failure_policy"), py::arg("compute"),
          py::arg("on"), py::arg("async_io"), py::arg("priority"), py::arg("core"),
          py::arg("watchdog"))
      .def(
          "add_critical_node",
          [](Scheduler& sched, const std::string& name, double timeout_s) {
            sched.add_critical_node(name, from_seconds(timeout_s));
          },
          py::arg("name"), py::arg("timeout"))
      .def("run", &Scheduler::run, Release())
      .def(
          "run_for",
          [](Scheduler& sched, double duration_s) {
            const auto duration = from_seconds(duration_s);
            py::gil_scoped_release released;
            return sched.run_for(duration);
          },
          py::arg("duration"))
      .def(
          "tick_once",
          [](Scheduler& sched, std::optional<std::vector<std::string>> names) {
            py::gil_scoped_release released;
            if (names) {
              sched.tick_once(*names);
            } else {
              sched.tick_once();
            }
          },
          py::arg("names") = py::none())
      .def(
          "tick_for",
          [](Scheduler& sched, double duration_s, std::vector<std::string> names) {
            const auto duration = from_seconds(duration_s);
            py::gil_scoped_release released;
            sched.tick_for(duration, names);
          },
          py::arg("duration"), py::arg("names"))
      .def("stop", &Scheduler::stop, Release())
      .def(
          "set_node_rate",
          [](Scheduler& sched, const std::string& name, double rate) {
            return sched.set_node_rate(name, Rate::hz(rate));
          },
          py::arg("name"), py::arg("rate"))
      .def(
          "set_tick_budget",
          [](Scheduler& sched, const std::string& name, double budget_s) {
            return sched.set_tick_budget(name, from_seconds(budget_s));
          },
          py::arg("name"), py::arg("budget"))
      .def(
          "remove_node",
          [](Scheduler& sched, const std::string& name) {
            py::gil_scoped_release released;
            return sched.remove_node(name);
          },
          py::arg("name"))
      .def("status", [](const Scheduler& sched) { return lower(to_string(sched.status())); })
      .def("is_running", &Scheduler::is_running)
      .def("current_tick", &Scheduler::current_tick)
      .def("name", [](const Scheduler& sched) { return sched.name(); })
      .def("stop_reason", &Scheduler::stop_reason)
      .def("node_count", &Scheduler::node_count)
      .def("node_names", &Scheduler::node_names)
      .def("has_node",
           [](const Scheduler& sched, const std::string& name) { return sched.has_node(name); })
      .def("node_info",
           [](const Scheduler& sched, const std::string& name) -> py::object {
             auto info = sched.node_info(name);
             return info ? py::object(info_dict(*info)) : py::object(py::none());
           })
      .def("nodes",
           [](const Scheduler& sched) {
             py::list out;
             for (const NodeInfo& info : sched.nodes()) out.append(info_dict(info));
             return out;
           })
      .def("node_metrics",
           [](const Scheduler& sched, const std::string& name) -> py::object {
             const auto metrics = sched.node_metrics(name);
             const auto info = sched.node_info(name);
             return metrics && info ? py::object(metrics_dict(*metrics, info->priority))
                                    : py::object(py::none());
           })
      .def("safety_stats",
           [](const Scheduler& sched) {
             const SafetyStats stats = sched.safety_stats();
             py::dict out;
             out["budget_overruns"] = stats.budget_overruns;
             out["deadline_misses"] = stats.deadline_misses;
             out["watchdog_expirations"] = stats.watchdog_expirations;
             py::dict health;
             for (const auto& [name, state] : stats.health_states) {
               health[py::str(name)] = std::string(to_string(state));
             }
             out["health_states"] = health;
             return out;
           })
      .def("timing_report", &Scheduler::timing_report)
      .def("has_full_rt", &Scheduler::has_full_rt)
      .def("degradations", &Scheduler::degradations)
      .def("capabilities",
           [](const Scheduler& sched) {
             const RtCapabilities caps = sched.capabilities();
             py::dict out;
             out["rt_scheduling"] = caps.rt_scheduling;
             out["memory_locking"] = caps.memory_locking;
             out["cpu_isolation"] = caps.cpu_isolation;
             return out;
           })
      .def("dump_blackbox",
           [](const Scheduler& sched, const std::string& path) { sched.dump_blackbox(path); });

  m.def("now", [] {
    const ClockSnapshot& clock = thread_clock();
    return clock.in_callback || !clock.valid ? seconds(horus::now()) : clock.now_s;
  });
  m.def("timestamp_now", [] {
    const ClockSnapshot& clock = thread_clock();
    return clock.in_callback || !clock.valid ? horus::timestamp_now() : clock.now_ns;
  });
  m.def("dt", [] {
    const ClockSnapshot& clock = thread_clock();
    return clock.in_callback ? seconds(horus::dt()) : clock.dt_s;
  });
  m.def("elapsed", [] {
    const ClockSnapshot& clock = thread_clock();
    return clock.in_callback ? seconds(horus::elapsed()) : clock.elapsed_s;
  });
  m.def("tick", [] {
    const ClockSnapshot& clock = thread_clock();
    return clock.in_callback ? horus::tick_index() : clock.tick;
  });
  m.def("budget_remaining", [] {
    const auto remaining = horus::budget_remaining();
    return remaining == std::chrono::nanoseconds::max() ? std::numeric_limits<double>::infinity()
                                                        : seconds(remaining);
  });
  m.def("rng_float", [] { return horus::rng_float(); });
  m.def(
      "lateness", [] { return seconds(horus::lateness()); },
      "Inside a callback: how late the scheduler began this tick after its release, before "
      "taking the GIL (bench/python measures Python ticks with it).");
  m.def("in_callback", [] { return thread_clock().in_callback; });
  m.def(
      "log",
      [](const std::string& level, std::string_view source, std::string_view message) {
        static const std::pair<const char*, LogLevel> levels[] = {{"debug", LogLevel::Debug},
                                                                  {"info", LogLevel::Info},
                                                                  {"warn", LogLevel::Warn},
                                                                  {"error", LogLevel::Error}};
        for (const auto& [name, value] : levels) {
          if (level == name) {
            log::emit(value, source, message);
            return;
          }
        }
        throw Error("log level must be debug, info, warn or error, got '" + level + "'");
      },
      py::arg("level"), py::arg("source"), py::arg("message"));
  m.def("flush_log", &log::flush, py::call_guard<py::gil_scoped_release>(),
        "Returns once every line logged so far is on stderr.");
}

}  // namespace horus::python
