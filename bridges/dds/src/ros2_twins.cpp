#include "horus/dds/ros2_twins.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <horus/msg/cmd_vel.hpp>
#include <horus/msg/imu.hpp>
#include <horus/msg/laser_scan.hpp>
#include <horus/msg/odometry.hpp>
#include <horus/msg/pose_stamped.hpp>
#include <horus/msg/twist.hpp>

namespace horus::dds_bridge {
namespace {

constexpr std::uint64_t kNanos = 1'000'000'000;

// A twin's body, member by member, XCDR1 little-endian: each number at its alignment (at most
// 8) from the start of the body.
class CdrOut {
 public:
  explicit CdrOut(std::vector<std::byte>& sample) : out_(sample) {
    out_.assign({std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0}});
  }

  template <typename T>
  void number(T value) {
    align(sizeof(T));
    const auto* bytes = reinterpret_cast<const std::byte*>(&value);
    out_.insert(out_.end(), bytes, bytes + sizeof(T));
  }
  template <typename T, std::size_t N>
  void numbers(const std::array<T, N>& values) {
    for (const T value : values) number(value);
  }
  void string(std::string_view text) {
    number(static_cast<std::uint32_t>(text.size() + 1));
    const auto* bytes = reinterpret_cast<const std::byte*>(text.data());
    out_.insert(out_.end(), bytes, bytes + text.size());
    out_.push_back(std::byte{0});
  }
  // The padding to a multiple of 4, counted in the encapsulation's options.
  void finish() {
    const std::size_t padding = (4 - (out_.size() - 4) % 4) % 4;
    out_.resize(out_.size() + padding);
    out_[3] = static_cast<std::byte>(padding);
  }

 private:
  void align(std::size_t size) {
    const std::size_t body = out_.size() - 4;
    out_.resize(out_.size() +
                (std::min<std::size_t>(size, 8) - body % std::min<std::size_t>(size, 8)) %
                    std::min<std::size_t>(size, 8));
  }
  std::vector<std::byte>& out_;
};

// Reads a twin's body; throws std::invalid_argument saying what does not fit.
class CdrIn {
 public:
  CdrIn(std::span<const std::byte> body, bool little) : body_(body), little_(little) {}

  template <typename T>
  T number() {
    at_ += (sizeof(T) - at_ % sizeof(T)) % sizeof(T);
    const std::span<const std::byte> bytes = raw(sizeof(T));
    std::array<std::byte, sizeof(T)> copy{};
    std::copy(bytes.begin(), bytes.end(), copy.begin());
    if (little_ != (std::endian::native == std::endian::little)) {
      std::reverse(copy.begin(), copy.end());
    }
    T value;
    std::memcpy(&value, copy.data(), sizeof(T));
    return value;
  }
  template <typename T, std::size_t N>
  void numbers(std::array<T, N>& values) {
    for (T& value : values) value = number<T>();
  }
  std::uint32_t count() {
    const auto value = number<std::uint32_t>();
    if (value > body_.size() - at_) {
      throw std::invalid_argument("a count of " + std::to_string(value) + " at offset " +
                                  std::to_string(at_ - 4) + " runs past the " +
                                  std::to_string(body_.size()) + "-byte body");
    }
    return value;
  }
  std::string string() {
    const std::uint32_t size = count();
    if (size == 0) {
      throw std::invalid_argument("a string at offset " + std::to_string(at_ - 4) +
                                  " has length 0 (no NUL)");
    }
    const std::span<const std::byte> bytes = raw(size);
    return {reinterpret_cast<const char*>(bytes.data()), size - 1};
  }
  std::size_t left() const { return body_.size() - at_; }

