// The horus-blackbox command on a file a scheduler wrote: every event, the --node / --kind /
// --last filters, its errors (missing file, bad option) with their exit statuses, and the last
// ticks (node, start, duration, topics) of a dump written by a fatal stop and by a crash.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "horus/literals.hpp"
#include "horus/scheduler.hpp"
#include "horus/topic.hpp"
#include "private_shm_root.hpp"

using namespace horus::literals;

namespace {

// Every test runs in its own process (gtest_discover_tests): the topics live under a private
// root outside /dev/shm, removed when the test ends.
const horus_test::PrivateShmRoot shm_root{"blackboxtool"};

struct Outcome {
  int status;
  std::string output;  // stdout and stderr together
};

Outcome run_tool(const std::string& arguments) {
  const std::string command = std::string(HORUS_BLACKBOX_TOOL) + " " + arguments + " 2>&1";
  std::FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) throw std::runtime_error("popen failed");
  Outcome outcome{0, {}};
  std::array<char, 4096> buffer{};
  while (const std::size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe)) {
    outcome.output.append(buffer.data(), n);
  }
  const int status = ::pclose(pipe);
  outcome.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return outcome;
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

class Failing : public horus::Node {
 public:
  std::string_view name() const override { return "motor"; }
  void tick() override {
    if (++ticks_ <= 3) throw std::runtime_error("encoder lost");
  }

 private:
  int ticks_ = 0;
};

class Quiet : public horus::Node {
 public:
  std::string_view name() const override { return "lidar"; }
  void tick() override {}
};

class BlackboxTool : public ::testing::Test {
 protected:
  void SetUp() override {
    file_ = std::filesystem::temp_directory_path() /
            ("horus_blackbox_tool_" + std::to_string(::getpid()) + ".blackbox");
    horus::Scheduler sched{horus::SchedulerConfig{}.name("agv").blackbox_mb(1).deterministic(true)};
    sched.add(std::make_shared<Failing>()).failure_policy(horus::FailurePolicy::Ignore{}).build();
    sched.add(std::make_shared<Quiet>()).build();
    for (int i = 0; i < 5; ++i) sched.tick_once();
    sched.dump_blackbox(file_);
  }
  void TearDown() override { std::filesystem::remove(file_); }
  std::filesystem::path file_;
};

}  // namespace

TEST_F(BlackboxTool, PrintsEveryEventWithAHeader) {
  const Outcome out = run_tool(file_.string());
  EXPECT_EQ(out.status, 0) << out.output;
  EXPECT_NE(out.output.find(file_.string() + ": 6 events (6 shown)"), std::string::npos)
      << out.output;
  EXPECT_EQ(count(out.output, "NodeError"), 3U) << out.output;
  EXPECT_EQ(count(out.output, "encoder lost"), 3U) << out.output;
  EXPECT_EQ(count(out.output, "NodeInit "), 2U) << out.output;
  EXPECT_EQ(count(out.output, "SchedulerStart"), 1U) << out.output;
}

TEST_F(BlackboxTool, FiltersByNodeKindAndLast) {
  const Outcome lidar = run_tool(file_.string() + " --node lidar");
  EXPECT_EQ(lidar.status, 0);
  EXPECT_NE(lidar.output.find("(1 shown)"), std::string::npos) << lidar.output;
  EXPECT_EQ(count(lidar.output, "motor"), 0U) << lidar.output;

  const Outcome errors = run_tool(file_.string() + " --kind NodeError --last 2");
  EXPECT_EQ(errors.status, 0);
  EXPECT_NE(errors.output.find("(2 shown)"), std::string::npos) << errors.output;
  EXPECT_EQ(count(errors.output, "NodeError"), 2U) << errors.output;
}

TEST_F(BlackboxTool, ReportsAMissingFileAndBadArguments) {
  const Outcome missing = run_tool(file_.string() + ".nope");
  EXPECT_EQ(missing.status, 1);
  EXPECT_NE(missing.output.find("horus-blackbox: "), std::string::npos) << missing.output;
  EXPECT_NE(missing.output.find(".nope"), std::string::npos) << missing.output;

  const Outcome option = run_tool(file_.string() + " --colour");
  EXPECT_EQ(option.status, 2);
  EXPECT_NE(option.output.find("unknown option --colour"), std::string::npos) << option.output;

  const Outcome last = run_tool(file_.string() + " --last -1");
  EXPECT_EQ(last.status, 2);
  EXPECT_NE(last.output.find("--last needs a non-negative number"), std::string::npos)
      << last.output;

  EXPECT_EQ(run_tool("--help").status, 0);
}

namespace {

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  for (std::size_t end = text.find('\n'); end != std::string::npos;
       start = end + 1, end = text.find('\n', start)) {
    lines.push_back(text.substr(start, end - start));
  }
  return lines;
}

