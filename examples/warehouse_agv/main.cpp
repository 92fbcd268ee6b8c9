// The warehouse AGV: seven nodes, standard messages, one action, one scheduler. See README.md.
// Each node is declared in nodes/<name>.hnode (its topics, data and scheduling settings);
// horus-gen makes the base classes (warehouse_agv::LidarBase, ...), this file writes their ticks.
// The nodes share nothing but topics (the robot's position included: the motor controller
// publishes it) and the GoToPallet action (actions/go_to_pallet.haction: the fleet node sends
// it, the planner serves it), so `--nodes` runs any of them in a process of its own
// (launch/warehouse.yaml).
#include <horus/horus.hpp>
#include <warehouse_agv.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

using namespace horus::literals;
namespace msg = horus::msg;
using warehouse_agv::GoToPallet;

namespace {

// The simulated world: the fleet server sends the robot to a pallet down a corridor (GoToPallet);
// the motor controller moves it and publishes where it is on "robot.pose"; at a set time someone
// steps in front of it.
constexpr std::uint32_t kPalletId = 7;
constexpr double kPalletX = 1.2;  // m
// The robot stops this far short of a pallet: where its forks reach it.
constexpr double kForkReach = 0.5;  // m
// The corridor's walls are 1 m to each side of the robot's path.
constexpr double kCorridorHalfWidth = 1.0;  // m

std::uint64_t stamp() { return static_cast<std::uint64_t>(horus::now().count()); }

// The robot's position from the poses published since `last_known` (never a pose an earlier run
// left in the topic, which read_latest() would give before the motor controller's first tick).
double latest_robot_x(horus::Topic<msg::Pose2D>& pose, double last_known) noexcept {
  while (const auto latest = pose.try_recv()) last_known = latest->x;
  return last_known;
}

// Each node narrates through horus's logger: the node's name is attached automatically, the
// lines go to stderr and to the namespace's log ring (read_log(), `horus log`).
void say(const std::string& line) { HORUS_LOG_INFO("%s", line.c_str()); }

// The same from a thread of a node that is not its tick's (an action client's callbacks).
void say_as(std::string_view node, const std::string& line) {
  horus::log::emit(horus::LogLevel::Info, node, line);
}

std::string metres(double x) { return std::to_string(x).substr(0, 4) + " m"; }

// nodes/lidar.hnode: 40 Hz, publishes "scan"; a person steps in front of the robot
// `person_at_s` after the lidar started.
class Lidar : public warehouse_agv::LidarBase {
 public:
  explicit Lidar(double person_at_s) : person_at_s_(person_at_s) {}
  void tick() override {
    robot_x_ = latest_robot_x(pose_, robot_x_);
    const double since_start =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double person = since_start >= person_at_s_ ? robot_x_ + 0.25 : kPalletX;
    const double ahead = std::min(kPalletX, person) - robot_x_;
    msg::LaserScan scan{};
    for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
      const double angle = scan.angle_min + static_cast<double>(i) * scan.angle_increment;
      const double wall = 1.0 / std::max(std::abs(std::sin(angle)), 1e-3);
      const double front =
          std::abs(angle) < 0.2 && std::cos(angle) > 0 ? ahead / std::cos(angle) : 1e9;
      scan.ranges[i] = static_cast<float>(std::min({wall, front, double{scan.range_max}}));
    }
    scan.timestamp_ns = stamp();
    scan_.send(scan);
    if (++count_ % 40 == 1) say(scan.log_summary().substr(0, 96) + "...");
  }