 private:
  std::span<const std::byte> raw(std::size_t size) {
    if (at_ + size > body_.size()) {
      throw std::invalid_argument(std::to_string(size) + " bytes wanted at offset " +
                                  std::to_string(at_) + " of a " + std::to_string(body_.size()) +
                                  "-byte body");
    }
    const std::span<const std::byte> out = body_.subspan(at_, size);
    at_ += size;
    return out;
  }
  std::span<const std::byte> body_;
  bool little_;
  std::size_t at_ = 0;
};

std::uint64_t now_nanos() {
  return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                        std::chrono::system_clock::now().time_since_epoch())
                                        .count());
}

// std_msgs/Header: builtin_interfaces/Time (int32 sec, uint32 nanosec), then frame_id.
void write_header(CdrOut& out, std::uint64_t nanos, std::string_view frame_id = "") {
  out.number(static_cast<std::int32_t>(nanos / kNanos));
  out.number(static_cast<std::uint32_t>(nanos % kNanos));
  out.string(frame_id);
}

struct Header {
  std::uint64_t stamp = 0;  // a stamp before 1970 counts as 0
  std::string frame_id;
};

Header read_header(CdrIn& in) {
  const auto sec = in.number<std::int32_t>();
  const auto nanosec = in.number<std::uint32_t>();
  const std::int64_t nanos = std::int64_t{sec} * static_cast<std::int64_t>(kNanos) + nanosec;
  return {static_cast<std::uint64_t>(std::max<std::int64_t>(0, nanos)), in.string()};
}

template <std::size_t N>
void fit(FixedString<N>& into, const char* what, const std::string& value) {
  if (!into.try_assign(value)) {
    throw std::invalid_argument(std::string(what) + " '" + value +
                                "' is longer than HORUS's string<" + std::to_string(N) + ">");
  }
}

// -- geometry_msgs/Twist <- CmdVel (planar: linear.x, angular.z), Twist (3D) ------------------

void write(CdrOut& out, const msg::CmdVel& message) {
  for (const double value : {double{message.linear}, 0.0, 0.0, 0.0, 0.0, double{message.angular}}) {
    out.number(value);
  }
}
void read(CdrIn& in, msg::CmdVel& message) {
  std::array<double, 6> values{};
  in.numbers(values);
  message.linear = static_cast<float>(values[0]);
  message.angular = static_cast<float>(values[5]);
  message.stamp_nanos = now_nanos();  // Twist has no stamp: the time it arrived
}

void write(CdrOut& out, const msg::Twist& message) {
  out.numbers(message.linear);
  out.numbers(message.angular);
}
void read(CdrIn& in, msg::Twist& message) {
  in.numbers(message.linear);
  in.numbers(message.angular);
  message.timestamp_ns = now_nanos();
}

// -- sensor_msgs/Imu <- Imu (same fields; no frame) -------------------------------------------

void write(CdrOut& out, const msg::Imu& message) {
  write_header(out, message.timestamp_ns);
  out.numbers(message.orientation);
  out.numbers(message.orientation_covariance);
  out.numbers(message.angular_velocity);
  out.numbers(message.angular_velocity_covariance);
  out.numbers(message.linear_acceleration);
  out.numbers(message.linear_acceleration_covariance);
}
void read(CdrIn& in, msg::Imu& message) {
  message.timestamp_ns = read_header(in).stamp;
  in.numbers(message.orientation);
  in.numbers(message.orientation_covariance);
  in.numbers(message.angular_velocity);
  in.numbers(message.angular_velocity_covariance);
  in.numbers(message.linear_acceleration);
  in.numbers(message.linear_acceleration_covariance);
}

// -- sensor_msgs/LaserScan <- LaserScan (360 ranges; no intensities, no frame) -----------------

