// The helper methods of the standard messages (schemas/horus/msg/mixins/*.inc), checked against
// tests/golden/msg_helpers_cases.json: the same table tests/python/test_msg_helpers.py checks the
// Python mixins against, so both languages are held to the same values.
#include <horus/msg.hpp>
#include <horus/msgpack.hpp>

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#ifndef HORUS_GOLDEN_DIR
#error "HORUS_GOLDEN_DIR must name tests/golden"
#endif

namespace {

using namespace horus::msg;
using namespace std::chrono_literals;

// ---- a small JSON reader: enough for the case table (objects, arrays, numbers, strings,
// true/false/null). Numbers keep their text so that u64/i64 values convert exactly.
struct Json {
  enum class Kind { Null, Bool, Number, String, Array, Object } kind = Kind::Null;
  bool boolean = false;
  std::string text;  // number token or string value
  std::vector<Json> items;
  std::map<std::string, Json> fields;

  const Json& operator[](const std::string& key) const {
    const auto it = fields.find(key);
    if (it == fields.end()) throw std::runtime_error("case table: missing key '" + key + "'");
    return it->second;
  }
  const Json& operator[](std::size_t i) const { return items.at(i); }
  bool is_null() const { return kind == Kind::Null; }
  bool b() const { return boolean; }
  // "nan", "inf", "-inf" stand for the non-finite numbers JSON cannot write.
  double d() const {
    if (kind == Kind::String) {
      if (text == "nan") return std::numeric_limits<double>::quiet_NaN();
      if (text == "inf") return std::numeric_limits<double>::infinity();
      if (text == "-inf") return -std::numeric_limits<double>::infinity();
    }
    return std::strtod(text.c_str(), nullptr);
  }
  float f() const { return static_cast<float>(d()); }
  std::uint64_t u64() const { return std::strtoull(text.c_str(), nullptr, 10); }
  std::int64_t i64() const { return std::strtoll(text.c_str(), nullptr, 10); }
  std::string s() const { return text; }
};

class JsonParser {
 public:
  explicit JsonParser(std::string text) : text_(std::move(text)) {}
  Json parse() {
    Json value = parse_value();
    skip_space();
    if (pos_ != text_.size()) fail("trailing characters");
    return value;
  }

 private:
  [[noreturn]] void fail(const std::string& what) {
    throw std::runtime_error("case table: " + what + " at offset " + std::to_string(pos_));
  }
  void skip_space() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
  }
  bool accept(char c) {
    skip_space();
    if (pos_ < text_.size() && text_[pos_] == c) {
      ++pos_;
      return true;
    }
    return false;
  }
  void expect(char c) {
    if (!accept(c)) fail(std::string("expected '") + c + "'");
  }
  bool accept_word(std::string_view word) {
    skip_space();
    if (text_.compare(pos_, word.size(), word) != 0) return false;
    pos_ += word.size();
    return true;
  }
  std::string parse_string() {
    expect('"');
    std::string out;
    while (pos_ < text_.size() && text_[pos_] != '"') {
      char c = text_[pos_++];
      if (c != '\\') {
        out += c;
        continue;
      }
      if (pos_ >= text_.size()) fail("unterminated escape");
      c = text_[pos_++];
      if (c == 'u') {
        const unsigned code = static_cast<unsigned>(std::stoul(text_.substr(pos_, 4), nullptr, 16));
        pos_ += 4;
        if (code < 0x80) {
          out += static_cast<char>(code);
        } else if (code < 0x800) {
          out += static_cast<char>(0xC0 | (code >> 6));
          out += static_cast<char>(0x80 | (code & 0x3F));
        } else {
          out += static_cast<char>(0xE0 | (code >> 12));
          out += static_cast<char>(0x80 | ((code >> 6) & 0x3F));
          out += static_cast<char>(0x80 | (code & 0x3F));
        }
      } else {
        out += c == 'n' ? '\n' : c == 't' ? '\t' : c;
      }
    }
    expect('"');
    return out;
  }
  Json parse_value() {
    skip_space();
    Json v;
    if (pos_ >= text_.size()) fail("unexpected end");
    const char c = text_[pos_];
    if (c == '{') {
      ++pos_;
      v.kind = Json::Kind::Object;
      if (accept('}')) return v;
      do {
        std::string key = parse_string();
        expect(':');
        v.fields.emplace(std::move(key), parse_value());
      } while (accept(','));
      expect('}');
    } else if (c == '[') {
      ++pos_;
      v.kind = Json::Kind::Array;
      if (accept(']')) return v;
      do {
        v.items.push_back(parse_value());
      } while (accept(','));
      expect(']');
    } else if (c == '"') {
      v.kind = Json::Kind::String;
      v.text = parse_string();
    } else if (accept_word("true")) {
      v.kind = Json::Kind::Bool;
      v.boolean = true;
    } else if (accept_word("false")) {
      v.kind = Json::Kind::Bool;
    } else if (accept_word("null")) {
      v.kind = Json::Kind::Null;
    } else {
      const std::size_t start = pos_;
      while (pos_ < text_.size() &&
             std::string_view("+-0123456789.eE").find(text_[pos_]) != std::string_view::npos) {
        ++pos_;
      }
      if (pos_ == start) fail("unexpected character");
      v.kind = Json::Kind::Number;
      v.text = text_.substr(start, pos_ - start);
    }
    return v;
  }

