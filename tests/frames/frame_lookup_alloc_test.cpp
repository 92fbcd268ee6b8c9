// Lookups allocate nothing: FrameTree::lookup, can_lookup and wait_for's check run at a node's
// rate (every scan, every control tick), so they must not reach the heap, whatever the chain's
// depth and however long the frames' names (a std::string of more than 15 bytes would).
#include <chrono>
#include <string>
#include <vector>

#include "../support/allocation_counter.hpp"
#include "frame_test_support.hpp"
#include "horus/frames.hpp"
#include "private_shm_root.hpp"

namespace {

using namespace std::chrono_literals;
using frames_test::expect_transform;
using frames_test::FrameTreeTest;
using frames_test::planar;
using horus::FrameTree;

const horus_test::PrivateShmRoot private_root("frame_lookup_alloc_test");

constexpr std::chrono::nanoseconds kEpoch = std::chrono::seconds(1000);
constexpr int kLookups = 1000;

/// A name longer than std::string's inline buffer (15 bytes).
std::string long_name(const std::string& what) { return "robot_with_long_names/" + what; }

/// `depth` frames below "<prefix>root": each one 1 m along x from its parent, turned a quarter
/// turn about z at `kEpoch` + 1 s and by nothing at `kEpoch`. Returns the names, root first.
std::vector<std::string> write_chain(FrameTree& tree, const std::string& prefix, int depth) {
  std::vector<std::string> names{long_name(prefix + "root")};
  for (int i = 1; i <= depth; ++i) names.push_back(long_name(prefix + "link_" + std::to_string(i)));
  for (int step = 0; step <= 10; ++step) {
    const auto stamp = kEpoch + step * 100ms;
    for (int i = 1; i <= depth; ++i) {
      tree.set_transform(names[i - 1], names[i], planar(1, 0, 0, step * M_PI / 20), stamp);
    }
  }
  return names;
}

TEST_F(FrameTreeTest, LookupsOfAFiveDeepChainAllocateNothing) {
  FrameTree tree(options());
  const std::vector<std::string> names = write_chain(tree, "", 5);
  // A static sensor beside the chain, so the lookup also crosses a common ancestor.
  const std::string sensor = long_name("sensor_on_link_2");
  tree.set_static_transform(names[2], sensor, planar(0, 1, 0, 0));
  const std::string& root = names.front();
  const std::string& tip = names.back();
  const auto past = kEpoch + 550ms;  // between two entries: interpolated

  horus::Transform at_past;
  horus::Transform latest;
  horus::Transform across;
  horus::Transform upward;
  bool answerable = true;
  const long before = horus_test::allocations.load();
  for (int i = 0; i < kLookups; ++i) {
    at_past = tree.lookup(root, tip, past);
    latest = tree.lookup(root, tip);
    across = tree.lookup(sensor, tip, past, std::chrono::hours(24 * 365 * 100));
    upward = tree.lookup(tip, root, past);
    answerable = answerable && tree.can_lookup(root, tip, past) && tree.can_lookup(sensor, tip);
    answerable = answerable && tree.wait_for(root, tip, past, 1s);
  }
  const long allocated = horus_test::allocations.load() - before;
  EXPECT_EQ(allocated, 0) << "allocations in " << kLookups << " rounds of lookups";
  EXPECT_TRUE(answerable);

  // The same answers as ever: at 0.55 s every link is 1 m along x turned by 0.55 * pi/2 (slerp
  // of its neighbours at 0.5 and 0.6 s, halfway), so five compose to a walk along a polygon.
  const double yaw = 0.55 * M_PI / 2;
  double x = 0;
  double y = 0;
  for (int i = 0; i < 5; ++i) {
    x += std::cos(i * yaw);
    y += std::sin(i * yaw);
  }
  expect_transform(at_past, x, y, 0, 5 * yaw);
  double latest_x = 0;
  double latest_y = 0;
  for (int i = 0; i < 5; ++i) {
    latest_x += std::cos(i * M_PI / 2);
    latest_y += std::sin(i * M_PI / 2);
  }
  expect_transform(latest, latest_x, latest_y, 0, 5 * M_PI / 2);
  // The root seen from the tip: the inverse.
  const horus::Transform inverse = horus::inverse(at_past);
  expect_transform(upward, inverse.translation.x, inverse.translation.y, 0,
                   frames_test::yaw_of(inverse.rotation));
  // The sensor sits 1 m along link_2's y: the tip seen from it.
  const horus::Transform tip_in_link_2 =
      horus::compose(horus::inverse(tree.lookup(root, names[2], past)), at_past);
  const horus::Transform expected =
      horus::compose(horus::inverse(planar(0, 1, 0, 0)), tip_in_link_2);
  expect_transform(across, expected.translation.x, expected.translation.y, 0,
                   frames_test::yaw_of(expected.rotation));
}

TEST_F(FrameTreeTest, LookupsOfADeepChainAllocateNothing) {
  FrameTree tree(options());
  const std::vector<std::string> names = write_chain(tree, "deep_", 30);
  const long before = horus_test::allocations.load();
  bool answerable = true;
  for (int i = 0; i < kLookups; ++i) {
    tree.lookup(names.front(), names.back(), kEpoch + 250ms);
    answerable = answerable && tree.can_lookup(names.back(), names.front());
  }
  EXPECT_EQ(horus_test::allocations.load() - before, 0);
  EXPECT_TRUE(answerable);
}

}  // namespace
