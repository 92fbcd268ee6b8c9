// What the frame tests share: transforms built from planar poses, comparisons, and a private
// namespace per test case.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "horus/frames.hpp"

namespace frames_test {

/// A planar pose: (x, y, z) and a rotation of `yaw` radians about z.
inline horus::Transform planar(double x, double y, double z, double yaw) {
  return {{x, y, z}, horus::axis_angle({0, 0, 1}, yaw)};
}

/// The yaw of a rotation about z.
inline double yaw_of(const horus::Quaternion& q) { return 2 * std::atan2(q.z, q.w); }

/// Whether two angles are the same rotation (modulo a turn).
inline ::testing::AssertionResult same_angle(double a, double b, double tolerance = 1e-9) {
  const double difference = std::remainder(a - b, 2 * M_PI);
  if (std::abs(difference) <= tolerance) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "angles " << a << " and " << b << " differ by " << difference;
}

inline void expect_transform(const horus::Transform& got, double x, double y, double z, double yaw,
                             double tolerance = 1e-9) {
  EXPECT_NEAR(got.translation.x, x, tolerance);
  EXPECT_NEAR(got.translation.y, y, tolerance);
  EXPECT_NEAR(got.translation.z, z, tolerance);
  EXPECT_NEAR(std::abs(got.rotation.x) + std::abs(got.rotation.y), 0, tolerance)
      << "a rotation about z only was expected";
  EXPECT_TRUE(same_angle(yaw_of(got.rotation), yaw, tolerance));
}

/// The running test case's own namespace (its tree is removed at the end).
class FrameTreeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    namespace_name_ =
        std::string("frames_") + ::testing::UnitTest::GetInstance()->current_test_info()->name();
    horus::remove_frame_tree(namespace_name_);
  }
  void TearDown() override { horus::remove_frame_tree(namespace_name_); }

  horus::FrameTreeOptions options() const {
    horus::FrameTreeOptions o;
    o.namespace_name = namespace_name_;
    return o;
  }

  std::string namespace_name_;
};

}  // namespace frames_test