void write(CdrOut& out, const msg::LaserScan& message) {
  write_header(out, message.timestamp_ns);
  for (const float value :
       {message.angle_min, message.angle_max, message.angle_increment, message.time_increment,
        message.scan_time, message.range_min, message.range_max}) {
    out.number(value);
  }
  out.number(static_cast<std::uint32_t>(message.ranges.size()));
  out.numbers(message.ranges);
  out.number(std::uint32_t{0});  // intensities
}
void read(CdrIn& in, msg::LaserScan& message) {
  message.timestamp_ns = read_header(in).stamp;
  for (float* field :
       {&message.angle_min, &message.angle_max, &message.angle_increment, &message.time_increment,
        &message.scan_time, &message.range_min, &message.range_max}) {
    *field = in.number<float>();
  }
  const std::uint32_t ranges = in.count();
  if (ranges > message.ranges.size()) {
    throw std::invalid_argument("a scan of " + std::to_string(ranges) +
                                " ranges does not fit HORUS's " +
                                std::to_string(message.ranges.size()));
  }
  message.ranges.fill(0.0F);  // 0: no reading
  for (std::uint32_t i = 0; i < ranges; ++i) message.ranges[i] = in.number<float>();
  const std::uint32_t intensities = in.count();  // HORUS has none
  for (std::uint32_t i = 0; i < intensities; ++i) in.number<float>();
}

// -- nav_msgs/Odometry <- Odometry (planar pose: z 0, orientation a yaw) ----------------------

void write(CdrOut& out, const msg::Odometry& message) {
  write_header(out, message.timestamp_ns, message.frame_id.view());
  out.string(message.child_frame_id.view());
  const msg::Pose2D& pose = message.pose;
  for (const double value :
       {pose.x, pose.y, 0.0, 0.0, 0.0, std::sin(pose.theta / 2), std::cos(pose.theta / 2)}) {
    out.number(value);
  }
  out.numbers(message.pose_covariance);
  write(out, message.twist);
  out.numbers(message.twist_covariance);
}
void read(CdrIn& in, msg::Odometry& message) {
  const Header header = read_header(in);
  message.timestamp_ns = message.pose.timestamp_ns = message.twist.timestamp_ns = header.stamp;
  fit(message.frame_id, "frame_id", header.frame_id);
  fit(message.child_frame_id, "child_frame_id", in.string());
  std::array<double, 7> pose{};
  in.numbers(pose);
  const auto [x, y, z, w] = std::array{pose[3], pose[4], pose[5], pose[6]};
  message.pose.x = pose[0];
  message.pose.y = pose[1];
  message.pose.theta = std::atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));
  in.numbers(message.pose_covariance);
  in.numbers(message.twist.linear);
  in.numbers(message.twist.angular);
  in.numbers(message.twist_covariance);
}

// -- geometry_msgs/PoseStamped <- PoseStamped (same fields) -----------------------------------

void write(CdrOut& out, const msg::PoseStamped& message) {
  write_header(out, message.timestamp_ns, message.frame_id.view());
  const msg::Point3& position = message.pose.position;
  const msg::Quaternion& orientation = message.pose.orientation;
  for (const double value : {position.x, position.y, position.z, orientation.x, orientation.y,
                             orientation.z, orientation.w}) {
    out.number(value);
  }
}
void read(CdrIn& in, msg::PoseStamped& message) {
  const Header header = read_header(in);
  message.timestamp_ns = message.pose.timestamp_ns = header.stamp;
  fit(message.frame_id, "frame_id", header.frame_id);
  msg::Point3& position = message.pose.position;
  msg::Quaternion& orientation = message.pose.orientation;
  for (double* field : {&position.x, &position.y, &position.z, &orientation.x, &orientation.y,
                        &orientation.z, &orientation.w}) {
    *field = in.number<double>();
  }
}

// -- tf2_msgs/TFMessage <- StampedTransform (geometry_msgs/TransformStamped each) -------------

constexpr std::string_view kTfMessage = "tf2_msgs/msg/TFMessage";

// tf2 accepts frame ids with one leading '/' (ROS 1's style); HORUS names have none.
std::string frame_id(std::string name) {
  if (name.starts_with('/')) name.erase(0, 1);
  return name;
}

