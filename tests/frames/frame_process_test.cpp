// The frame tree across real processes (fork): a small robot written by one process and looked
// up by another, the authority rule, and writers killed mid-update while a reader looks up.
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <random>
#include <thread>

#include "frame_test_support.hpp"
#include "horus/clock.hpp"
#include "horus/detail/process.hpp"
#include "horus/frames.hpp"
#include "private_shm_root.hpp"

namespace {

using namespace std::chrono_literals;
using frames_test::expect_transform;
using frames_test::FrameTreeTest;
using frames_test::planar;
using horus::FrameTree;
using horus::Transform;

const horus_test::PrivateShmRoot private_root("frame_process_test");

constexpr std::chrono::nanoseconds kEpoch = std::chrono::seconds(1000);

/// Forks a child that runs `body` and exits with its result (1 when it throws). The child dies
/// with the test process, so a failed assertion never leaves a writer running.
template <class Body>
pid_t fork_child(Body body) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    int code = 1;
    try {
      code = body();
    } catch (...) {
    }
    ::_exit(code);
  }
  return pid;
}

/// Kills the child when the test leaves early (a failed ASSERT returns past the kill).
class KillOnExit {
 public:
  explicit KillOnExit(pid_t pid) : pid_(pid) {}
  ~KillOnExit() {
    if (pid_ > 0 && ::waitpid(pid_, nullptr, WNOHANG) == 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  KillOnExit(const KillOnExit&) = delete;
  KillOnExit& operator=(const KillOnExit&) = delete;

 private:
  pid_t pid_;
};

int exit_code(pid_t pid) {
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The robot: map -> odom -> base_link -> {lidar (static), camera}, odom, base_link and camera
// written at 100 Hz (tick k at 10 k ms), every value linear in k so that the interpolated answer
// between ticks is the same formula at a fractional k.
Transform odom_in_map(double k) { return planar(0.01 * k, 0.005 * k, 0, 0.002 * k); }
Transform base_in_odom(double k) { return planar(0.1 * k, 0, 0, 0.01 * k); }
Transform camera_in_base(double k) { return planar(0.05, 0, 0.4, 0.003 * k); }
const Transform kLidarInBase = planar(0.2, 0, 0.3, 0);
constexpr int kTicks = 100;

TEST_F(FrameTreeTest, RobotWrittenByOneProcessIsLookedUpByAnotherAtPastTimes) {
  const pid_t writer = fork_child([this] {
    FrameTree tree(options());
    tree.set_static_transform("base_link", "lidar", kLidarInBase);
    auto next = std::chrono::steady_clock::now();
    for (int k = 0; k < kTicks; ++k) {
      const auto stamp = kEpoch + k * 10ms;
      tree.set_transform("map", "odom", odom_in_map(k), stamp);
      tree.set_transform("odom", "base_link", base_in_odom(k), stamp);
      tree.set_transform("base_link", "camera", camera_in_base(k), stamp);
      next += 10ms;
      std::this_thread::sleep_until(next);
    }
    return 0;
  });
  const KillOnExit guard(writer);
  FrameTree tree(options());
  EXPECT_TRUE(tree.wait_for("map", "camera", kEpoch + (kTicks - 1) * 10ms, 10s));
  ASSERT_EQ(exit_code(writer), 0);

  // map <- lidar at 123.4 ms (k = 12.34), by hand in the plane.
  const double k = 12.34;
  const double odom_yaw = 0.002 * k;
  const double base_yaw = odom_yaw + 0.01 * k;
  const double base_x = 0.01 * k + std::cos(odom_yaw) * 0.1 * k;
  const double base_y = 0.005 * k + std::sin(odom_yaw) * 0.1 * k;
  const double lidar_x = base_x + std::cos(base_yaw) * 0.2;
  const double lidar_y = base_y + std::sin(base_yaw) * 0.2;
  expect_transform(tree.lookup("map", "lidar", kEpoch + 123400us), lidar_x, lidar_y, 0.3, base_yaw,
                   1e-9);
  // The inverse direction.
  const Transform lidar_from_map = tree.lookup("lidar", "map", kEpoch + 123400us);
  const horus::Vector3 origin = horus::transform_point(lidar_from_map, {lidar_x, lidar_y, 0.3});
  EXPECT_NEAR(std::hypot(origin.x, origin.y, origin.z), 0, 1e-9);
  // camera <- lidar through base_link at 0.5 s (k = 50.0, an entry) and 0.555 s (between).
  for (const double at : {50.0, 55.5}) {
    const double camera_yaw = 0.003 * at;
    const double dx = 0.2 - 0.05;
    const double dz = 0.3 - 0.4;
    expect_transform(tree.lookup("camera", "lidar",
                                 kEpoch + std::chrono::microseconds(static_cast<long>(at * 10000))),
                     std::cos(camera_yaw) * dx, -std::sin(camera_yaw) * dx, dz, -camera_yaw, 1e-9);
  }
  // The writer has exited: its static frame stays, its dynamic history too.
  EXPECT_EQ(tree.lookup_stamped("map", "lidar").stamp, kEpoch + (kTicks - 1) * 10ms);
  const std::string text = tree.as_text();
  EXPECT_NE(text.find("map\n  odom  [dynamic, 100.0 Hz, pid " + std::to_string(writer)),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("(exited)"), std::string::npos) << text;
}

TEST_F(FrameTreeTest, ASecondLiveAuthorityIsRefusedAndADeadOnesFramesAreTakenOver) {
  int ready[2];
  int release[2];
  ASSERT_EQ(::pipe(ready), 0);
  ASSERT_EQ(::pipe(release), 0);
  const pid_t first = fork_child([&] {
    FrameTree tree(options());
    tree.set_transform("map", "odom", planar(1, 0, 0, 0), kEpoch);
    char byte = 1;
    if (::write(ready[1], &byte, 1) != 1) return 2;
    return ::read(release[0], &byte, 1) == 1 ? 0 : 3;
  });
  const KillOnExit guard(first);
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);
  FrameTree tree(options());
  try {
    tree.set_transform("map", "odom", planar(2, 0, 0, 0), kEpoch + 10ms);
    FAIL() << "a second authority of odom was accepted";
  } catch (const horus::FrameAuthorityError& error) {
    EXPECT_EQ(error.pid(), static_cast<std::uint32_t>(first));
    EXPECT_EQ(error.program(), horus::detail::process_name(static_cast<std::uint32_t>(first)));
    EXPECT_FALSE(error.program().empty());
    EXPECT_NE(std::string(error.what())
                  .find("process " + std::to_string(first) + " (" + error.program() + ")"),
              std::string::npos)
        << error.what();
  }
  // Another child frame is this process's to set.
  tree.set_transform("odom", "base_link", planar(0, 1, 0, 0), kEpoch);
  expect_transform(tree.lookup("map", "base_link", kEpoch), 1, 1, 0, 0);

  ::kill(first, SIGKILL);
  EXPECT_EQ(exit_code(first), -1);
  tree.set_transform("map", "odom", planar(2, 0, 0, 0), kEpoch + 10ms);
  expect_transform(tree.lookup("map", "odom", kEpoch + 5ms), 1.5, 0, 0, 0);
  EXPECT_EQ(tree.frames().at(1).name, "odom");
  EXPECT_EQ(tree.frames().at(1).authority_pid, static_cast<std::uint32_t>(::getpid()));
  for (const int fd : {ready[0], ready[1], release[0], release[1]}) ::close(fd);
}

/// What every writer of the kill loop writes at `stamp`: x = s, y = 2 s, z = -s and a yaw of
/// s / 1000 rad, s being ms since `start`. A torn entry breaks one of these relations.
Transform kill_loop_value(std::chrono::nanoseconds stamp, std::chrono::nanoseconds start) {
  const double s = static_cast<double>((stamp - start).count()) / 1e6;
  return planar(s, 2 * s, -s, s * 1e-3);
}

::testing::AssertionResult consistent(const Transform& t) {
  const double s = t.translation.x;
  if (std::abs(t.translation.y - 2 * s) > 1e-6 || std::abs(t.translation.z + s) > 1e-6) {
    return ::testing::AssertionFailure()
           << "torn translation " << s << ", " << t.translation.y << ", " << t.translation.z;
  }
  return frames_test::same_angle(frames_test::yaw_of(t.rotation), s * 1e-3, 1e-6);
}

TEST_F(FrameTreeTest, WritersKilledMidUpdateNeverLeaveATornTransformNorAStuckReader) {
  FrameTree tree(options());
  const std::chrono::nanoseconds start = horus::now();
  std::mt19937 random(7);
  long lookups = 0;
  auto slowest = std::chrono::nanoseconds::zero();
  for (int round = 0; round < 40; ++round) {
    const std::uint32_t changes_before = tree.change_count();
    const pid_t writer = fork_child([this, start] {
      FrameTree own(options());
      for (;;) {
        const std::chrono::nanoseconds stamp = horus::now();
        own.set_transform("world", "link", kill_loop_value(stamp, start), stamp);
      }
      return 0;
    });
    const KillOnExit guard(writer);
    // The kill lands while the writer writes: on a loaded machine a fresh child may need a while
    // before its first write.
    ASSERT_NE(tree.wait_for_change(changes_before, 10s), changes_before) << "round " << round;
    const auto until =
        std::chrono::steady_clock::now() + std::chrono::milliseconds(2 + random() % 13);
    while (std::chrono::steady_clock::now() < until) {
      const auto began = std::chrono::steady_clock::now();
      try {
        const horus::StampedTransform latest = tree.lookup_stamped("world", "link");
        ASSERT_TRUE(consistent(latest.transform)) << "round " << round;
        const Transform past = tree.lookup("world", "link", latest.stamp - 300us);
        ASSERT_TRUE(consistent(past)) << "round " << round;
        lookups += 2;
      } catch (const horus::UnknownFrameError&) {
        // The first writer has not written yet.
      } catch (const horus::ExtrapolationError& e) {
        // Less than 300 us of history yet, or no transform yet.
      } catch (const horus::FrameError& e) {
        // The writer writes as fast as it can, lapping the 1024 entries in about 100 us: a
        // lookup 300 us back can find its entries overwritten on every attempt, and then says
        // so (the documented answer) rather than spinning.
        ASSERT_NE(std::string(e.what()).find("were rewritten during"), std::string::npos)
            << e.what();
      }
      slowest = std::max(slowest, std::chrono::steady_clock::now() - began);
    }
    ::kill(writer, SIGKILL);
    ASSERT_EQ(exit_code(writer), -1);
  }
  EXPECT_GT(lookups, 0);
  EXPECT_LT(slowest, 1s) << "a lookup was stuck behind a killed writer";
  const std::vector<horus::StampedTransform> history = tree.history("link");
  ASSERT_FALSE(history.empty());
  for (const horus::StampedTransform& entry : history) {
    ASSERT_TRUE(consistent(entry.transform)) << "at " << entry.stamp.count();
  }
}

}  // namespace