 private:
  double person_at_s_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// nodes/safety.hnode: order 0, every cycle, before the motors tick.
class Safety : public warehouse_agv::SafetyBase {
 public:
  void tick() override {
    const auto scan = scan_.try_recv();
    if (engaged_) {
      // Held every cycle, not sent once: a motor controller that starts after the stop (a
      // process of its own, restarted) halts on its first tick too.
      stop_.timestamp_ns = stamp();
      estop_.send(stop_);
      return;
    }
    if (!scan) return;
    const auto closest = scan->min_range();
    if (closest && *closest < 0.3f) {
      stop_.engaged = 1;
      stop_.reason.assign("obstacle at " + std::to_string(*closest).substr(0, 4) + " m");
      stop_.source.assign("safety");
      stop_.timestamp_ns = stamp();
      estop_.send(stop_);
      engaged_ = true;
      say("EMERGENCY STOP " + stop_.log_summary());
    }
  }
};

// nodes/planner.hnode: 10 Hz on the compute pool. It serves GoToPallet from its tick (the
// action's tick mode): each tick takes the next goal when it has none, ends the goal it has
// (arrived, canceled, stopped by the emergency stop), or plans the path to it and reports the
// distance left.
class Planner : public warehouse_agv::PlannerBase {
 public:
  Planner()
      : navigator_(horus::ActionServerBuilder<GoToPallet>().on_goal(&Planner::decide).build()) {}

  void tick() override {
    robot_x_ = latest_robot_x(pose_, robot_x_);
    if (const auto stop = estop_.try_recv(); stop && stop->engaged)
      estop_reason_ = stop->reason.str();
    if (!goal_ && (goal_ = navigator_.next_goal())) {
      const GoToPallet::Goal& wanted = goal_->goal();
      say("goal: pallet " + std::to_string(wanted.pallet_id) + " at x=" + metres(wanted.x) +
          ", stopping at x=" + metres(wanted.x - kForkReach));
    }
    if (!goal_) return;
    const GoToPallet::Goal& wanted = goal_->goal();
    const double stop_at = wanted.x - kForkReach;
    const double distance = stop_at - robot_x_;
    if (goal_->is_cancel_requested()) {
      send_path(robot_x_);  // the tracker holds the robot where it is
      say("pallet " + std::to_string(wanted.pallet_id) + ": " + goal_->cancel_reason());
      goal_->cancel(result(false, distance));
    } else if (estop_reason_) {
      goal_->abort("emergency stop: " + *estop_reason_, result(false, distance));
    } else if (std::abs(distance) <= wanted.tolerance_m) {
      say("pallet " + std::to_string(wanted.pallet_id) + " reached at x=" + metres(robot_x_));
      goal_->succeed(result(true, distance));
    } else if (distance < 0.0) {
      goal_->abort("pallet " + std::to_string(wanted.pallet_id) + " is behind the robot (x=" +
                       metres(robot_x_) + "), which drives forward only",
                   result(false, distance));
    } else {
      if (!scan_.try_recv()) return;
      send_path(stop_at);
      goal_->publish_feedback({distance, robot_x_});
      return;
    }
    goal_.reset();
  }

 private:
  // Quick and stateless (it runs on the server's thread): the goals the robot cannot drive.
  static horus::GoalDecision decide(const GoToPallet::Goal& goal) {
    if (!(std::abs(goal.y) < kCorridorHalfWidth)) {
      return horus::GoalDecision::reject("pallet " + std::to_string(goal.pallet_id) +
                                         " is off the corridor (y=" + metres(goal.y) +
                                         "; the walls are 1 m to each side)");
    }
    if (!(goal.tolerance_m > 0.0))
      return horus::GoalDecision::reject("tolerance_m must be positive");
    return horus::GoalDecision::accept();
  }

  GoToPallet::Result result(bool reached, double distance) const {
    return {reached, goal_->goal().pallet_id, robot_x_, 0.0, distance};
  }

  void send_path(double goal) {
    msg::PathPlan plan{};
    const double start = robot_x_;
    plan.waypoint_count = 20;
    for (std::size_t i = 0; i < plan.waypoint_count; ++i) {
      plan.waypoint_data[i * 3] =
          static_cast<float>(start + (goal - start) * static_cast<double>(i + 1) / 20.0);
    }
    plan.goal_pose = {static_cast<float>(goal), 0.0f, 0.0f};
    plan.timestamp_ns = stamp();
    path_.send(plan);
    if (++count_ % 10 == 1) say("path to x=" + metres(goal) + ", 20 waypoints");
  }