  std::string text_;
  std::size_t pos_ = 0;
};

const Json& cases(const std::string& name) {
  static const Json table = [] {
    std::ifstream in(std::string(HORUS_GOLDEN_DIR) + "/msg_helpers_cases.json");
    if (!in) throw std::runtime_error("cannot open msg_helpers_cases.json in " HORUS_GOLDEN_DIR);
    std::stringstream buffer;
    buffer << in.rdbuf();
    return JsonParser(buffer.str()).parse();
  }();
  return table[name];
}

// Equal, NaN equal to NaN, infinities by sign; finite values within a relative tolerance.
::testing::AssertionResult near(double actual, double expected, double tolerance) {
  if (std::isnan(expected) && std::isnan(actual)) return ::testing::AssertionSuccess();
  if (std::isinf(expected) && actual == expected) return ::testing::AssertionSuccess();
  if (std::isfinite(expected) && std::isfinite(actual) &&
      std::fabs(actual - expected) <= tolerance * std::max(1.0, std::fabs(expected))) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure() << "expected " << expected << ", got " << actual;
}
constexpr double kF64 = 1e-9;
constexpr double kF32 = 1e-6;

Pose2D pose(const Json& v) { return Pose2D::make(v[0].d(), v[1].d(), v[2].d()); }
Vector3 vec(const Json& v) { return Vector3::make(v[0].d(), v[1].d(), v[2].d()); }

// ---- geometry -----------------------------------------------------------------------------

TEST(MsgHelpers, CmdVelFactories) {
  const Json& c = cases("cmd_vel_with_timestamp")[0];
  const CmdVel cmd = CmdVel::with_timestamp(c["linear"].f(), c["angular"].f(), c["stamp"].u64());
  EXPECT_EQ(cmd.linear, 1.0f);
  EXPECT_EQ(cmd.angular, 0.5f);
  EXPECT_EQ(cmd.stamp_nanos, 123456789u);
  EXPECT_EQ(CmdVel::zero(), CmdVel{});
  static_assert(CmdVel::make(1.0f, 0.5f).stamp_nanos == 0, "make leaves the stamp to the sender");
}

TEST(MsgHelpers, TwistFactoriesAndValidity) {
  const Json& c = cases("twist_new_2d")[0];
  const Twist t = Twist::new_2d(c["linear_x"].d(), c["angular_z"].d());
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(t.linear[i], c["linear"][i].d());
    EXPECT_EQ(t.angular[i], c["angular"][i].d());
  }
  EXPECT_EQ(Twist::stop(), Twist{});
  for (const Json& row : cases("twist_is_valid").items) {
    const Twist tw =
        Twist::make({row["linear"][0].d(), row["linear"][1].d(), row["linear"][2].d()},
                    {row["angular"][0].d(), row["angular"][1].d(), row["angular"][2].d()});
    EXPECT_EQ(tw.is_valid(), row["expect"].b());
  }
}

