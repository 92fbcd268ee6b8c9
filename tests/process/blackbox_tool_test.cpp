// The horus-blackbox command on a file a scheduler wrote: every event, the --node / --kind /
// --last filters, and its errors (missing file, bad option) with their exit statuses.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;

namespace {

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