  horus::ActionServer<GoToPallet> navigator_;
  std::optional<horus::ServerGoal<GoToPallet>> goal_;
  std::optional<std::string> estop_reason_;  // held, as the motor controller holds the stop
};

// nodes/tracker.hnode: 100 Hz; full speed (0.8 m/s) until 0.2 m before the goal.
class Tracker : public warehouse_agv::TrackerBase {
 public:
  void tick() override {
    robot_x_ = latest_robot_x(pose_, robot_x_);
    if (auto plan = path_.try_recv()) goal_ = plan->goal_pose[0];
    const double remaining = goal_ - robot_x_;
    const auto cmd = msg::CmdVel::with_timestamp(
        static_cast<float>(std::clamp(4.0 * remaining, 0.0, 0.8)), 0.0f, stamp());
    cmd_.send(cmd);
    if (++count_ % 50 == 1) say(cmd.log_summary());
  }
};

// nodes/motor.hnode: 1 kHz, 300 us budget, 900 us deadline, Miss::SafeMode.
class Motor : public warehouse_agv::MotorBase {
 public:
  double position() const noexcept { return robot_x_; }

  void tick() override {
    if (auto stop = estop_.try_recv(); stop && stop->engaged && !estopped_) {
      estopped_ = true;
      say("emergency stop: wheels halted at x=" + metres(robot_x_));
    }
    if (auto cmd = cmd_.try_recv()) target_ = std::min(cmd->linear, params().max_speed());
    msg::DifferentialDriveCommand drive{};
    drive.left_velocity = drive.right_velocity = estopped_ ? 0.0f : target_;
    drive.max_acceleration = 1.0f;
    drive.enable = estopped_ ? 0 : 1;
    drive.timestamp_ns = stamp();
    wheels_.send(drive);
    robot_x_ += drive.left_velocity * 1e-3;
    pose_.send(msg::Pose2D{.x = robot_x_, .timestamp_ns = drive.timestamp_ns});
    if (++count_ % 500 == 1) {
      say("wheels " + std::to_string(drive.left_velocity).substr(0, 4) +
          " m/s at x=" + metres(robot_x_) + (drive.enable ? "" : " (disabled)"));
    }
  }
  void enter_safe_state() override {
    target_ = 0.0f;
    ++safe_entries_;
  }
  bool is_safe_state() const override { return target_ == 0.0f || estopped_; }
  void shutdown() override {
    wheels_.send(msg::DifferentialDriveCommand{});
    say("shutdown: wheels disabled (" + std::to_string(safe_entries_) +
        " deadline misses answered by stopping)");
  }
};

// nodes/battery.hnode: 2 Hz.
class Battery : public warehouse_agv::BatteryBase {
 public:
  void tick() override {
    msg::BatteryState state{};
    percentage_ -= 0.4f;
    state.voltage = 22.0f + 3.2f * percentage_ / 100.0f;
    state.current = -2.5f;
    state.percentage = percentage_;
    state.capacity = 40.0f;
    state.charge = 40.0f * percentage_ / 100.0f;
    state.power_supply_status = msg::BatteryState::STATUS_DISCHARGING;
    state.timestamp_ns = stamp();
    battery_.send(state);
    if (state.is_low(20.0f)) say("low battery");
  }
};

// nodes/fleet.hnode: 1 Hz on a thread of its own (async_io), FailurePolicy::Skip. The robot's
// link to the fleet server: it reports telemetry, and passes on the server's order, "go to
// pallet 7" (a GoToPallet goal to the planner), saying what comes back.
class Fleet : public warehouse_agv::FleetBase {
 public:
  void tick() override {
    if (!order_sent_) send_order();
    const auto battery = battery_.read_latest();
    const auto wheels = wheels_.read_latest();
    msg::Heartbeat beat{};
    beat.node_name.assign("agv-07");
    beat.sequence = ++sequence_;
    beat.alive = 1;
    beat.uptime = horus::elapsed().count() / 1e9;
    beat.timestamp_ns = stamp();
    telemetry_.send(beat);
    char line[160];
    std::snprintf(line, sizeof line, "telemetry #%llu: battery %.1f%% %.2f V, wheels %.2f m/s%s",
                  static_cast<unsigned long long>(beat.sequence),
                  battery ? battery->percentage : 0.0f, battery ? battery->voltage : 0.0f,
                  wheels ? wheels->left_velocity : 0.0f,
                  wheels && !wheels->enable ? " (disabled)" : "");
    say(line);
  }

