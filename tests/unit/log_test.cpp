// Logging: the node's name on lines from its callbacks, the level filter, the stable stderr
// format, the shared-memory ring read_log() reads, dropped-line accounting, and the scheduler's
// and on_error()'s lines going through it.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <new>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "allocation_counter.hpp"
#include "horus/error.hpp"
#include "horus/literals.hpp"
#include "horus/log.hpp"
#include "horus/scheduler.hpp"
#include "private_shm_root.hpp"

namespace {

// Every test runs in its own process (gtest_discover_tests), so this gives each one a private
// shared-memory root before the first line opens the ring.
const horus_test::PrivateShmRoot shm_root{"logtest"};

using horus_test::allocations;

class Lambda : public horus::Node {
 public:
  Lambda(std::string name, std::function<void()> body) : name_(std::move(name)), body_(body) {}
  std::string_view name() const override { return name_; }
  void tick() override { body_(); }

 private:
  std::string name_;
  std::function<void()> body_;
};

std::vector<horus::LogRecord> records_from(std::string_view source) {
  std::vector<horus::LogRecord> out;
  for (auto& r : horus::read_log().records) {
    if (r.source == source) out.push_back(r);
  }
  return out;
}

int evaluated(int& counter) { return ++counter; }

}  // namespace

TEST(Log, LinesFromATickCarryTheNodeNameInTheStableFormat) {
  horus::Scheduler sched;
  sched
      .add(std::make_shared<Lambda>(
          "lidar", [] { HORUS_LOG_INFO("connected on %s at %d baud", "/dev/ttyUSB0", 115200); }))
      .build();
  testing::internal::CaptureStderr();
  sched.tick_once();
  horus::log::flush();
  const std::string err = testing::internal::GetCapturedStderr();
  const std::regex line(
      R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z INFO lidar: connected on /dev/ttyUSB0 at 115200 baud\n)");
  EXPECT_TRUE(std::regex_search(err, line)) << err;

  const auto records = records_from("lidar");
  ASSERT_EQ(records.size(), 1U);
  EXPECT_EQ(records[0].level, horus::LogLevel::Info);
  EXPECT_EQ(records[0].message, "connected on /dev/ttyUSB0 at 115200 baud");
  EXPECT_EQ(records[0].pid, static_cast<std::uint32_t>(::getpid()));
  EXPECT_NE(err.find(horus::format_log_line(records[0]) + "\n"), std::string::npos) << err;
}

TEST(Log, LinesOutsideCallbacksAreKeptWithADashSource) {
  EXPECT_EQ(horus::log::current_node(), "");
  horus::log::warn("from main: %d", 7);
  const auto records = records_from("-");
  ASSERT_EQ(records.size(), 1U);
  EXPECT_EQ(records[0].level, horus::LogLevel::Warn);
  EXPECT_EQ(records[0].message, "from main: 7");
}

TEST(Log, CurrentNodeIsSetOnlyInsideCallbacks) {
  std::string seen;
  horus::Scheduler sched;
  sched.add(std::make_shared<Lambda>("probe", [&] { seen = horus::log::current_node(); })).build();
  sched.tick_once();
  EXPECT_EQ(seen, "probe");
  EXPECT_EQ(horus::log::current_node(), "");
}

TEST(Log, LevelFilterDropsLinesAndTheMacroSkipsItsArguments) {
  int counter = 0;
  HORUS_LOG_DEBUG("never %d", evaluated(counter));
  EXPECT_EQ(counter, 0);
  horus::log::debug("dropped too");
  EXPECT_TRUE(records_from("-").empty());

  horus::log::set_level(horus::LogLevel::Debug);
  HORUS_LOG_DEBUG("now %d", evaluated(counter));
  EXPECT_EQ(counter, 1);
  ASSERT_EQ(records_from("-").size(), 1U);
  EXPECT_EQ(records_from("-")[0].level, horus::LogLevel::Debug);

  horus::log::set_level(horus::LogLevel::Error);
  horus::log::warn("below error");
  EXPECT_EQ(records_from("-").size(), 1U);
  horus::log::set_level(horus::LogLevel::Info);
}

TEST(Log, EmitLogsInTheGivenNodesName) {
  horus::log::emit(horus::LogLevel::Error, "py_motor", "overheated");
  const auto records = records_from("py_motor");
  ASSERT_EQ(records.size(), 1U);
  EXPECT_EQ(records[0].message, "overheated");
  EXPECT_EQ(records[0].level, horus::LogLevel::Error);
}

TEST(Log, LongMessagesAndSourcesAreCut) {
  const std::string long_source(100, 's');
  horus::log::emit(horus::LogLevel::Info, long_source, std::string(1000, 'm'));
  const auto records = records_from(std::string(horus::kMaxLogSource, 's'));
  ASSERT_EQ(records.size(), 1U);
  EXPECT_EQ(records[0].message, std::string(horus::kMaxLogText, 'm'));
}

TEST(Log, DefaultOnErrorLogsInTheNodesName) {
  horus::Scheduler sched;
  sched.add(std::make_shared<Lambda>("motor", [] { throw std::runtime_error("stalled"); }))
      .failure_policy(horus::FailurePolicy::Ignore{})
      .build();
  sched.tick_once();
  const auto records = records_from("motor");
  ASSERT_EQ(records.size(), 1U);
  EXPECT_EQ(records[0].level, horus::LogLevel::Error);
  EXPECT_EQ(records[0].message, "Node error: stalled");
}

