// The warehouse AGV: seven nodes, standard messages, one scheduler. See README.md.
// Each node is declared in nodes/<name>.hnode (its topics, data and scheduling settings);
// horus-gen makes the base classes (warehouse_agv::LidarBase, ...), this file writes their ticks.
#include <horus/horus.hpp>
#include <warehouse_agv.hpp>

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

// nodes/lidar.hnode: 40 Hz, publishes "scan".
class Lidar : public warehouse_agv::LidarBase {
 public:
  explicit Lidar(const World& world) : world_(world) {}
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
};

// nodes/safety.hnode: order 0, every cycle, before the motors tick.
class Safety : public warehouse_agv::SafetyBase {
 public:
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
};

// nodes/planner.hnode: 10 Hz on the compute pool.
class Planner : public warehouse_agv::PlannerBase {
 public:
  explicit Planner(const World& world) : world_(world) {}
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
};

// nodes/tracker.hnode: 100 Hz.
class Tracker : public warehouse_agv::TrackerBase {
 public:
  explicit Tracker(const World& world) : world_(world) {}
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
};

// nodes/motor.hnode: 1 kHz, 300 us budget, 900 us deadline, Miss::SafeMode.
class Motor : public warehouse_agv::MotorBase {
 public:
  explicit Motor(World& world) : world_(world) {}
  void tick() override {
    if (auto stop = estop_.try_recv(); stop && stop->engaged && !estopped_) {
      estopped_ = true;
      say("emergency stop: wheels halted at x=" + metres(world_.robot_x.load()));
    }
    if (auto cmd = cmd_.try_recv()) target_ = std::min(cmd->linear, params().max_speed());
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

// nodes/fleet.hnode: 1 Hz on a thread of its own (async_io), FailurePolicy::Skip.
class Fleet : public warehouse_agv::FleetBase {
 public:
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
  // Each node with the order, rate, budget, ... its .hnode file declares.
  warehouse_agv::SafetyBase::add_to(sched, std::make_unique<Safety>()).build();
  warehouse_agv::LidarBase::add_to(sched, std::make_unique<Lidar>(world)).build();
  warehouse_agv::PlannerBase::add_to(sched, std::make_unique<Planner>(world)).build();
  warehouse_agv::TrackerBase::add_to(sched, std::make_unique<Tracker>(world)).build();
  warehouse_agv::MotorBase::add_to(sched, std::make_unique<Motor>(world)).build();
  warehouse_agv::BatteryBase::add_to(sched, std::make_unique<Battery>()).build();
  warehouse_agv::FleetBase::add_to(sched, std::make_unique<Fleet>()).build();
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