 private:
  // The goal, shared by this node's thread and the client's (which runs the callbacks). The
  // handle is stored once send_goal() returns; the result is read from it once the goal has
  // ended; whichever thread sees both comes second and reports it, once.
  struct Order {
    std::optional<horus::GoalHandle<GoToPallet>> goal;
    std::atomic<bool> stored{false};
    std::atomic<bool> ended{false};
    std::atomic<bool> reported{false};
    unsigned feedback_received = 0;  // the client's thread only
  };

  // Blocks until the planner answers (this node's thread is its own); without a planner yet
  // (a process of its own, still starting), it waits a while (less than the scheduler's
  // watchdog) and tries again next tick.
  void send_order() {
    if (!client_.wait_for_server(std::chrono::milliseconds(300))) {
      if (!waiting_reported_) say("GoToPallet: waiting for the planner to serve it");
      waiting_reported_ = true;
      return;
    }
    const GoToPallet::Goal goal{.pallet_id = kPalletId, .x = kPalletX, .y = 0.0};
    // Weak: the goal's callbacks must not keep alive the handle that holds them.
    const std::weak_ptr<Order> weak = order_;
    horus::GoalCallbacks<GoToPallet> callbacks;
    callbacks.on_feedback = [weak](const GoToPallet::Feedback& feedback) {
      const std::shared_ptr<Order> order = weak.lock();
      // The planner sends feedback every tick (10 Hz): every third is enough to follow.
      if (!order || order->feedback_received++ % 3 != 0) return;
      say_as("fleet", "GoToPallet feedback: " + metres(feedback.distance_m) +
                          " to go, robot at x=" + metres(feedback.x));
    };
    callbacks.on_state = [weak](horus::GoalState state, std::string_view) {
      const std::shared_ptr<Order> order = weak.lock();
      if (!order || !horus::is_terminal(state)) return;
      order->ended = true;
      if (order->stored) report_once(*order);
    };
    auto sent = client_.send_goal(goal, std::chrono::seconds(1), callbacks);
    if (!sent) {
      // The planner went away in between, or did not answer: the next tick tries again.
      say("GoToPallet: the goal was not sent: " + sent.error().to_string());
      return;
    }
    if (sent->state() == horus::GoalState::Rejected) {
      say("GoToPallet pallet " + std::to_string(kPalletId) + ": rejected: " + sent->reason());
    } else {
      say("GoToPallet pallet " + std::to_string(kPalletId) + " at x=" + metres(kPalletX) +
          ": goal " + sent->id().to_string() + " accepted");
      order_->goal = std::move(*sent);
      order_->stored = true;
      if (order_->ended) report_once(*order_);
    }
    order_sent_ = true;
  }

  static void report_once(Order& order) {
    if (order.reported.exchange(true)) return;
    const auto outcome = order.goal->try_result();
    if (!outcome) return;
    const std::string_view state = horus::to_string(outcome->state);
    const GoToPallet::Result& result = outcome->result;
    const bool reason = !outcome->reason.empty();
    char line[320];
    std::snprintf(line, sizeof line,
                  "GoToPallet %.*s%s%s%s: pallet %u %s, robot at x=%.2f m (%.2f m from the "
                  "stopping point)",
                  static_cast<int>(state.size()), state.data(), reason ? " (" : "",
                  outcome->reason.c_str(), reason ? ")" : "", result.pallet_id,
                  result.reached ? "reached" : "not reached", result.x, result.distance_m);
    say_as("fleet", line);
  }