TEST(Log, TheSchedulersOwnWarningsCarryItsName) {
  class FailsInit : public horus::Node {
   public:
    std::string_view name() const override { return "camera"; }
    void init() override { throw std::runtime_error("no device"); }
    void tick() override {}
  };
  horus::Scheduler sched{horus::SchedulerConfig{}.name("agv")};
  sched.add(std::make_shared<FailsInit>()).failure_policy(horus::FailurePolicy::Ignore{}).build();
  sched.tick_once();
  const auto records = records_from("@agv");
  ASSERT_EQ(records.size(), 1U);
  EXPECT_EQ(records[0].message, "node 'camera' excluded: init() failed: no device");
}

TEST(Log, AMissIsLoggedInTheNodesNameWhateverItsPolicyOnceNotPerMiss) {
  using namespace horus::literals;
  horus::Scheduler sched{horus::SchedulerConfig{}.name("busy")};
  const auto slow = [] { std::this_thread::sleep_for(std::chrono::milliseconds(2)); };
  sched.add(std::make_shared<Lambda>("warned", slow)).rate(1000_hz).deadline(50_us).build();
  sched.add(std::make_shared<Lambda>("skipped", slow))
      .rate(1000_hz)
      .deadline(50_us)
      .on_miss(horus::Miss::Skip)
      .build();
  for (int i = 0; i < 3; ++i) sched.tick_once();  // warned misses 3 times, skipped twice
  ASSERT_EQ(sched.node_metrics("warned")->deadline_misses, 3U);
  ASSERT_EQ(sched.node_metrics("skipped")->deadline_misses, 2U);
  for (const std::string node : {"warned", "skipped"}) {
    std::vector<horus::LogRecord> lines;
    for (const auto& record : records_from("@busy")) {
      if (record.message.find("node '" + node + "' missed its deadline") != std::string::npos) {
        lines.push_back(record);
      }
    }
    ASSERT_EQ(lines.size(), 1U) << node << ": the first miss, then at most one line per interval";
    EXPECT_EQ(lines[0].level, horus::LogLevel::Warn);
    EXPECT_NE(lines[0].message.find("; misses: 1 by this node, "), std::string::npos)
        << lines[0].message;
    EXPECT_NE(lines[0].message.find(" of max_deadline_misses 100 in total"), std::string::npos)
        << lines[0].message;
  }
}

TEST(Log, EveryLineReachesStderrOrIsCountedAsDroppedAndTheRingKeepsTheNewest) {
  const auto before = horus::log::stats();
  const auto ring_before = horus::read_log();
  constexpr int kLines = 6000;  // more than either ring holds
  testing::internal::CaptureStderr();
  for (int i = 0; i < kLines; ++i) horus::log::info("burst %d", i);
  horus::log::flush();
  const std::string err = testing::internal::GetCapturedStderr();
  const auto after = horus::log::stats();
  EXPECT_EQ(after.logged - before.logged, static_cast<std::uint64_t>(kLines));
  std::size_t printed = 0;
  std::istringstream lines(err);
  for (std::string line; std::getline(lines, line);) {
    if (line.find(" INFO -: burst ") != std::string::npos) ++printed;
  }
  EXPECT_EQ(printed + (after.dropped - before.dropped), static_cast<std::size_t>(kLines));

  const auto ring = horus::read_log();
  EXPECT_EQ(ring.written - ring_before.written, static_cast<std::uint64_t>(kLines));
  ASSERT_FALSE(ring.records.empty());
  EXPECT_LT(ring.records.size(), static_cast<std::size_t>(kLines));
  EXPECT_EQ(ring.records.back().message, "burst " + std::to_string(kLines - 1));
  for (std::size_t i = 1; i < ring.records.size(); ++i) {
    EXPECT_LT(ring.records[i - 1].sequence, ring.records[i].sequence);
  }
}

TEST(Log, LoggingFromATickDoesNotAllocate) {
  horus::Scheduler sched;  // opens the ring and starts the writer
  long during = -1;
  sched
      .add(std::make_shared<Lambda>("rt",
                                    [&] {
                                      const long start = allocations.load();
                                      for (int i = 0; i < 100; ++i)
                                        HORUS_LOG_INFO("tick %d value %.3f", i, 0.5 * i);
                                      during = allocations.load() - start;
                                    }))
      .build();
  sched.tick_once();
  EXPECT_EQ(during, 0);
}

TEST(Log, ReadLogOfANamespaceWithoutLinesIsEmpty) {
  const auto snapshot = horus::read_log("nobody_logged_here");
  EXPECT_TRUE(snapshot.records.empty());
  EXPECT_EQ(snapshot.written, 0U);
}

TEST(Log, ReadLogRejectsAFileThatIsNotALogRing) {
  std::filesystem::create_directories(shm_root.root() + "/@logs");
  std::ofstream(shm_root.root() + "/@logs/garbage") << std::string(4096, 'x');
  try {
    horus::read_log("garbage");
    FAIL() << "expected horus::Error";
  } catch (const horus::Error& e) {
    EXPECT_NE(std::string(e.what()).find("@logs/garbage"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("bad magic"), std::string::npos) << e.what();
  }
}

TEST(Log, ToStringNamesEveryLevel) {
  EXPECT_EQ(horus::to_string(horus::LogLevel::Debug), "DEBUG");
  EXPECT_EQ(horus::to_string(horus::LogLevel::Info), "INFO");
  EXPECT_EQ(horus::to_string(horus::LogLevel::Warn), "WARN");
  EXPECT_EQ(horus::to_string(horus::LogLevel::Error), "ERROR");
}