TEST(MsgHelpers, Pose2DNormalizeAngleWrapsIntoMinusPiPi) {
  for (const Json& row : cases("pose2d_normalize_angle").items) {
    Pose2D p = Pose2D::make(1.0, 2.0, row["theta"].d());
    p.normalize_angle();
    EXPECT_TRUE(near(p.theta, row["expect"].d(), kF64)) << "theta " << row["theta"].text;
    if (std::isfinite(p.theta)) {
      EXPECT_LE(std::fabs(p.theta), 3.14159265358979323846);
    }
    EXPECT_EQ(p.x, 1.0);
  }
}

TEST(MsgHelpers, Pose2DDistanceAndValidity) {
  for (const Json& row : cases("pose2d_distance_to").items) {
    EXPECT_TRUE(near(pose(row["a"]).distance_to(pose(row["b"])), row["expect"].d(), kF64));
  }
  for (const Json& row : cases("pose2d_is_valid").items) {
    EXPECT_EQ(pose(row["pose"]).is_valid(), row["expect"].b());
  }
  EXPECT_EQ(Pose2D::origin(), Pose2D{});
}

TEST(MsgHelpers, Point3AndVector3) {
  for (const Json& row : cases("point3_distance_to").items) {
    const Point3 a = Point3::make(row["a"][0].d(), row["a"][1].d(), row["a"][2].d());
    const Point3 b = Point3::make(row["b"][0].d(), row["b"][1].d(), row["b"][2].d());
    EXPECT_TRUE(near(a.distance_to(b), row["expect"].d(), kF64));
  }
  for (const Json& row : cases("vector3_ops").items) {
    const Vector3 a = vec(row["a"]), b = vec(row["b"]);
    EXPECT_TRUE(near(a.magnitude(), row["magnitude"].d(), kF64));
    EXPECT_TRUE(near(a.dot(b), row["dot"].d(), kF64));
    const Vector3 c = a.cross(b), n = a.normalized();
    EXPECT_TRUE(near(c.x, row["cross"][0].d(), kF64));
    EXPECT_TRUE(near(c.y, row["cross"][1].d(), kF64));
    EXPECT_TRUE(near(c.z, row["cross"][2].d(), kF64));
    EXPECT_TRUE(near(n.x, row["normalized"][0].d(), kF64));
    EXPECT_TRUE(near(n.y, row["normalized"][1].d(), kF64));
    EXPECT_TRUE(near(n.z, row["normalized"][2].d(), kF64));
  }
  static_assert(Vector3::make(1, 0, 0).cross(Vector3::make(0, 1, 0)).z == 1.0);
}

TEST(MsgHelpers, QuaternionFromEulerAndNormalize) {
  EXPECT_EQ(Quaternion{}, Quaternion::identity()) << "a default Quaternion is the identity";
  for (const Json& row : cases("quaternion_from_euler").items) {
    const Quaternion q =
        Quaternion::from_euler(row["rpy"][0].d(), row["rpy"][1].d(), row["rpy"][2].d());
    EXPECT_TRUE(near(q.x, row["expect"][0].d(), kF64));
    EXPECT_TRUE(near(q.y, row["expect"][1].d(), kF64));
    EXPECT_TRUE(near(q.z, row["expect"][2].d(), kF64));
    EXPECT_TRUE(near(q.w, row["expect"][3].d(), kF64));
  }
  for (const Json& row : cases("quaternion_normalize").items) {
    Quaternion q =
        Quaternion::make(row["q"][0].d(), row["q"][1].d(), row["q"][2].d(), row["q"][3].d());
    q.normalize();
    EXPECT_TRUE(near(q.x, row["expect"][0].d(), kF64));
    EXPECT_TRUE(near(q.y, row["expect"][1].d(), kF64));
    EXPECT_TRUE(near(q.z, row["expect"][2].d(), kF64));
    EXPECT_TRUE(near(q.w, row["expect"][3].d(), kF64));
  }
}