/// The tick rows of the tool's output (after the ticks' header line).
std::vector<std::string> tick_rows(const std::string& output) {
  const std::vector<std::string> lines = lines_of(output);
  std::vector<std::string> rows;
  bool in_ticks = false;
  for (const std::string& line : lines) {
    if (in_ticks) rows.push_back(line);
    if (line.starts_with("tick start (UTC)")) in_ticks = true;
  }
  return rows;
}

class Driver : public horus::Node {
 public:
  std::string_view name() const override { return "driver"; }
  void tick() override { cmd_.send(++sent_); }
  horus::Topic<std::int32_t> cmd_{"rover.cmd"};
  std::int32_t sent_ = 0;
};

/// Receives the driver's commands; fails (throws, or aborts the process) in its `last`-th tick.
class Arm : public horus::Node {
 public:
  Arm(int last, bool crash) : last_(last), crash_(crash) {}
  std::string_view name() const override { return "arm"; }
  void tick() override {
    while (cmd_.try_recv()) {
    }
    if (++ticks_ < last_) return;
    if (crash_) std::abort();
    throw std::runtime_error("joint 3 overheated");
  }
  horus::Topic<std::int32_t> cmd_{"rover.cmd"};
  int last_;
  bool crash_;
  int ticks_ = 0;
};

}  // namespace

TEST(BlackboxToolTicks, AFatalStopDumpShowsTheLastTicksWithNodeDurationAndTopics) {
  const auto file = std::filesystem::temp_directory_path() /
                    ("horus_blackbox_fatal_" + std::to_string(::getpid()) + ".blackbox");
  {
    horus::Scheduler sched{
        horus::SchedulerConfig{}.name("rover").deterministic(true).blackbox_mb(1).blackbox_path(
            file)};
    sched.add(std::make_shared<Driver>()).order(0).build();
    sched.add(std::make_shared<Arm>(5, false)).order(1).build();  // FailurePolicy::Fatal
    EXPECT_NE(sched.run(), 0);
  }
  ASSERT_TRUE(std::filesystem::exists(file)) << "the fatal stop wrote no blackbox";
  const Outcome out = run_tool(file.string() + " --ticks 4");
  std::filesystem::remove(file);
  EXPECT_EQ(out.status, 0) << out.output;
  EXPECT_NE(out.output.find(": 10 ticks (4 shown)"), std::string::npos) << out.output;
  const std::vector<std::string> rows = tick_rows(out.output);
  ASSERT_EQ(rows.size(), 4U) << out.output;
  // Oldest first: driver and arm alternate, the arm's failing fifth tick (index 4) last.
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const bool arm = i % 2 == 1;
    const std::string& row = rows[i];
    EXPECT_NE(row.find(arm ? " arm " : " driver "), std::string::npos) << row;
    EXPECT_NE(row.find(arm ? "rover.cmd 0/1" : "rover.cmd 1/0"), std::string::npos) << row;
    EXPECT_NE(row.find(std::string(" ") + (i < 2 ? "3" : "4") + " "), std::string::npos) << row;
    EXPECT_EQ(row.find("Z  "), 26U) << "the tick's start time first: " << row;
  }
  EXPECT_NE(out.output.find("joint 3 overheated"), std::string::npos) << out.output;
}

TEST(BlackboxToolTicks, ACrashDumpShowsTheTicksBeforeTheCrash) {
  const auto file = std::filesystem::temp_directory_path() /
                    ("horus_blackbox_crash_" + std::to_string(::getpid()) + ".blackbox");
  std::filesystem::remove(file);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    horus::Scheduler sched{
        horus::SchedulerConfig{}.name("rover").tick_rate(200_hz).blackbox_mb(1).blackbox_path(
            file)};
    sched.add(std::make_shared<Driver>()).order(0).build();
    sched.add(std::make_shared<Arm>(3, true)).order(1).build();
    sched.run();
    std::_Exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGABRT) << "status " << status;
  ASSERT_TRUE(std::filesystem::exists(file)) << "the crash wrote no blackbox";
  const Outcome out = run_tool(file.string() + " --node arm");
  const Outcome all = run_tool(file.string() + " --ticks 100");
  std::filesystem::remove(file);
  EXPECT_EQ(out.status, 0) << out.output;
  // The arm's two ticks before the one that aborted (its record is written when a tick ends).
  const std::vector<std::string> rows = tick_rows(out.output);
  ASSERT_EQ(rows.size(), 2U) << out.output;
  for (const std::string& row : rows) {
    EXPECT_NE(row.find(" arm "), std::string::npos) << row;
    EXPECT_NE(row.find("rover.cmd 0/1"), std::string::npos) << row;
  }
  // The driver ticked a third time, just before the arm's fatal tick.
  EXPECT_EQ(tick_rows(all.output).size(), 5U) << all.output;
  EXPECT_NE(tick_rows(all.output).back().find(" driver "), std::string::npos) << all.output;
}