  horus::ActionClient<GoToPallet> client_;
  std::shared_ptr<Order> order_ = std::make_shared<Order>();
  bool order_sent_ = false;
  bool waiting_reported_ = false;
};

// What to run: all seven nodes (the demo) or some of them, the others running in processes of
// their own.
struct Options {
  bool apart = false;                 // only the nodes named by --nodes
  std::vector<std::string> nodes;     // in the order of kNodeNames; all of them by default
  std::optional<double> seconds;      // how long to run; unset: until Ctrl+C or SIGTERM
  std::optional<double> person_at_s;  // when the person steps in front of the robot
};

constexpr std::string_view kNodeNames[] = {"safety", "lidar",   "planner", "tracker",
                                           "motor",  "battery", "fleet"};
constexpr std::string_view kUsage =
    "usage: warehouse_agv [SECONDS]\n"
    "       warehouse_agv --nodes NAME[,NAME...] [--person-at SECONDS] [SECONDS]\n"
    "  The seven nodes in this process for SECONDS (3 by default), or only the nodes named\n"
    "  (safety, lidar, planner, tracker, motor, battery, fleet) until Ctrl+C or SIGTERM, the\n"
    "  others running in processes of their own.\n";

// A positive number of seconds, or nullopt.
std::optional<double> parse_seconds(const std::string& text) {
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !(value > 0.0) || !std::isfinite(value)) return std::nullopt;
  return value;
}

// The options, or an error that says what is wrong with the command line.
std::optional<Options> parse_options(int argc, char** argv, std::string& error) {
  Options options;
  std::vector<std::string> named;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--nodes" || arg == "--person-at") {
      if (i + 1 == argc) {
        error = arg + " needs a value";
        return std::nullopt;
      }
      const std::string value = argv[++i];
      if (arg == "--person-at") {
        options.person_at_s = parse_seconds(value);
        if (!options.person_at_s) {
          error = "--person-at takes a positive number of seconds, not '" + value + "'";
          return std::nullopt;
        }
        continue;
      }
      for (std::size_t start = 0; start <= value.size();) {
        const std::size_t comma = std::min(value.find(',', start), value.size());
        const std::string name = value.substr(start, comma - start);
        if (std::find(std::begin(kNodeNames), std::end(kNodeNames), name) == std::end(kNodeNames)) {
          error = "no node '" + name +
                  "' (the nodes: safety, lidar, planner, tracker, motor, battery, fleet)";
          return std::nullopt;
        }
        named.push_back(name);
        start = comma + 1;
      }
    } else if (arg.starts_with("-")) {
      error = "unknown option '" + arg + "'";
      return std::nullopt;
    } else if (options.seconds) {
      error = "SECONDS given twice (then '" + arg + "')";
      return std::nullopt;
    } else if (!(options.seconds = parse_seconds(arg))) {
      error = "SECONDS is a positive number, not '" + arg + "'";
      return std::nullopt;
    }
  }
  for (const std::string_view name : kNodeNames) {
    if (named.empty() || std::find(named.begin(), named.end(), name) != named.end())
      options.nodes.emplace_back(name);
  }
  options.apart = !named.empty();
  if (!options.apart) {
    // The demo: three seconds, the person in the way after 60% of them.
    options.seconds = options.seconds.value_or(3.0);
    options.person_at_s = options.person_at_s.value_or(*options.seconds * 0.6);
  } else if (!options.person_at_s) {
    // Apart, the other processes take a moment to start: the robot is under way by then.
    options.person_at_s = options.seconds ? *options.seconds * 0.6 : 5.0;
  }
  return options;
}

bool has(const Options& options, std::string_view node) {
  return std::find(options.nodes.begin(), options.nodes.end(), node) != options.nodes.end();
}

}  // namespace