TEST(MsgHelpers, TransformStamped) {
  const TransformStamped id = TransformStamped::identity();
  EXPECT_TRUE(id.is_valid());
  EXPECT_EQ(id.rotation[3], 1.0);
  for (const Json& row : cases("transform_from_pose_2d").items) {
    Pose2D p = pose(row["pose"]);
    p.timestamp_ns = row["stamp"].u64();
    const TransformStamped tf = TransformStamped::from_pose_2d(p);
    for (std::size_t i = 0; i < 3; ++i)
      EXPECT_TRUE(near(tf.translation[i], row["translation"][i].d(), kF64));
    for (std::size_t i = 0; i < 4; ++i)
      EXPECT_TRUE(near(tf.rotation[i], row["rotation"][i].d(), kF64));
    EXPECT_EQ(tf.timestamp_ns, p.timestamp_ns);
    const Pose3D p3 = Pose3D::from_pose_2d(p);
    EXPECT_TRUE(near(p3.orientation.z, row["rotation"][2].d(), kF64));
    EXPECT_TRUE(near(p3.position.x, row["translation"][0].d(), kF64));
  }
  for (const Json& row : cases("transform_normalize_rotation").items) {
    TransformStamped tf =
        TransformStamped::make({1.0, 2.0, 3.0}, {row["rotation"][0].d(), row["rotation"][1].d(),
                                                 row["rotation"][2].d(), row["rotation"][3].d()});
    EXPECT_EQ(tf.is_valid(), row["valid_before"].b());
    tf.normalize_rotation();
    for (std::size_t i = 0; i < 4; ++i)
      EXPECT_TRUE(near(tf.rotation[i], row["expect"][i].d(), kF64));
    EXPECT_EQ(tf.is_valid(), row["valid_after"].b()) << "a zero quaternion stays invalid";
  }
}

// ---- sensors ------------------------------------------------------------------------------

TEST(MsgHelpers, LaserScanIncludingEmptyScan) {
  for (const Json& row : cases("laser_scan").items) {
    LaserScan scan{};
    for (const auto& [index, value] : row["ranges"].fields)
      scan.ranges.at(std::stoul(index)) = value.f();
    for (const Json& q : row["angle_at"].items) {
      EXPECT_TRUE(near(scan.angle_at(q[0].u64()), q[1].d(), kF32)) << "index " << q[0].text;
    }
    for (const Json& q : row["is_range_valid"].items) {
      EXPECT_EQ(scan.is_range_valid(q[0].u64()), q[1].b()) << "index " << q[0].text;
    }
    EXPECT_EQ(scan.valid_count(), row["valid_count"].u64());
    const auto closest = scan.min_range();
    if (row["min_range"].is_null()) {
      EXPECT_FALSE(closest.has_value()) << "an empty scan has no closest reading";
    } else {
      ASSERT_TRUE(closest.has_value());
      EXPECT_EQ(*closest, row["min_range"].f());
    }
  }
}

TEST(MsgHelpers, ImuOrientation) {
  const Json& row = cases("imu_orientation")[0];
  Imu imu = Imu::make();
  EXPECT_EQ(imu.has_orientation(), row["has_before"].b());
  imu.set_orientation_from_euler(row["rpy"][0].d(), row["rpy"][1].d(), row["rpy"][2].d());
  EXPECT_EQ(imu.has_orientation(), row["has_after"].b());
  for (std::size_t i = 0; i < 4; ++i)
    EXPECT_TRUE(near(imu.orientation[i], row["orientation"][i].d(), kF64));
  for (const Json& r : cases("imu_is_valid").items) {
    Imu m = Imu::make();
    for (std::size_t i = 0; i < 3; ++i) {
      m.angular_velocity[i] = r["angular_velocity"][i].d();
      m.linear_acceleration[i] = r["linear_acceleration"][i].d();
    }
    EXPECT_EQ(m.is_valid(), r["expect"].b());
  }
}

TEST(MsgHelpers, OdometryFramesAndUpdate) {
  Odometry odom = Odometry::make();
  odom.set_frames("odom", "base_link");
  EXPECT_EQ(odom.frame_id.view(), "odom");
  EXPECT_EQ(odom.child_frame_id.view(), "base_link");
  const std::string too_long(33, 'f');
  EXPECT_THROW(odom.set_frames(too_long, "base_link"), horus::Error);
  EXPECT_EQ(odom.frame_id.view(), "odom") << "a failed set_frames changes nothing";
  Pose2D p = Pose2D::make(1.0, 2.0, 0.5);
  p.timestamp_ns = 10;
  Twist t = Twist::new_2d(0.5, 0.2);
  t.timestamp_ns = 20;
  odom.update(p, t);
  EXPECT_EQ(odom.pose, p);
  EXPECT_EQ(odom.twist, t);
  EXPECT_EQ(odom.timestamp_ns, 20u);
  EXPECT_TRUE(odom.is_valid());
}

