// The warehouse AGV: seven nodes, standard messages, one scheduler. See README.md.
#include <horus/horus.hpp>
#include <horus/msg/battery_state.hpp>
#include <horus/msg/cmd_vel.hpp>
#include <horus/msg/differential_drive_command.hpp>
#include <horus/msg/emergency_stop.hpp>
#include <horus/msg/heartbeat.hpp>
#include <horus/msg/laser_scan.hpp>
#include <horus/msg/path_plan.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

using namespace horus::literals;
namespace msg = horus::msg;

namespace {

// The simulated world the nodes sense and act on: the robot drives along a corridor towards a
// pallet; at `person_at_s` someone steps in front of it.
struct World {
  std::atomic<double> robot_x{0.0};      // m, written by the motor controller only
  std::atomic<double> robot_speed{0.0};  // m/s
  double pallet_x = 4.0;                 // m
  double person_at_s = 0.0;              // s after start
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();

  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  double obstacle_ahead() const {
    const double person = seconds() >= person_at_s ? robot_x.load() + 0.25 : pallet_x;
    return std::min(pallet_x, person) - robot_x.load();
  }
};

std::uint64_t stamp() { return static_cast<std::uint64_t>(horus::now().count()); }

// Each node narrates through horus's logger: the node's name is attached automatically, the
// lines go to stderr and to the namespace's log ring (read_log(), `horus log`).
void say(const std::string& line) { HORUS_LOG_INFO("%s", line.c_str()); }

// Order 10, 40 Hz: a 360-beam scan of the corridor (walls 1 m to each side, the nearest obstacle
// ahead).
class Lidar : public horus::Node {
 public:
  explicit Lidar(const World& world) : world_(world), scan_("scan") {}
  std::string_view name() const override { return "lidar"; }
  void tick() override {
    msg::LaserScan scan{};
    const double ahead = world_.obstacle_ahead();
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
  const World& world_;
  horus::Topic<msg::LaserScan> scan_;
  std::uint64_t count_ = 0;
};

// Order 0, every cycle: an obstacle closer than 30 cm fires the emergency stop before the motors
// tick.
class Safety : public horus::Node {
 public:
  Safety() : scan_("scan"), estop_("emergency.stop") {}
  std::string_view name() const override { return "safety"; }
  void tick() override {
    const auto scan = scan_.try_recv();
    if (!scan || engaged_) return;
    const auto closest = scan->min_range();
    if (closest && *closest < 0.3f) {
      msg::EmergencyStop stop{};
      stop.engaged = 1;
      stop.reason.assign("obstacle at " + std::to_string(*closest).substr(0, 4) + " m");
      stop.source.assign("safety");
      stop.timestamp_ns = stamp();
      estop_.send(stop);
      engaged_ = true;
      say("EMERGENCY STOP " + stop.log_summary());
    }
  }

 private:
  horus::Topic<msg::LaserScan> scan_;
  horus::Topic<msg::EmergencyStop> estop_;
  bool engaged_ = false;
};

// Order 50, 10 Hz on the compute pool: a straight-line plan that stops 0.5 m before the pallet.
class Planner : public horus::Node {
 public:
  explicit Planner(const World& world) : world_(world), scan_("scan"), path_("path") {}
  std::string_view name() const override { return "planner"; }
  void tick() override {
    if (!scan_.try_recv()) return;
    msg::PathPlan plan{};
    const double goal = world_.pallet_x - 0.5;
    const double start = world_.robot_x.load();
    plan.waypoint_count = 20;
    for (std::size_t i = 0; i < plan.waypoint_count; ++i) {
      plan.waypoint_data[i * 3] =
          static_cast<float>(start + (goal - start) * static_cast<double>(i + 1) / 20.0);
    }
    plan.goal_pose = {static_cast<float>(goal), 0.0f, 0.0f};
    plan.timestamp_ns = stamp();
    path_.send(plan);
    if (++count_ % 10 == 1)
      say("path to x=" + std::to_string(goal).substr(0, 4) + " m, 20 waypoints");
  }

 private:
  const World& world_;
  horus::Topic<msg::LaserScan> scan_;
  horus::Topic<msg::PathPlan> path_;
  std::uint64_t count_ = 0;
};

// Order 60, 100 Hz: pure pursuit along the plan, slowing down near the goal.
class Tracker : public horus::Node {
 public:
  explicit Tracker(const World& world) : world_(world), path_("path"), cmd_("cmd_vel") {}
  std::string_view name() const override { return "tracker"; }
  void tick() override {
    if (auto plan = path_.try_recv()) goal_ = plan->goal_pose[0];
    const double remaining = goal_ - world_.robot_x.load();
    const auto cmd = msg::CmdVel::with_timestamp(
        static_cast<float>(std::clamp(0.8 * remaining, 0.0, 0.8)), 0.0f, stamp());
    cmd_.send(cmd);
    if (++count_ % 50 == 1) say(cmd.log_summary());
  }

