// Every standard message survives horus::encode / horus::decode unchanged, and its wire bytes are
// pinned by tests/golden/msg_roundtrip.json (size and FNV-1a 64 of the bytes of a deterministic
// value), so a change of layout, padding or MessagePack form shows up as a failing test.
//
// The value: a depth-first walk of the fields in declaration order with a counter k = 1, 2, ...
// taking one step per leaf: unsigned k mod 2^bits, signed -(k mod 2^(bits-1)), floats k + 0.25,
// bool k odd, enums their first enumerator, string<N> "s<k>" cut to N, String "text<k>", bytes
// and Vec<u8> (both std::vector<std::uint8_t>) {k, k+1, k+2} mod 256 in one step, other Vec<T>
// two elements, Option<T> present. The Python mirror builds the
// same value, so the same table checks its bytes (tests/python/test_msg_roundtrip.py).
//
// Refresh the table after an intended wire change:
//   HORUS_UPDATE_GOLDEN=1 <build>/tests/unit/msg_roundtrip_test
#include <horus/codec.hpp>
#include <horus/msg.hpp>
#include <horus/msgpack.hpp>

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "every_field.hpp"

#ifndef HORUS_GOLDEN_DIR
#error "HORUS_GOLDEN_DIR must name tests/golden"
#endif

namespace {

using namespace horus::msg;

std::uint64_t fnv1a64(const std::vector<std::uint8_t>& bytes) {
  std::uint64_t hash = 0xcbf29ce484222325ULL;
  for (std::uint8_t b : bytes) {
    hash ^= b;
    hash *= 0x100000001b3ULL;
  }
  return hash;
}

struct Pinned {
  std::size_t size;
  std::uint64_t hash;
};

// The golden table: one line per type, `"Name": {"size": N, "fnv1a64": "0x..."},`.
std::string golden_path() { return std::string(HORUS_GOLDEN_DIR) + "/msg_roundtrip.json"; }

std::map<std::string, Pinned> read_golden() {
  std::map<std::string, Pinned> table;
  std::ifstream in(golden_path());
  std::string line;
  while (std::getline(in, line)) {
    char name[64];
    unsigned long long size = 0, hash = 0;
    if (std::sscanf(line.c_str(), " \"%63[^\"]\": {\"size\": %llu, \"fnv1a64\": \"0x%llx\"}", name,
                    &size, &hash) == 3) {
      table[name] = Pinned{size, hash};
    }
  }
  return table;
}

template <class... Ts>
struct TypeList {};

class Roundtrip : public ::testing::Test {
 protected:
  template <class... Ts>
  void check_all(TypeList<Ts...>) {
    (check<Ts>(), ...);
  }

  static void TearDownTestSuite() {
    if (std::getenv("HORUS_UPDATE_GOLDEN") == nullptr) return;
    std::ostringstream out;
    out << "{\n \"_about\": \"Wire bytes of each horus.msg type for the deterministic value "
           "described in "
           "tests/unit/msg_roundtrip_test.cpp: size and FNV-1a 64. Refresh: HORUS_UPDATE_GOLDEN=1 "
           "msg_roundtrip_test\"";
    for (const auto& [name, pinned] : computed()) {
      char hex[32];
      std::snprintf(hex, sizeof hex, "0x%016llx", static_cast<unsigned long long>(pinned.hash));
      out << ",\n \"" << name << "\": {\"size\": " << pinned.size << ", \"fnv1a64\": \"" << hex
          << "\"}";
    }
    out << "\n}\n";
    std::ofstream(golden_path()) << out.str();
  }

  static std::map<std::string, Pinned>& computed() {
    static std::map<std::string, Pinned> table;
    return table;
  }

  template <class T>
  void check() {
    const std::string name(
        horus::TypeInfo<T>::name.substr(horus::TypeInfo<T>::name.rfind('.') + 1));
    auto value = std::make_unique<T>();
    std::uint64_t k = 1;
    horus_test::fill_every_field(*value, k);
    const std::vector<std::uint8_t> bytes = horus::encode(*value);
    if constexpr (horus::TypeInfo<T>::is_pod) {
      EXPECT_EQ(bytes.size(), sizeof(T)) << name;
    }
    EXPECT_EQ(horus::decode<T>(bytes), *value)
        << name << " changed on the way through encode/decode";
    const Pinned pinned{bytes.size(), fnv1a64(bytes)};
    computed()[name] = pinned;
    if (std::getenv("HORUS_UPDATE_GOLDEN") != nullptr) return;
    static const std::map<std::string, Pinned> golden = read_golden();
    const auto it = golden.find(name);
    ASSERT_NE(it, golden.end()) << name << " is missing from " << golden_path();
    EXPECT_EQ(pinned.size, it->second.size) << name << ": the wire size changed";
    EXPECT_EQ(pinned.hash, it->second.hash)
        << name << ": the wire bytes changed (layout, padding or encoding)";
  }
};

// Geometry, sensor, control.
TEST_F(Roundtrip, GeometrySensorControl) {
  check_all(
      TypeList<CmdVel, Twist, Pose2D, TransformStamped, Point3, Vector3, Quaternion, Pose3D,
               PoseStamped, PoseWithCovariance, TwistWithCovariance, Accel, AccelStamped, LaserScan,
               Imu, Odometry, Range, BatteryState, NavSatFix, JointState, MagneticField,
               Temperature, FluidPressure, Illuminance, MotorCommand, DifferentialDriveCommand,
               ServoCommand, JointCommand, PidConfig, TrajectoryPoint>{});
}

// Vision, detection, perception, navigation.
TEST_F(Roundtrip, VisionDetectionPerceptionNavigation) {
  check_all(TypeList<CompressedImage, CameraInfo, RegionOfInterest, StereoInfo, ImageDescriptor,
                     DepthImageDescriptor, PointCloudDescriptor, PoolBlock, TensorDescriptor,
                     BoundingBox2D, BoundingBox3D, Detection, Detection3D, PointXYZ, PointXYZRGB,
                     PointXYZI, Goal, GoalResult, Waypoint, Path, PathPlan, OccupancyGrid, CostMap,
                     VelocityObstacle, VelocityObstacles>{});
}

// Diagnostics, force, input, tracking, time, audio, generic.
TEST_F(Roundtrip, DiagnosticsForceInputTrackingTimeAudioGeneric) {
  check_all(
      TypeList<Heartbeat, NodeHeartbeat, Status, EmergencyStop, SafetyStatus, ResourceUsage,
               DiagnosticValue, DiagnosticReport, DiagnosticStatus, WrenchStamped,
               ImpedanceParameters, ForceCommand, ContactInfo, HapticFeedback, TactileArray,
               JoystickInput, KeyboardInput, SegmentationMask, Landmark, Landmark3D, LandmarkArray,
               TrackedObject, TrackingHeader, Clock, TimeReference, AudioFrame, GenericMessage>{});
}

}  // namespace