TEST(MsgHelpers, RangeConstantsAndValidity) {
  static_assert(Range::ULTRASONIC == 0 && Range::INFRARED == 1);
  for (const Json& row : cases("range_is_valid").items) {
    const Range r =
        Range::make(static_cast<std::uint8_t>(row["sensor_type"].u64()), row["range"].f());
    EXPECT_EQ(r.is_valid(), row["expect"].b()) << "range " << row["range"].text;
  }
}

TEST(MsgHelpers, BatteryState) {
  for (const Json& row : cases("battery_state").items) {
    BatteryState b = BatteryState::make(row["voltage"].f(), row["percentage"].f());
    b.current = row["current"].f();
    b.charge = row["charge"].f();
    EXPECT_EQ(b.is_low(20.0f), row["is_low_20"].b());
    EXPECT_EQ(b.is_critical(), row["is_critical"].b());
    const auto left = b.time_remaining();
    if (row["time_remaining"].is_null()) {
      EXPECT_FALSE(left.has_value());
    } else {
      ASSERT_TRUE(left.has_value());
      EXPECT_TRUE(near(left->count(), row["time_remaining"].d(), kF32));
    }
  }
  EXPECT_TRUE(std::isnan(BatteryState::make(12.0f, 50.0f).capacity)) << "unmeasured means unknown";
}

TEST(MsgHelpers, NavSatFix) {
  for (const Json& row : cases("nav_sat_fix").items) {
    const NavSatFix a =
        NavSatFix::from_coordinates(row["a"][0].d(), row["a"][1].d(), row["a"][2].d());
    const NavSatFix b =
        NavSatFix::from_coordinates(row["b"][0].d(), row["b"][1].d(), row["b"][2].d());
    EXPECT_TRUE(a.has_fix());
    EXPECT_EQ(a.is_valid(), row["valid_a"].b());
    EXPECT_TRUE(near(a.distance_to(b), row["distance"].d(), kF64));
  }
}

TEST(MsgHelpers, JointStateAddAndLookUp) {
  JointState js{};
  EXPECT_TRUE(js.add_joint("shoulder", 0.5, 0.1, 2.0));
  EXPECT_TRUE(js.add_joint("elbow", -1.0, 0.0, 1.0));
  EXPECT_EQ(js.position_of("elbow"), -1.0);
  EXPECT_FALSE(js.position_of("wrist").has_value());
  EXPECT_THROW(js.add_joint(std::string(40, 'j'), 0, 0, 0), horus::Error);
  for (int i = 2; i < 16; ++i) EXPECT_TRUE(js.add_joint("j" + std::to_string(i), 0, 0, 0));
  EXPECT_FALSE(js.add_joint("one_too_many", 0, 0, 0));
  EXPECT_EQ(js.joint_count, 16);
}

// ---- navigation ---------------------------------------------------------------------------

TEST(MsgHelpers, GoalIsReachedAcrossTheAngleWrap) {
  for (const Json& row : cases("goal_is_reached").items) {
    const Goal goal =
        Goal::make(pose(row["target"]), row["tolerance"][0].d(), row["tolerance"][1].d());
    EXPECT_EQ(goal.is_reached(pose(row["current"])), row["expect"].b())
        << "current theta " << row["current"][2].text;
  }
  const Goal g = Goal::make(Pose2D::make(5, 3, 0), 0.1, 0.05).with_timeout(30s).with_priority(2);
  EXPECT_EQ(g.timeout_seconds, 30.0);
  EXPECT_EQ(g.priority, 2);
  EXPECT_EQ(Goal::make(Pose2D{}, 0.1, 0.1).priority, 1);
}

TEST(MsgHelpers, GoalResultErrorIsCutAtACharacterBoundary) {
  const GoalResult base = GoalResult::make(7, GoalStatus::Aborted);
  EXPECT_EQ(base.status, static_cast<std::uint8_t>(GoalStatus::Aborted));
  for (const Json& row : cases("goal_result_with_error").items) {
    EXPECT_EQ(base.with_error(row["message"].s()).error_message.view(), row["expect"].s());
  }
}

