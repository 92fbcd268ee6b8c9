// Seed 001's drone flight controller in C++: IMU fusion, an inner attitude loop and an outer
// position loop at different rates on one scheduler, ESC output with a hard deadline, and a
// telemetry log. The hardware calls are stubs over a simulated altitude. See README.md.
//
//   drone_flight [seconds]   (default: until Ctrl+C)
#include <horus/horus.hpp>
#include <horus/msg/imu.hpp>
#include <horus/msg/joint_command.hpp>
#include <horus/msg/nav_sat_fix.hpp>
#include <horus/msg/trajectory_point.hpp>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>

using namespace horus::literals;
namespace msg = horus::msg;

namespace {

// The stubbed hardware: motors lift the drone, the GPS and the IMU read it back.
struct Airframe {
  std::atomic<double> altitude{9.0};  // m, written by the ESC only
  std::atomic<double> thrust{0.0};    // mean motor command
  std::atomic<long> esc_writes{0};
};

double seconds(std::chrono::nanoseconds d) { return std::chrono::duration<double>(d).count(); }

msg::Imu read_imu_hardware() {
  msg::Imu raw{};
  raw.angular_velocity = {0.0, 0.0, 0.1};
  raw.linear_acceleration = {0.0, 0.0, 9.81};
  return raw;
}

/// Orientation from the gyro alone: enough for a stub that does not tilt.
msg::Imu complementary_filter(msg::Imu raw) {
  raw.orientation = {0.0, 0.0, 0.0, 1.0};
  raw.timestamp_ns = horus::timestamp_now();
  return raw;
}

/// Four motor commands from the attitude (yaw rate) and the collective thrust of the setpoint.
msg::JointCommand pid_control(const msg::Imu& imu, const msg::TrajectoryPoint& setpoint,
                              double delta) {
  msg::JointCommand motors{};
  motors.joint_count = 4;
  for (std::size_t i = 0; i < 4; ++i) {
    motors.efforts[i] = setpoint.acceleration[2] + imu.angular_velocity[2] * delta;
  }
  motors.timestamp_ns = horus::timestamp_now();
  return motors;
}

/// Collective thrust towards the waypoint's altitude.
msg::TrajectoryPoint position_pid(const msg::NavSatFix& gps, const msg::TrajectoryPoint& waypoint,
                                  double /*delta*/) {
  msg::TrajectoryPoint setpoint{};
  setpoint.acceleration[2] = 0.5 + (waypoint.position[2] - gps.altitude) * 0.1;
  return setpoint;
}

msg::TrajectoryPoint current_waypoint() {
  msg::TrajectoryPoint waypoint{};
  waypoint.position = {0.0, 0.0, 10.0};
  return waypoint;
}

// Read IMU at 400 Hz.
class ImuRead : public horus::Node {
 public:
  std::string_view name() const override { return "imu"; }
  void tick() override { imu_.send(complementary_filter(read_imu_hardware())); }

 private:
  horus::Topic<msg::Imu> imu_{"imu"};
};

// Inner loop: attitude PID at 400 Hz, on the latest setpoint of the outer loop.
class AttitudeControl : public horus::Node {
 public:
  std::string_view name() const override { return "attitude"; }
  void tick() override {
    if (auto sp = setpoint_.try_recv()) held_setpoint_ = *sp;
    const auto imu = imu_.try_recv();
    if (!imu || !held_setpoint_) return;
    const double delta = seconds(horus::dt());
    motor_cmd_.send(pid_control(*imu, *held_setpoint_, delta));
  }
  void enter_safe_state() override {
    msg::JointCommand idle{};
    idle.joint_count = 4;
    motor_cmd_.send(idle);  // hover power off: better on the ground than flying blind
  }

 private:
  horus::Topic<msg::Imu> imu_{"imu"};
  horus::Topic<msg::TrajectoryPoint> setpoint_{"setpoint"};
  horus::Topic<msg::JointCommand> motor_cmd_{"motor_cmd"};
  std::optional<msg::TrajectoryPoint> held_setpoint_;
};

// Outer loop: position PID at 50 Hz.
class PositionControl : public horus::Node {
 public:
  std::string_view name() const override { return "position"; }
  void tick() override {
    const auto gps = gps_.try_recv();
    if (!gps) return;
    const auto waypoint = waypoint_.try_recv();
    setpoint_.send(
        position_pid(*gps, waypoint ? *waypoint : current_waypoint(), seconds(horus::dt())));
  }