 private:
  const World& world_;
  horus::Topic<msg::PathPlan> path_;
  horus::Topic<msg::CmdVel> cmd_;
  float goal_ = 0.0f;
  std::uint64_t count_ = 0;
};

// Order 70, 1 kHz, 300 us budget, 900 us deadline: wheel speeds from cmd_vel. A missed deadline
// (Miss::SafeMode) stops the wheels until the next command; the emergency stop halts them for good.
class Motor : public horus::Node {
 public:
  explicit Motor(World& world)
      : world_(world), cmd_("cmd_vel"), estop_("emergency.stop"), wheels_("motor.cmd") {}
  std::string_view name() const override { return "motor"; }
  void tick() override {
    if (auto stop = estop_.try_recv(); stop && stop->engaged && !estopped_) {
      estopped_ = true;
      say("emergency stop: wheels halted at x=" + metres(world_.robot_x.load()));
    }
    if (auto cmd = cmd_.try_recv()) target_ = cmd->linear;
    msg::DifferentialDriveCommand drive{};
    drive.left_velocity = drive.right_velocity = estopped_ ? 0.0f : target_;
    drive.max_acceleration = 1.0f;
    drive.enable = estopped_ ? 0 : 1;
    drive.timestamp_ns = stamp();
    wheels_.send(drive);
    world_.robot_speed = drive.left_velocity;
    world_.robot_x = world_.robot_x.load() + drive.left_velocity * 1e-3;
    if (++count_ % 500 == 1) {
      say("wheels " + std::to_string(drive.left_velocity).substr(0, 4) +
          " m/s at x=" + metres(world_.robot_x.load()) + (drive.enable ? "" : " (disabled)"));
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

 private:
  static std::string metres(double x) { return std::to_string(x).substr(0, 4) + " m"; }

  World& world_;
  horus::Topic<msg::CmdVel> cmd_;
  horus::Topic<msg::EmergencyStop> estop_;
  horus::Topic<msg::DifferentialDriveCommand> wheels_;
  float target_ = 0.0f;
  bool estopped_ = false;
  std::uint64_t safe_entries_ = 0;
  std::uint64_t count_ = 0;
};

// Order 100, 2 Hz: a 24 V pack slowly discharging.
class Battery : public horus::Node {
 public:
  Battery() : battery_("battery") {}
  std::string_view name() const override { return "battery"; }
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

 private:
  horus::Topic<msg::BatteryState> battery_;
  float percentage_ = 81.0f;
};

// Order 200, 1 Hz, off the tick loop (blocking I/O in real life); tolerates failures (Skip).
class Fleet : public horus::Node {
 public:
  Fleet() : battery_("battery"), wheels_("motor.cmd"), telemetry_("fleet.telemetry") {}
  std::string_view name() const override { return "fleet"; }
  void tick() override {
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
  horus::Topic<msg::BatteryState> battery_;
  horus::Topic<msg::DifferentialDriveCommand> wheels_;
  horus::Topic<msg::Heartbeat> telemetry_;
  std::uint64_t sequence_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  const double seconds = argc > 1 ? std::atof(argv[1]) : 3.0;
  // A namespace of its own, so the demo never mixes with other HORUS programs on the machine.
  setenv("HORUS_NAMESPACE", "warehouse_agv_demo", 0);
  World world;
  world.person_at_s = seconds * 0.6;

  horus::Scheduler sched{horus::SchedulerConfig{}
                             .name("warehouse_agv")
                             .tick_rate(1000_hz)
                             .rt(true)
                             .watchdog(500_ms)
                             .blackbox_mb(1)
                             .keep_topics(true)  // `horus topic` may still read them afterwards
                             .max_deadline_misses(1000)};
  sched.add(std::make_unique<Safety>()).order(0).rate(1000_hz).build();
  sched.add(std::make_unique<Lidar>(world)).order(10).rate(40_hz).build();
  sched.add(std::make_unique<Planner>(world)).order(50).rate(10_hz).compute().build();
  sched.add(std::make_unique<Tracker>(world)).order(60).rate(100_hz).build();
  sched.add(std::make_unique<Motor>(world))
      .order(70)
      .rate(1000_hz)
      .budget(300_us)
      .deadline(900_us)
      .on_miss(horus::Miss::SafeMode)
      .build();
  sched.add(std::make_unique<Battery>()).order(100).rate(2_hz).build();
  sched.add(std::make_unique<Fleet>())
      .order(200)
      .rate(1_hz)
      .async_io()
      .failure_policy(horus::FailurePolicy::Skip{})
      .build();
  sched.add_critical_node("motor", 200_ms);

  std::printf(
      "warehouse_agv: 7 nodes for %.1f s (a person steps in front of the robot at %.1f s)\n",
      seconds, world.person_at_s);
  std::fflush(stdout);
  for (const std::string& degradation : sched.degradations())
    HORUS_LOG_WARN("rt degraded: %s", degradation.c_str());
  const int status = sched.run_for(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::duration<double>(seconds)));
  std::printf("\nrobot stopped at x=%.2f m (pallet at %.1f m)\n\n%s", world.robot_x.load(),
              world.pallet_x, sched.timing_report().c_str());
  return status;
}