TEST(MsgHelpers, WaypointAndPath) {
  const Waypoint wp = Waypoint::make(Pose2D::make(1, 2, 0)).with_velocity(Twist::new_2d(0.5, 0.0));
  EXPECT_EQ(wp.velocity.linear[0], 0.5);
  const Waypoint stop = wp.with_stop();
  EXPECT_EQ(stop.stop_required, 1);
  EXPECT_EQ(stop.velocity, Twist::stop());
  for (const Json& row : cases("path").items) {
    auto path = std::make_unique<Path>();
    for (const Json& p : row["poses"].items)
      ASSERT_TRUE(path->add_waypoint(Waypoint::make(pose(p))));
    EXPECT_TRUE(near(path->total_length, row["total_length"].d(), kF64));
    for (const Json& q : row["closest"].items) {
      const auto index = path->closest_waypoint_index(pose(q[0]));
      if (q[1].is_null()) {
        EXPECT_FALSE(index.has_value());
      } else {
        EXPECT_EQ(index, q[1].u64());
      }
    }
  }
  auto full = std::make_unique<Path>();
  for (int i = 0; i < 256; ++i) ASSERT_TRUE(full->add_waypoint(Waypoint{}));
  EXPECT_FALSE(full->add_waypoint(Waypoint{}));
  EXPECT_EQ(full->waypoint_count, 256);
}

TEST(MsgHelpers, PathPlan) {
  for (const Json& row : cases("path_plan").items) {
    PathPlan plan{};
    EXPECT_TRUE(plan.is_empty());
    for (const Json& w : row["waypoints"].items)
      ASSERT_TRUE(plan.add_waypoint(w[0].f(), w[1].f(), w[2].f()));
    for (const Json& q : row["lookups"].items) {
      const auto w = plan.waypoint(q[0].u64());
      if (q[1].is_null()) {
        EXPECT_FALSE(w.has_value());
      } else {
        ASSERT_TRUE(w.has_value());
        for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ((*w)[i], q[1][i].f());
      }
    }
  }
  PathPlan full{};
  for (int i = 0; i < 256; ++i) ASSERT_TRUE(full.add_waypoint(1, 2, 3));
  EXPECT_FALSE(full.add_waypoint(1, 2, 3));
}

TEST(MsgHelpers, OccupancyGridIncludingOutOfGridCoordinates) {
  for (const Json& row : cases("occupancy_grid").items) {
    OccupancyGrid grid = OccupancyGrid::make(static_cast<std::uint32_t>(row["width"].u64()),
                                             static_cast<std::uint32_t>(row["height"].u64()),
                                             row["resolution"].f(), pose(row["origin"]));
    for (const Json& q : row["world_to_grid"].items) {
      const auto cell = grid.world_to_grid(q[0].d(), q[1].d());
      if (q[2].is_null()) {
        EXPECT_FALSE(cell.has_value())
            << "(" << q[0].text << ", " << q[1].text << ") is off the grid";
      } else {
        ASSERT_TRUE(cell.has_value()) << "(" << q[0].text << ", " << q[1].text << ")";
        EXPECT_EQ(cell->first, q[2][0].u64());
        EXPECT_EQ(cell->second, q[2][1].u64());
      }
    }
    for (const Json& q : row["set_occupancy"].items) {
      EXPECT_EQ(grid.set_occupancy(static_cast<std::uint32_t>(q[0].u64()),
                                   static_cast<std::uint32_t>(q[1].u64()),
                                   static_cast<std::int8_t>(q[2].i64())),
                q[3].b());
    }
    for (const Json& q : row["occupancy"].items) {
      const auto v = grid.occupancy(static_cast<std::uint32_t>(q[0].u64()),
                                    static_cast<std::uint32_t>(q[1].u64()));
      if (q[2].is_null()) {
        EXPECT_FALSE(v.has_value());
      } else {
        EXPECT_EQ(v, static_cast<std::int8_t>(q[2].i64()));
      }
    }
    for (const Json& q : row["is_free"].items)
      EXPECT_EQ(grid.is_free(q[0].d(), q[1].d()), q[2].b());
    for (const Json& q : row["is_occupied"].items)
      EXPECT_EQ(grid.is_occupied(q[0].d(), q[1].d()), q[2].b());
  }
}