 private:
  horus::Topic<msg::NavSatFix> gps_{"gps"};
  horus::Topic<msg::TrajectoryPoint> waypoint_{"waypoint"};
  horus::Topic<msg::TrajectoryPoint> setpoint_{"setpoint"};
};

// ESC output at 400 Hz with a hard deadline.
class MotorOutput : public horus::Node {
 public:
  explicit MotorOutput(Airframe& airframe) : airframe_(airframe) {}
  std::string_view name() const override { return "esc"; }
  void tick() override {
    if (const auto cmd = motor_cmd_.try_recv()) write_esc(*cmd);
  }
  void shutdown() override { airframe_.thrust = 0.0; }  // motors off on the way out

 private:
  void write_esc(const msg::JointCommand& cmd) {
    double mean = 0.0;
    for (std::size_t i = 0; i < 4; ++i) mean += cmd.efforts[i] / 4.0;
    airframe_.thrust = mean;
    // 0.5 hovers; more climbs. 2.5 ms per ESC period.
    airframe_.altitude = airframe_.altitude + (mean - 0.5) * 0.0025;
    airframe_.esc_writes.fetch_add(1);
  }
  Airframe& airframe_;
  horus::Topic<msg::JointCommand> motor_cmd_{"motor_cmd"};
};

// Log to SD card at 10 Hz (here: the "log" topic and a line now and then).
class TelemetryLog : public horus::Node {
 public:
  std::string_view name() const override { return "logger"; }
  void tick() override {
    if (auto imu = imu_.try_recv()) {
      imu->timestamp_ns = horus::timestamp_now();
      log_.send(*imu);
      if (horus::tick_index() % 10 == 0) {
        HORUS_LOG_INFO("t %.3f s, tick %llu, yaw rate %.2f rad/s", seconds(horus::elapsed()),
                       static_cast<unsigned long long>(horus::tick_index()),
                       imu->angular_velocity[2]);
      }
    }
  }

 private:
  horus::Topic<msg::Imu> imu_{"imu"};
  horus::Topic<msg::Imu> log_{"log"};
};

// The GPS receiver: the stub the seed's position loop reads "gps" from.
class GpsReceiver : public horus::Node {
 public:
  explicit GpsReceiver(const Airframe& airframe) : airframe_(airframe) {}
  std::string_view name() const override { return "gps"; }
  void tick() override {
    msg::NavSatFix fix{};
    fix.status = msg::NavSatFix::STATUS_FIX;
    fix.altitude = airframe_.altitude;
    gps_.send(fix);
  }

 private:
  const Airframe& airframe_;
  horus::Topic<msg::NavSatFix> gps_{"gps"};
};

}  // namespace

int main(int argc, char** argv) {
  std::optional<std::chrono::nanoseconds> duration;
  if (argc > 1) {
    duration = std::chrono::duration_cast<std::chrono::nanoseconds>(
        std::chrono::duration<double>(std::strtod(argv[1], nullptr)));
  }
  Airframe airframe;
  auto imu = horus::RunNode(std::make_shared<ImuRead>()).rate(400_hz).order(0).core(0);
  auto att = horus::RunNode(std::make_shared<AttitudeControl>())
                 .rate(400_hz)
                 .order(10)
                 .budget(200_us)
                 .deadline(500_us)
                 .on_miss(horus::Miss::SafeMode)
                 .core(1);
  auto pos = horus::RunNode(std::make_shared<PositionControl>()).rate(50_hz).order(20);
  auto esc = horus::RunNode(std::make_shared<MotorOutput>(airframe))
                 .rate(400_hz)
                 .order(30)
                 .budget(100_us)
                 .deadline(200_us)
                 .on_miss(horus::Miss::Stop)
                 .core(1);
  auto logger = horus::RunNode(std::make_shared<TelemetryLog>()).rate(10_hz).order(100);
  auto gps = horus::RunNode(std::make_shared<GpsReceiver>(airframe)).rate(10_hz).order(5);

  const int status = horus::run({imu, att, pos, esc, logger, gps},
                                horus::SchedulerConfig{}
                                    .tick_rate(400_hz)
                                    .rt(true)
                                    .watchdog(100_ms)
                                    .blackbox_mb(8)
                                    .max_deadline_misses(10)
                                    .cores({0, 1}),
                                duration);
  // An ESC that misses its deadline stops the flight (on_miss Stop), as the seed asks: status 1.
  std::printf("drone_flight: flight over (status %d): %ld ESC writes, altitude %.2f m\n", status,
              airframe.esc_writes.load(), airframe.altitude.load());
  return status;
}