int main(int argc, char** argv) {
  std::string error;
  const std::optional<Options> options = parse_options(argc, argv, error);
  if (!options) {
    std::fprintf(stderr, "warehouse_agv: %s\n%s", error.c_str(), kUsage.data());
    return 2;
  }
  // A namespace of its own, so the demo never mixes with other HORUS programs on the machine.
  setenv("HORUS_NAMESPACE", "warehouse_agv_demo", 0);

  std::string scheduler_name = "warehouse_agv";
  if (options->apart) {
    // Each process its own name (and so its own blackbox file) when the nodes run apart.
    for (const std::string& node : options->nodes) scheduler_name += "-" + node;
  }
  horus::Scheduler sched{horus::SchedulerConfig{}
                             .name(scheduler_name)
                             .tick_rate(1000_hz)
                             .rt(true)
                             .watchdog(500_ms)
                             .blackbox_mb(1)
                             // The demo's topics stay for `horus topic` to read afterwards;
                             // apart, each process cleans up what it created as it ends (a
                             // launch leaves nothing behind).
                             .keep_topics(!options->apart)
                             .max_deadline_misses(1000)};
  // Each node with the order, rate, budget, ... its .hnode file declares.
  std::shared_ptr<Motor> motor;
  if (has(*options, "safety"))
    warehouse_agv::SafetyBase::add_to(sched, std::make_unique<Safety>()).build();
  if (has(*options, "lidar"))
    warehouse_agv::LidarBase::add_to(sched, std::make_unique<Lidar>(*options->person_at_s)).build();
  if (has(*options, "planner")) {
    std::unique_ptr<Planner> planner;
    try {
      planner = std::make_unique<Planner>();
    } catch (const horus::Error& e) {
      // GoToPallet has one server in a namespace: another planner runs there already.
      std::fprintf(stderr, "warehouse_agv: the planner cannot serve GoToPallet: %s\n", e.what());
      return 1;
    }
    warehouse_agv::PlannerBase::add_to(sched, std::move(planner)).build();
  }
  if (has(*options, "tracker"))
    warehouse_agv::TrackerBase::add_to(sched, std::make_unique<Tracker>()).build();
  if (has(*options, "motor")) {
    motor = std::make_shared<Motor>();
    warehouse_agv::MotorBase::add_to(sched, motor).build();
    sched.add_critical_node("motor", 200_ms);
  }
  if (has(*options, "battery"))
    warehouse_agv::BatteryBase::add_to(sched, std::make_unique<Battery>()).build();
  if (has(*options, "fleet"))
    warehouse_agv::FleetBase::add_to(sched, std::make_unique<Fleet>()).build();

  if (!options->apart) {
    std::printf(
        "warehouse_agv: 7 nodes for %.1f s (a person steps in front of the robot at %.1f s)\n",
        *options->seconds, *options->person_at_s);
  } else {
    std::string nodes;
    for (const std::string& node : options->nodes) nodes += (nodes.empty() ? "" : ", ") + node;
    std::printf("warehouse_agv: %s of the 7 nodes, ", nodes.c_str());
    if (options->seconds)
      std::printf("for %.1f s", *options->seconds);
    else
      std::printf("until Ctrl+C or SIGTERM");
    if (has(*options, "lidar"))
      std::printf(" (a person steps in front of the robot at %.1f s)", *options->person_at_s);
    std::printf("\n");
  }
  std::fflush(stdout);
  for (const std::string& degradation : sched.degradations())
    HORUS_LOG_WARN("rt degraded: %s", degradation.c_str());
  const int status = options->seconds
                         ? sched.run_for(std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::duration<double>(*options->seconds)))
                         : sched.run();
  if (motor)
    std::printf("\nrobot stopped at x=%.2f m (pallet at %.1f m)\n", motor->position(), kPalletX);
  std::printf("\n%s", sched.timing_report().c_str());
  return status;
}