TEST(MsgHelpers, CostMapInflation) {
  const Json& row = cases("cost_map")[0];
  OccupancyGrid grid = OccupancyGrid::make(static_cast<std::uint32_t>(row["width"].u64()),
                                           static_cast<std::uint32_t>(row["height"].u64()),
                                           row["resolution"].f(), pose(row["origin"]));
  std::fill(grid.data.begin(), grid.data.end(), std::int8_t{0});
  for (const Json& c : row["cells"].items) {
    ASSERT_TRUE(grid.set_occupancy(static_cast<std::uint32_t>(c[0].u64()),
                                   static_cast<std::uint32_t>(c[1].u64()),
                                   static_cast<std::int8_t>(c[2].i64())));
  }
  CostMap map = CostMap::from_occupancy_grid(grid, row["inflation_radius"].f());
  for (const Json& q : row["cost_default_scaling"].items) {
    EXPECT_EQ(map.cost(q[0].d(), q[1].d()), static_cast<std::uint8_t>(q[2].u64()))
        << "at (" << q[0].text << ", " << q[1].text << ")";
  }
  map.cost_scaling_factor = 2.0f;
  map.compute_costs();
  for (const Json& q : row["cost_scaling_2"].items) {
    EXPECT_EQ(map.cost(q[0].d(), q[1].d()), static_cast<std::uint8_t>(q[2].u64()))
        << "at (" << q[0].text << ", " << q[1].text << ")";
  }
  CostMap empty{};
  EXPECT_EQ(empty.cost(0.0, 0.0), empty.lethal_cost) << "off an empty map is lethal";
}

// ---- vision, detection --------------------------------------------------------------------

TEST(MsgHelpers, StereoDepthAndDisparity) {
  for (const Json& row : cases("stereo_info").items) {
    StereoInfo stereo{};
    stereo.left_camera = CameraInfo::make(640, 480, row["fx"].d(), row["fx"].d(), 320, 240);
    stereo.baseline = row["baseline"].d();
    for (const Json& q : row["depth_from_disparity"].items) {
      EXPECT_TRUE(near(stereo.depth_from_disparity(q[0].f()), q[1].d(), kF32))
          << "disparity " << q[0].text;
    }
    for (const Json& q : row["disparity_from_depth"].items) {
      EXPECT_TRUE(near(stereo.disparity_from_depth(q[0].f()), q[1].d(), kF32))
          << "depth " << q[0].text;
    }
  }
  const CameraInfo info = CameraInfo::make(640, 480, 525.0, 520.0, 320.0, 240.0);
  EXPECT_EQ(info.focal_lengths(), (std::array<double, 2>{525.0, 520.0}));
  EXPECT_EQ(info.principal_point(), (std::array<double, 2>{320.0, 240.0}));
}

TEST(MsgHelpers, BoundingBoxAndRegionOfInterest) {
  for (const Json& row : cases("bounding_box_2d").items) {
    const BoundingBox2D a{row["a"][0].f(), row["a"][1].f(), row["a"][2].f(), row["a"][3].f()};
    const BoundingBox2D b{row["b"][0].f(), row["b"][1].f(), row["b"][2].f(), row["b"][3].f()};
    EXPECT_TRUE(near(a.area(), row["area_a"].d(), kF32));
    EXPECT_TRUE(near(a.iou(b), row["iou"].d(), kF32));
  }
  for (const Json& row : cases("region_of_interest").items) {
    const auto u = [&](std::size_t i) { return static_cast<std::uint32_t>(row["roi"][i].u64()); };
    const RegionOfInterest roi = RegionOfInterest::make(u(0), u(1), u(2), u(3));
    EXPECT_EQ(roi.area(), row["area"].u64());
    for (const Json& q : row["contains"].items) {
      EXPECT_EQ(roi.contains(static_cast<std::uint32_t>(q[0].u64()),
                             static_cast<std::uint32_t>(q[1].u64())),
                q[2].b())
          << "(" << q[0].text << ", " << q[1].text << ")";
    }
  }
}

// ---- time, audio, generic -----------------------------------------------------------------

