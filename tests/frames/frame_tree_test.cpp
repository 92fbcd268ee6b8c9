// The frame tree within one process: transform arithmetic, lookups, every error, the file's
// checks, wait_for, and a lookup hammer for ThreadSanitizer.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <fstream>
#include <thread>
#include <vector>

#include "frame_test_support.hpp"
#include "horus/clock.hpp"
#include "horus/frames.hpp"
#include "private_shm_root.hpp"

namespace {

using namespace std::chrono_literals;
using frames_test::expect_transform;
using frames_test::FrameTreeTest;
using frames_test::planar;
using horus::FrameTree;
using horus::Transform;

const horus_test::PrivateShmRoot private_root("frame_tree_test");

/// A fixed epoch for synthetic stamps: 1000 s.
constexpr std::chrono::nanoseconds kEpoch = std::chrono::seconds(1000);

TEST(FrameMath, ComposeInverseAndHelpers) {
  const Transform a = planar(1, 2, 3, M_PI / 2);
  const Transform round_trip = horus::compose(a, horus::inverse(a));
  expect_transform(round_trip, 0, 0, 0, 0);
  // A quarter turn about z maps x to y, then the translation applies.
  const horus::Vector3 point = horus::transform_point(a, {1, 0, 0});
  EXPECT_NEAR(point.x, 1, 1e-12);
  EXPECT_NEAR(point.y, 3, 1e-12);
  EXPECT_NEAR(point.z, 3, 1e-12);
  const horus::Vector3 vector = horus::transform_vector(a, {1, 0, 0});
  EXPECT_NEAR(vector.x, 0, 1e-12);
  EXPECT_NEAR(vector.y, 1, 1e-12);
  EXPECT_NEAR(vector.z, 0, 1e-12);
  const horus::Pose pose = horus::transform_pose(a, planar(1, 0, 0, M_PI / 4));
  expect_transform(pose, 1, 3, 3, 3 * M_PI / 4);
}

TEST(FrameMath, SlerpIsExactOnBothSidesOfTheSmallAngleSeries) {
  // Rotations about a tilted axis, from far below the series' limit (rotations about 0.2 rad
  // apart) to far above it: every interpolated rotation is the axis-angle one, to double precision,
  // and of unit length (interpolate() does not normalise).
  const horus::Vector3 axis{0.48, -0.6, 0.64};
  for (const double apart :
       {1e-9, 1e-5, 1e-3, 0.02, 0.1, 0.199, 0.1997, 0.1999, 0.2, 0.21, 1.0, 2.5}) {
    const Transform a{{}, horus::axis_angle(axis, 0.7)};
    const Transform b{{}, horus::axis_angle(axis, 0.7 + apart)};
    for (const double fraction : {0.0, 0.125, 0.5, 0.9, 1.0}) {
      const horus::Quaternion got = horus::interpolate(a, b, fraction).rotation;
      const horus::Quaternion want = horus::axis_angle(axis, 0.7 + fraction * apart);
      EXPECT_NEAR(got.x, want.x, 2e-15) << apart << " " << fraction;
      EXPECT_NEAR(got.y, want.y, 2e-15) << apart << " " << fraction;
      EXPECT_NEAR(got.z, want.z, 2e-15) << apart << " " << fraction;
      EXPECT_NEAR(got.w, want.w, 2e-15) << apart << " " << fraction;
      EXPECT_NEAR(got.x * got.x + got.y * got.y + got.z * got.z + got.w * got.w, 1, 4e-15);
    }
  }
}

TEST(FrameMath, InterpolatesLinearTranslationAndSlerpRotation) {
  const Transform half = horus::interpolate(planar(0, 0, 0, 0), planar(2, 4, 0, M_PI / 2), 0.5);
  expect_transform(half, 1, 2, 0, M_PI / 4);
  // The short way round: from +170 to -170 degrees passes through 180.
  const Transform wrapped = horus::interpolate(planar(0, 0, 0, 170 * M_PI / 180),
                                               planar(0, 0, 0, -170 * M_PI / 180), 0.5);
  expect_transform(wrapped, 0, 0, 0, M_PI);
}

TEST_F(FrameTreeTest, StaticChainComposesThroughTheCommonAncestor) {
  FrameTree tree(options());
  tree.set_static_transform("base_link", "lidar", planar(0.2, 0, 0.3, 0));
  tree.set_static_transform("base_link", "camera", planar(0.1, 0.05, 0.25, M_PI / 2));
  // camera <- lidar: lidar origin seen from the camera, by hand: (0.1, -0.05, 0.05) rotated -90.
  expect_transform(tree.lookup("camera", "lidar"), -0.05, -0.1, 0.05, -M_PI / 2);
  expect_transform(tree.lookup("lidar", "lidar"), 0, 0, 0, 0);
  const std::string text = tree.as_text();
  EXPECT_NE(text.find("base_link\n  lidar  [static"), std::string::npos) << text;
  const std::string dot = tree.as_dot();
  EXPECT_NE(dot.find("\"base_link\" -> \"camera\" [style=dashed];"), std::string::npos) << dot;
}

TEST_F(FrameTreeTest, InterpolatesBetweenNeighboursAndAnswersTheLatestCommonTime) {
  FrameTree tree(options());
  for (int k = 0; k <= 10; ++k) {
    tree.set_transform("map", "odom", planar(k, 0, 0, 0.1 * k), kEpoch + k * 10ms);
  }
  for (int k = 0; k <= 5; ++k) {
    tree.set_transform("odom", "base_link", planar(0, 2.0 * k, 0, 0), kEpoch + k * 10ms);
  }
  expect_transform(tree.lookup("map", "odom", kEpoch + 25ms), 2.5, 0, 0, 0.25);
  // map <- base_link at 2.5 ticks: odom at (2.5, 0) turned 0.25 rad, base_link 5 along its y.
  const Transform chained = tree.lookup("map", "base_link", kEpoch + 25ms);
  expect_transform(chained, 2.5 - 5 * std::sin(0.25), 5 * std::cos(0.25), 0, 0.25);
  const horus::StampedTransform latest = tree.lookup_stamped("map", "base_link");
  EXPECT_EQ(latest.stamp, kEpoch + 50ms) << "the newest time both frames have";
  expect_transform(latest.transform, 5 - 10 * std::sin(0.5), 10 * std::cos(0.5), 0, 0.5);
  const std::vector<horus::StampedTransform> history = tree.history("base_link");
  ASSERT_EQ(history.size(), 6U);
  EXPECT_EQ(history.front().parent, "odom");
  EXPECT_EQ(history.back().stamp, kEpoch + 50ms);
  const std::vector<horus::FrameInfo> frames = tree.frames();
  ASSERT_EQ(frames.size(), 3U);
  EXPECT_EQ(frames[0].name, "map");
  EXPECT_EQ(frames[0].parent, "");
  EXPECT_EQ(frames[0].authority_pid, 0U) << "a root has no authority";
  EXPECT_EQ(frames[1].name, "odom");
  EXPECT_EQ(frames[1].parent, "map");
  EXPECT_EQ(frames[1].latest, kEpoch + 100ms);
  EXPECT_EQ(frames[1].oldest, kEpoch);
  EXPECT_EQ(frames[1].updates, 11U);
  EXPECT_EQ(frames[2].authority_pid, static_cast<std::uint32_t>(::getpid()));
  EXPECT_TRUE(frames[2].authority_alive);
}

TEST_F(FrameTreeTest, ExtrapolationSaysWhichFrameAndHowFar) {
  FrameTree tree(options());
  tree.set_transform("map", "odom", planar(0, 0, 0, 0), kEpoch);
  tree.set_transform("map", "odom", planar(1, 0, 0, 0), kEpoch + 100ms);
  try {
    tree.lookup("map", "odom", kEpoch + 350ms);
    FAIL() << "a time after the newest transform was answered";
  } catch (const horus::ExtrapolationError& error) {
    EXPECT_EQ(error.frame(), "odom");
    EXPECT_FALSE(error.into_past());
    EXPECT_EQ(error.by(), 250ms);
    EXPECT_NE(std::string(error.what()).find("250.000 ms"), std::string::npos) << error.what();
  }
  try {
    tree.lookup("odom", "map", kEpoch - 20ms);
    FAIL() << "a time before the oldest transform was answered";
  } catch (const horus::ExtrapolationError& error) {
    EXPECT_TRUE(error.into_past());
    EXPECT_EQ(error.by(), 20ms);
    EXPECT_NE(std::string(error.what()).find("into the past"), std::string::npos);
  }
}

TEST_F(FrameTreeTest, HistoryOlderThanTheTreesDurationIsNotAnswered) {
  horus::FrameTreeOptions short_history = options();
  short_history.history = 100ms;
  FrameTree tree(short_history);
  EXPECT_EQ(tree.history_duration(), 100ms);
  for (int k = 0; k <= 30; ++k) {
    tree.set_transform("map", "odom", planar(k, 0, 0, 0), kEpoch + k * 10ms);
  }
  expect_transform(tree.lookup("map", "odom", kEpoch + 200ms), 20, 0, 0, 0);
  try {
    tree.lookup("map", "odom", kEpoch + 150ms);
    FAIL() << "a time older than the history duration was answered";
  } catch (const horus::ExtrapolationError& error) {
    EXPECT_TRUE(error.into_past());
    EXPECT_EQ(error.by(), 50ms);
  }
  EXPECT_EQ(tree.history("odom").size(), 11U);
}

TEST_F(FrameTreeTest, UnknownFrameNamesTheClosestOnes) {
  FrameTree tree(options());
  tree.set_static_transform("base_link", "lidar", planar(0, 0, 0, 0));
  try {
    tree.lookup("base_link", "lidra");
    FAIL() << "an unknown frame was answered";
  } catch (const horus::UnknownFrameError& error) {
    EXPECT_EQ(error.frame(), "lidra");
    ASSERT_FALSE(error.closest().empty());
    EXPECT_EQ(error.closest().front(), "lidar");
    EXPECT_NE(std::string(error.what()).find("closest: lidar"), std::string::npos) << error.what();
  }
}

TEST_F(FrameTreeTest, UnconnectedTreesAreAnError) {
  FrameTree tree(options());
  tree.set_static_transform("map", "odom", planar(0, 0, 0, 0));
  tree.set_static_transform("world", "table", planar(0, 0, 0, 0));
  EXPECT_THROW(tree.lookup("odom", "table"), horus::DisconnectedFramesError);
  std::string why;
  EXPECT_FALSE(tree.can_lookup("odom", "table", std::nullopt, &why));
  EXPECT_NE(why.find("roots \"map\" and \"world\""), std::string::npos) << why;
}

TEST_F(FrameTreeTest, StaleFrameSaysByHowMuch) {
  FrameTree tree(options());
  tree.set_static_transform("base_link", "lidar", planar(0, 0, 0, 0));
  tree.set_transform("odom", "base_link", planar(0, 0, 0, 0), horus::now() - 2s);
  try {
    tree.lookup("odom", "lidar", std::nullopt, 500ms);
    FAIL() << "a frame older than the limit was answered";
  } catch (const horus::StaleFrameError& error) {
    EXPECT_EQ(error.frame(), "base_link");
    EXPECT_GE(error.by(), 1500ms);
    EXPECT_LT(error.by(), 1600ms);
  }
  EXPECT_NO_THROW(tree.lookup("odom", "lidar", std::nullopt, 10s));
}

TEST_F(FrameTreeTest, RefusesNanNonUnitRotationCyclesAndTimeGoingBack) {
  FrameTree tree(options());
  Transform nan = planar(0, 0, 0, 0);
  nan.translation.y = std::nan("");
  EXPECT_THROW(tree.set_transform("map", "odom", nan, kEpoch), horus::InvalidTransformError);
  Transform long_rotation = planar(0, 0, 0, 0);
  long_rotation.rotation.w = 1.01;
  EXPECT_THROW(tree.set_transform("map", "odom", long_rotation, kEpoch),
               horus::InvalidTransformError);
  // Within the tolerance it is taken, and stored normalised.
  long_rotation.rotation.w = 1.0005;
  tree.set_transform("map", "odom", long_rotation, kEpoch);
  EXPECT_DOUBLE_EQ(tree.lookup("map", "odom", kEpoch).rotation.w, 1.0);
  tree.set_static_transform("odom", "base_link", planar(0, 0, 0, 0));
  try {
    tree.set_static_transform("base_link", "map", planar(0, 0, 0, 0));
    FAIL() << "a cycle was accepted";
  } catch (const horus::FrameCycleError& error) {
    EXPECT_NE(std::string(error.what()).find("\"map\" is an ancestor of \"base_link\""),
              std::string::npos)
        << error.what();
  }
  EXPECT_THROW(tree.set_static_transform("map", "map", planar(0, 0, 0, 0)), horus::FrameCycleError);
  EXPECT_THROW(tree.set_transform("map", "odom", planar(0, 0, 0, 0), kEpoch - 1ms),
               horus::FrameError);
  EXPECT_THROW(tree.set_static_transform("map", " odom", planar(0, 0, 0, 0)), horus::FrameError);
  // The refused writes changed nothing.
  EXPECT_EQ(tree.frames().size(), 3U);
  EXPECT_EQ(tree.history("odom").size(), 1U);
}

TEST_F(FrameTreeTest, ReparentingStartsTheHistoryAfresh) {
  FrameTree tree(options());
  tree.set_transform("map", "robot", planar(1, 0, 0, 0), kEpoch);
  tree.set_transform("map", "robot", planar(2, 0, 0, 0), kEpoch + 10ms);
  tree.set_static_transform("world", "map", planar(0, 0, 0, 0));
  tree.set_transform("world", "robot", planar(5, 0, 0, 0), kEpoch + 20ms);
  EXPECT_EQ(tree.history("robot").size(), 1U);
  EXPECT_THROW(tree.lookup("world", "robot", kEpoch + 5ms), horus::ExtrapolationError);
  expect_transform(tree.lookup("world", "robot", kEpoch + 20ms), 5, 0, 0, 0);
}

TEST_F(FrameTreeTest, ATreeHoldsAFixedNumberOfFrames) {
  FrameTree tree(options());
  for (std::size_t i = 1; i < horus::kMaxFrames; ++i) {
    tree.set_static_transform("root", "frame_" + std::to_string(i), planar(0, 0, 0, 0));
  }
  try {
    tree.set_static_transform("root", "one_too_many", planar(0, 0, 0, 0));
    FAIL() << "a frame past the capacity was added";
  } catch (const horus::FrameCapacityError& error) {
    EXPECT_NE(std::string(error.what()).find("256 frames"), std::string::npos) << error.what();
  }
  EXPECT_EQ(tree.frames().size(), horus::kMaxFrames);
}

TEST_F(FrameTreeTest, AMalformedFileIsAnErrorNeverACrash) {
  std::string path;
  {
    FrameTree tree(options());
    tree.set_static_transform("map", "odom", planar(0, 0, 0, 0));
    path = tree.path();
  }
  {
    // A right-sized file with a wrong magic number.
    const int fd = ::open(path.c_str(), O_RDWR);
    ASSERT_GE(fd, 0);
    const std::uint64_t junk = 0x1234;
    ASSERT_EQ(::pwrite(fd, &junk, sizeof(junk), 0), static_cast<ssize_t>(sizeof(junk)));
    ::close(fd);
    EXPECT_THROW(FrameTree{options()}, horus::FrameError);
  }
  {
    // A short file.
    ASSERT_EQ(::truncate(path.c_str(), 100), 0);
    try {
      FrameTree tree(options());
      FAIL() << "a 100-byte file was opened as a tree";
    } catch (const horus::FrameError& error) {
      EXPECT_NE(std::string(error.what()).find("100 bytes"), std::string::npos) << error.what();
    }
  }
}

TEST_F(FrameTreeTest, ACorruptEntryGivesAnErrorWithoutSpinning) {
  FrameTree tree(options());
  tree.set_transform("map", "odom", planar(0, 0, 0, 0), kEpoch);
  tree.set_transform("map", "odom", planar(1, 0, 0, 0), kEpoch + 10ms);
  // Find the newest entry's sequence word (2t+2 = 4 for ticket 1) in the file and make it odd,
  // as a writer killed in the middle of rewriting it would (and as no live writer leaves it).
  const int fd = ::open(tree.path().c_str(), O_RDWR);
  ASSERT_GE(fd, 0);
  struct stat info {};
  ASSERT_EQ(::fstat(fd, &info), 0);
  auto* bytes = static_cast<unsigned char*>(::mmap(nullptr, static_cast<std::size_t>(info.st_size),
                                                   PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0));
  ASSERT_NE(bytes, MAP_FAILED);
  // Header (4096), frame 0 ("map", the root), then frame 1 ("odom"): 128 bytes of meta, then
  // its entries of 80 bytes.
  const std::size_t frame_size = 128 + horus::kFrameHistoryEntries * 80;
  auto* seq = reinterpret_cast<std::uint64_t*>(bytes + 4096 + frame_size + 128 + 80);
  ASSERT_EQ(*seq, 4U);
  *seq = 5;
  const auto started = std::chrono::steady_clock::now();
  EXPECT_THROW(tree.lookup("map", "odom"), horus::FrameError);
  EXPECT_LT(std::chrono::steady_clock::now() - started, 1s);
  ::munmap(bytes, static_cast<std::size_t>(info.st_size));
  ::close(fd);
}

TEST_F(FrameTreeTest, WaitForSleepsUntilAWriteAnswersIt) {
  FrameTree tree(options());
  EXPECT_FALSE(tree.wait_for("map", "odom", kEpoch, 20ms)) << "nothing was ever written";
  std::thread writer([this] {
    FrameTree other(options());
    std::this_thread::sleep_for(50ms);
    other.set_transform("map", "odom", planar(0, 0, 0, 0), kEpoch);
    std::this_thread::sleep_for(20ms);
    other.set_transform("map", "odom", planar(1, 0, 0, 0), kEpoch + 10ms);
  });
  const std::uint32_t before = tree.change_count();
  const auto started = std::chrono::steady_clock::now();
  EXPECT_TRUE(tree.wait_for("map", "odom", kEpoch + 5ms, 5s));
  EXPECT_GE(std::chrono::steady_clock::now() - started, 40ms);
  EXPECT_GE(tree.change_count() - before, 2U);
  expect_transform(tree.lookup("map", "odom", kEpoch + 5ms), 0.5, 0, 0, 0);
  writer.join();
}

// Several threads look up while one writes (ThreadSanitizer checks the protocol's ordering):
// every answer is a transform that was written or lies between two that were.
TEST_F(FrameTreeTest, LookupHammer) {
  FrameTree tree(options());
  tree.set_static_transform("base", "sensor", planar(0, 0, 1, 0));
  tree.set_transform("world", "base", planar(0, 0, 0, 0), kEpoch);
  std::atomic<bool> done{false};
  std::atomic<long> answered{0};
  std::thread writer([&] {
    // At least 20000 writes, and on until the readers have answered 3000 lookups under them.
    for (int k = 1; k <= 20000 || answered.load() < 3000; ++k) {
      tree.set_transform("world", "base", planar(k, 2.0 * k, 0, k * 1e-3), kEpoch + k * 1ms);
    }
    done = true;
  });
  std::vector<std::thread> readers;
  for (int r = 0; r < 3; ++r) {
    readers.emplace_back([&, r] {
      while (!done) {
        try {
          const horus::StampedTransform latest = tree.lookup_stamped("world", "sensor");
          const auto past = latest.stamp - std::chrono::microseconds(300 + 100 * r);
          const Transform t = tree.lookup("world", "sensor", past);
          const double x = t.translation.x;
          ASSERT_NEAR(t.translation.y, 2 * x, 1e-6);
          ASSERT_NEAR(t.translation.z, 1, 1e-9);
          ASSERT_TRUE(frames_test::same_angle(frames_test::yaw_of(t.rotation), x * 1e-3, 1e-6));
          ++answered;
        } catch (const horus::ExtrapolationError&) {
          // The first millisecond has nothing older to interpolate from.
        }
      }
    });
  }
  writer.join();
  for (std::thread& reader : readers) reader.join();
  EXPECT_GE(answered.load(), 3000);
}

}  // namespace
