# Cap'n Proto equivalent of bench/generator/schemas/bench_msgs (35 structs, 5 enums).
# Cap'n Proto has no fixed-size arrays or fixed-capacity strings: [T; N] becomes List(T),
# string<N> becomes Text. See ../README.md for the other differences.
@0xdc41a93897f5f109;

using Cxx = import "/capnp/c++.capnp";
$Cxx.namespace("bench_msgs");

# --- geometry ---

struct Header {
  stampNs @0 :UInt64;
  seq @1 :UInt32;
  frameId @2 :Text;
}

struct Vector3 {
  x @0 :Float64;
  y @1 :Float64;
  z @2 :Float64;
}

struct Point3 {
  x @0 :Float64;
  y @1 :Float64;
  z @2 :Float64;
}

struct Quaternion {
  x @0 :Float64;
  y @1 :Float64;
  z @2 :Float64;
  w @3 :Float64 = 1.0;
}

struct Pose {
  position @0 :Point3;
  orientation @1 :Quaternion;
}

struct Pose2D {
  x @0 :Float64;
  y @1 :Float64;
  theta @2 :Float64;
}

struct Twist {
  linear @0 :Vector3;
  angular @1 :Vector3;
}

struct Transform {
  translation @0 :Vector3;
  rotation @1 :Quaternion;
}

struct TransformStamped {
  header @0 :Header;
  childFrameId @1 :Text;
  transform @2 :Transform;
}

struct PoseStamped {
  header @0 :Header;
  pose @1 :Pose;
}

struct TwistStamped {
  header @0 :Header;
  twist @1 :Twist;
}

struct Wrench {
  force @0 :Vector3;
  torque @1 :Vector3;
}

struct WrenchStamped {
  header @0 :Header;
  wrench @1 :Wrench;
}

# --- sensors ---

struct Imu {
  header @0 :Header;
  orientation @1 :Quaternion;
  orientationCovariance @2 :List(Float64);
  angularVelocity @3 :Vector3;
  angularVelocityCovariance @4 :List(Float64);
  linearAcceleration @5 :Vector3;
  linearAccelerationCovariance @6 :List(Float64);
}

struct LaserScan {
  const maxPoints :UInt32 = 360;
  header @0 :Header;
  angleMin @1 :Float32;
  angleMax @2 :Float32;
  angleIncrement @3 :Float32;
  timeIncrement @4 :Float32;
  scanTime @5 :Float32;
  rangeMin @6 :Float32;
  rangeMax @7 :Float32;
  ranges @8 :List(Float32);
  intensities @9 :List(Float32);
}

struct GpsFix {
  header @0 :Header;
  latitude @1 :Float64;
  longitude @2 :Float64;
  altitude @3 :Float64;
  positionCovariance @4 :List(Float64);
  covarianceType @5 :UInt8;
  status @6 :Int8;
  satellites @7 :UInt8;
}

struct Temperature {
  header @0 :Header;
  temperature @1 :Float64;
  variance @2 :Float64;
}

struct RangeSensor {
  const ultrasound :UInt8 = 0;
  const infrared :UInt8 = 1;
  header @0 :Header;
  radiationType @1 :UInt8;
  fieldOfView @2 :Float32;
  minRange @3 :Float32;
  maxRange @4 :Float32;
  range @5 :Float32;
}

enum BatteryStatus {
  unknown @0;
  charging @1;
  discharging @2;
  notCharging @3;
  full @4;
}

struct BatteryState {
  stampNs @0 :UInt64;
  voltage @1 :Float32;
  current @2 :Float32;
  charge @3 :Float32;
  capacity @4 :Float32;
  percentage @5 :Float32;
  temperature @6 :Float32;
  cellVoltages @7 :List(Float32);
  status @8 :BatteryStatus;
  present @9 :Bool;
}

struct WheelOdometry {
  stampNs @0 :UInt64;
  leftTicks @1 :Int64;
  rightTicks @2 :Int64;
  leftVelocity @3 :Float32;
  rightVelocity @4 :Float32;
}

struct Odometry {
  header @0 :Header;
  childFrameId @1 :Text;
  pose @2 :Pose;
  poseCovariance @3 :List(Float64);
  twist @4 :Twist;
  twistCovariance @5 :List(Float64);
}

# --- control ---

enum ControlMode {
  idle @0;
  position @1;
  velocity @2;
  torque @3;
}

enum GripperMode {
  open @0;
  close @1;
  hold @2;
}

struct CmdVel {
  stampNs @0 :UInt64;
  linear @1 :Float32;
  angular @2 :Float32;
}

struct MotorCommand {
  stampNs @0 :UInt64;
  motorId @1 :UInt8;
  mode @2 :ControlMode = velocity;
  target @3 :Float64;
  maxVelocity @4 :Float64;
  maxAcceleration @5 :Float64;
  feedForward @6 :Float64;
  enable @7 :Bool;
}

struct MotorFeedback {
  stampNs @0 :UInt64;
  motorId @1 :UInt32;
  position @2 :Float64;
  velocity @3 :Float32;
  current @4 :Float32;
  temperatureC @5 :Float32 = 20.0;
  mode @6 :ControlMode;
  faultCode @7 :UInt16;
}

struct JointState {
  header @0 :Header;
  names @1 :List(Text);
  positions @2 :List(Float64);
  velocities @3 :List(Float64);
  efforts @4 :List(Float64);
  count @5 :UInt8;
}

struct GripperCommand {
  stampNs @0 :UInt64;
  position @1 :Float32;
  maxEffort @2 :Float32;
  mode @3 :GripperMode;
}

struct Goal2D {
  header @0 :Header;
  target @1 :Pose2D;
  toleranceXy @2 :Float32;
  toleranceTheta @3 :Float32;
  timeoutMs @4 :UInt32;
}

struct EmergencyStop {
  stampNs @0 :UInt64;
  engaged @1 :Bool;
  source @2 :Text;
  reason @3 :Text;
}

# --- system ---

enum DiagnosticLevel {
  ok @0;
  warn @1;
  error @2;
  stale @3;
}

enum LogLevel {
  debug @0;
  info @1;
  warn @2;
  error @3;
  fatal @4;
}

struct DiagnosticStatus {
  stampNs @0 :UInt64;
  level @1 :DiagnosticLevel;
  name @2 :Text;
  message @3 :Text;
  hardwareId @4 :Text;
  values @5 :List(Float32);
}

struct Heartbeat {
  stampNs @0 :UInt64;
  nodeName @1 :Text;
  sequence @2 :UInt64;
  uptimeMs @3 :UInt64;
  healthy @4 :Bool;
}

struct LogMessage {
  stampNs @0 :UInt64;
  level @1 :LogLevel;
  node @2 :Text;
  text @3 :Text;
  file @4 :Text;
  line @5 :UInt32;
}

# --- perception ---

struct Image {
  header @0 :Header;
  height @1 :UInt32;
  width @2 :UInt32;
  encoding @3 :Text;
  step @4 :UInt32;
  data @5 :Data;
}

struct PointCloud {
  header @0 :Header;
  width @1 :UInt32;
  height @2 :UInt32;
  pointStep @3 :UInt32;
  fieldNames @4 :List(Text);
  data @5 :Data;
  isDense @6 :Bool;
}

struct Path {
  header @0 :Header;
  poses @1 :List(PoseStamped);
}

struct OccupancyGrid {
  header @0 :Header;
  resolution @1 :Float32;
  width @2 :UInt32;
  height @3 :UInt32;
  origin @4 :Pose;
  data @5 :List(Int8);
}