TEST(MsgHelpers, ClockAndTimeReference) {
  const Json& c = cases("clock")[0];
  Clock a = Clock::sim_time(c["a"].u64(), 2.0), b = Clock::replay_time(c["b"].u64(), 0.5);
  EXPECT_EQ(a.source, Clock::SOURCE_SIM);
  EXPECT_EQ(b.source, Clock::SOURCE_REPLAY);
  EXPECT_EQ(b.elapsed_since(a), c["elapsed_b_since_a"].u64());
  EXPECT_EQ(a.elapsed_since(b), c["elapsed_a_since_b"].u64()) << "never a wrapped value";
  EXPECT_FALSE(a.is_paused());
  EXPECT_EQ(Clock{}.sim_speed, 1.0);
  for (const Json& row : cases("time_reference").items) {
    TimeReference ref{};
    ref.offset_ns = row["offset_ns"].i64();
    EXPECT_EQ(ref.correct_timestamp(row["local"].u64()), row["expect"].u64())
        << "offset " << row["offset_ns"].text;
  }
}

TEST(MsgHelpers, AudioFrame) {
  for (const Json& row : cases("audio_frame").items) {
    AudioFrame frame{};
    frame.num_samples = static_cast<std::uint32_t>(row["num_samples"].u64());
    frame.sample_rate = static_cast<std::uint32_t>(row["sample_rate"].u64());
    frame.channels = static_cast<std::uint8_t>(row["channels"].u64());
    EXPECT_EQ(frame.frame_count(), row["frame_count"].u64());
    EXPECT_TRUE(near(frame.duration_ms(), row["duration_ms"].d(), kF64));
  }
}

TEST(MsgHelpers, GenericMessageEnforcesTheLimitEveryWayInAndOut) {
  for (const Json& row : cases("generic_message_limit").items) {
    const std::vector<std::uint8_t> payload(row["payload_bytes"].u64(), 0xc0);
    if (row["accepted"].b()) {
      EXPECT_EQ(GenericMessage::make(payload).data.size(), payload.size());
      EXPECT_NO_THROW(GenericMessage::with_metadata(payload, "meta"));
    } else {
      try {
        GenericMessage::make(payload);
        ADD_FAILURE() << "a payload of " << payload.size() << " bytes was accepted";
      } catch (const horus::Error& e) {
        EXPECT_NE(std::string(e.what()).find("exceeds the 4096-byte maximum"), std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find(std::to_string(payload.size())), std::string::npos)
            << e.what();
      }
      EXPECT_THROW(GenericMessage::with_metadata(payload, "meta"), horus::Error);
      GenericMessage forged;
      forged.data = payload;
      EXPECT_THROW(forged.to_value<int>(), horus::Error)
          << "an oversized payload is refused on the way out too";
    }
  }
  EXPECT_THROW(GenericMessage::from_value(std::string(5000, 'x')), horus::Error);
}

TEST(MsgHelpers, GenericMessageRoundTripsValues) {
  const std::map<std::string, double> reading{{"humidity", 60.0}, {"temperature", 22.5}};
  const GenericMessage msg = GenericMessage::from_value(reading);
  EXPECT_FALSE(msg.metadata.has_value());
  EXPECT_EQ((msg.to_value<std::map<std::string, double>>()), reading);
  EXPECT_THROW(msg.to_value<std::vector<int>>(), horus::DecodeError);
  GenericMessage garbage = GenericMessage::make({0x92, 0x01});  // array of 2, one element missing
  EXPECT_THROW(garbage.to_value<std::vector<int>>(), horus::DecodeError);
  const GenericMessage tagged = GenericMessage::with_metadata(msg.data, "source=lidar");
  EXPECT_EQ(tagged.metadata, "source=lidar");
  EXPECT_EQ(horus::decode<GenericMessage>(horus::encode(tagged)), tagged);
}

TEST(MsgHelpers, ConciseLogSummaries) {
  const Json& rows = cases("log_summary");
  EXPECT_EQ(CmdVel::make(1.0f, 0.5f).log_summary(), rows[0]["expect"].s());
  EXPECT_EQ(CameraInfo::make(640, 480, 525, 525, 320, 240).log_summary(), rows[1]["expect"].s());
  EXPECT_EQ(OccupancyGrid::make(200, 200, 0.05f, Pose2D{}).log_summary(), rows[2]["expect"].s());
  EXPECT_EQ(GenericMessage::from_value(42).log_summary(), rows[3]["expect"].s());
}

}  // namespace