void write(CdrOut& out, const StampedTransform& transform) {
  write_header(out, static_cast<std::uint64_t>(std::max<std::int64_t>(0, transform.stamp.count())),
               transform.parent);
  out.string(transform.child);
  const Vector3& t = transform.transform.translation;
  const Quaternion& q = transform.transform.rotation;
  for (const double value : {t.x, t.y, t.z, q.x, q.y, q.z, q.w}) out.number(value);
}
void read(CdrIn& in, StampedTransform& transform) {
  Header header = read_header(in);
  transform.stamp = std::chrono::nanoseconds(header.stamp);
  transform.parent = frame_id(std::move(header.frame_id));
  transform.child = frame_id(in.string());
  Vector3& t = transform.transform.translation;
  Quaternion& q = transform.transform.rotation;
  for (double* field : {&t.x, &t.y, &t.z, &q.x, &q.y, &q.z, &q.w}) *field = in.number<double>();
}

std::string hex(std::span<const std::byte> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  for (const std::byte b : bytes) {
    out += kDigits[std::to_integer<unsigned>(b) >> 4];
    out += kDigits[std::to_integer<unsigned>(b) & 0xf];
  }
  return out;
}

// Why `sample` is not an XCDR1 sample of `ros2` (its encapsulation header), or empty.
std::string not_plain_cdr(std::span<const std::byte> sample, std::string_view ros2) {
  if (sample.size() < 4) {
    return "a CDR sample of " + std::to_string(sample.size()) +
           " bytes has no encapsulation header";
  }
  const auto scheme = std::to_integer<unsigned>(sample[1]);
  if (sample[0] != std::byte{0} || scheme > 1) {
    return "encapsulation " + hex(sample.first(2)) +
           (scheme >= 6 && scheme <= 11 && sample[0] == std::byte{0}
                ? " is XCDR2, and the bridge reads XCDR1 (plain CDR) only: the writer must "
                  "offer XCDR1 (its data representation QoS)"
                : " is not plain CDR (XCDR1): the writer's type is not " + std::string(ros2));
  }
  return {};
}

template <typename Message>
class TwinConversion final : public Conversion {
 public:
  explicit TwinConversion(std::string_view ros2) : ros2_(ros2) {}

  void to_dds(std::span<const std::byte> message, std::vector<std::byte>& sample) override {
    if (message.size() != sizeof(Message)) {
      throw std::invalid_argument("a message of " + std::to_string(message.size()) +
                                  " bytes, not " + std::to_string(sizeof(Message)));
    }
    Message value;
    std::memcpy(&value, message.data(), sizeof(Message));
    CdrOut out(sample);
    write(out, value);
    out.finish();
  }

  std::string to_local(std::span<const std::byte> sample,
                       std::vector<std::byte>& message) override {
    if (std::string why = not_plain_cdr(sample, ros2_); !why.empty()) {
      return why;
    }
    Message value{};
    try {
      CdrIn in(sample.subspan(4), sample[1] == std::byte{1});
      read(in, value);
      // Up to 3 bytes pad a sample to a multiple of 4; more is not this type.
      if (in.left() > 3) {
        throw std::invalid_argument(std::to_string(in.left()) + " bytes are left over");
      }
    } catch (const std::invalid_argument& error) {
      return "a CDR sample does not decode as " + std::string(ros2_) + ": " + error.what();
    }
    const auto* bytes = reinterpret_cast<const std::byte*>(&value);
    message.assign(bytes, bytes + sizeof(Message));
    return {};
  }

 private:
  std::string_view ros2_;
};

constexpr std::array kTwins{
    Ros2Twin{"horus.msg.CmdVel", "geometry_msgs/msg/Twist"},
    Ros2Twin{"horus.msg.Twist", "geometry_msgs/msg/Twist"},
    Ros2Twin{"horus.msg.Imu", "sensor_msgs/msg/Imu"},
    Ros2Twin{"horus.msg.LaserScan", "sensor_msgs/msg/LaserScan"},
    Ros2Twin{"horus.msg.Odometry", "nav_msgs/msg/Odometry"},
    Ros2Twin{"horus.msg.PoseStamped", "geometry_msgs/msg/PoseStamped"},
};

}  // namespace

std::string Ros2Twin::dds_type() const {
  const std::size_t first = ros2.find('/');
  const std::size_t second = ros2.find('/', first + 1);
  return std::string(ros2.substr(0, first)) +
         "::" + std::string(ros2.substr(first + 1, second - first - 1)) +
         "::dds_::" + std::string(ros2.substr(second + 1)) + "_";
}

std::span<const Ros2Twin> ros2_twins() noexcept { return kTwins; }

const Ros2Twin* ros2_twin_of(std::string_view horus_type) noexcept {
  for (const Ros2Twin& twin : kTwins) {
    if (twin.horus == horus_type) return &twin;
  }
  return nullptr;
}

TypeIdentity twin_type_identity(const Ros2Twin& twin) {
  const std::string_view name = twin.horus;
  if (name == "horus.msg.CmdVel") return type_identity<msg::CmdVel>();
  if (name == "horus.msg.Twist") return type_identity<msg::Twist>();
  if (name == "horus.msg.Imu") return type_identity<msg::Imu>();
  if (name == "horus.msg.LaserScan") return type_identity<msg::LaserScan>();
  if (name == "horus.msg.Odometry") return type_identity<msg::Odometry>();
  if (name == "horus.msg.PoseStamped") return type_identity<msg::PoseStamped>();
  throw std::invalid_argument(std::string(name) + " has no ROS 2 twin");
}

std::unique_ptr<Conversion> twin_conversion(const Ros2Twin& twin) {
  const std::string_view name = twin.horus;
  if (name == "horus.msg.CmdVel") return std::make_unique<TwinConversion<msg::CmdVel>>(twin.ros2);
  if (name == "horus.msg.Twist") return std::make_unique<TwinConversion<msg::Twist>>(twin.ros2);
  if (name == "horus.msg.Imu") return std::make_unique<TwinConversion<msg::Imu>>(twin.ros2);
  if (name == "horus.msg.LaserScan") {
    return std::make_unique<TwinConversion<msg::LaserScan>>(twin.ros2);
  }
  if (name == "horus.msg.Odometry") {
    return std::make_unique<TwinConversion<msg::Odometry>>(twin.ros2);
  }
  if (name == "horus.msg.PoseStamped") {
    return std::make_unique<TwinConversion<msg::PoseStamped>>(twin.ros2);
  }
  throw std::invalid_argument(std::string(name) + " has no ROS 2 twin");
}

void tf_message_to_cdr(std::span<const StampedTransform> transforms,
                       std::vector<std::byte>& sample) {
  CdrOut out(sample);
  out.number(static_cast<std::uint32_t>(transforms.size()));
  for (const StampedTransform& transform : transforms) write(out, transform);
  out.finish();
}

std::string tf_message_from_cdr(std::span<const std::byte> sample,
                                std::vector<StampedTransform>& transforms) {
  transforms.clear();
  if (std::string why = not_plain_cdr(sample, kTfMessage); !why.empty()) {
    return why;
  }
  try {
    CdrIn in(sample.subspan(4), sample[1] == std::byte{1});
    // Read one by one: a forged count runs out of bytes before it allocates much.
    const std::uint32_t count = in.count();
    for (std::uint32_t i = 0; i < count; ++i) read(in, transforms.emplace_back());
    if (in.left() > 3) {
      throw std::invalid_argument(std::to_string(in.left()) + " bytes are left over");
    }
  } catch (const std::invalid_argument& error) {
    transforms.clear();
    return "a CDR sample does not decode as " + std::string(kTfMessage) + ": " + error.what();
  }
  return {};
}

}  // namespace horus::dds_bridge
