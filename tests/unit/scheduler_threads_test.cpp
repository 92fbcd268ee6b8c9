// The threads the scheduler really gets: cores(), a node's core() and priority(), isolated CPUs
// for rt(true), or the degradation reported when the machine refuses; and name, verbose and
// tick_for(duration, names).
#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "horus/error.hpp"
#include "horus/literals.hpp"
#include "horus/log.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;

namespace {

std::vector<int> affinity_of_this_thread() {
  cpu_set_t set;
  CPU_ZERO(&set);
  pthread_getaffinity_np(pthread_self(), sizeof(set), &set);
  std::vector<int> cpus;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (CPU_ISSET(c, &set)) cpus.push_back(c);
  }
  return cpus;
}

/// Records, on its first tick, the affinity and policy of the thread that runs it.
class ThreadProbe : public horus::Node {
 public:
  explicit ThreadProbe(std::string name) : name_(std::move(name)) {}
  std::string_view name() const override { return name_; }
  void tick() override {
    ticks.fetch_add(1);
    std::lock_guard lock(mutex);
    if (!seen) {
      seen = true;
      cpus = affinity_of_this_thread();
      sched_param param{};
      pthread_getschedparam(pthread_self(), &policy, &param);
      priority = param.sched_priority;
    }
  }
  std::atomic<int> ticks{0};
  std::mutex mutex;
  bool seen = false;
  std::vector<int> cpus;
  int policy = -1;
  int priority = -1;

 private:
  std::string name_;
};

int last_cpu() { return static_cast<int>(std::max(1U, std::thread::hardware_concurrency())) - 1; }

bool has_degradation(const horus::Scheduler& sched, const std::string& text) {
  const auto list = sched.degradations();
  return std::any_of(list.begin(), list.end(),
                     [&](const std::string& d) { return d.find(text) != std::string::npos; });
}

horus::SchedulerConfig real() {
  return horus::SchedulerConfig{}.tick_rate(200_hz).handle_signals(false);
}

}  // namespace

TEST(SchedulerThreads, CoresPinsTheMainLoopAndNodeThreads) {
  auto main_node = std::make_shared<ThreadProbe>("main_node");
  auto rt_node = std::make_shared<ThreadProbe>("rt_node");
  horus::Scheduler sched{real().cores({last_cpu()})};
  sched.add(main_node).build();
  sched.add(rt_node).rate(200_hz).build();
  const auto before = affinity_of_this_thread();
  sched.run_for(50_ms);
  ASSERT_TRUE(main_node->seen && rt_node->seen);
  EXPECT_EQ(main_node->cpus, std::vector<int>{last_cpu()});
  EXPECT_EQ(rt_node->cpus, std::vector<int>{last_cpu()});
  EXPECT_EQ(affinity_of_this_thread(), before);  // the caller's own affinity is given back
}

TEST(SchedulerThreads, ANodesCorePinsItsThread) {
  auto pinned = std::make_shared<ThreadProbe>("pinned");
  auto io = std::make_shared<ThreadProbe>("io");
  horus::Scheduler sched{real()};
  sched.add(pinned).rate(200_hz).core(0).build();
  sched.add(io).async_io().core(last_cpu()).build();
  sched.run_for(50_ms);
  ASSERT_TRUE(pinned->seen && io->seen);
  EXPECT_EQ(pinned->cpus, std::vector<int>{0});
  EXPECT_EQ(io->cpus, std::vector<int>{last_cpu()});
}

TEST(SchedulerThreads, PriorityIsSchedFifoWhenAllowedElseADegradation) {
  auto node = std::make_shared<ThreadProbe>("fifo");
  horus::Scheduler sched{real().rt(true)};
  sched.add(node).rate(200_hz).priority(20).build();
  sched.run_for(50_ms);
  ASSERT_TRUE(node->seen);
  if (sched.capabilities().rt_scheduling) {
    EXPECT_EQ(node->policy, SCHED_FIFO);
    EXPECT_EQ(node->priority, 20);
  } else {
    EXPECT_EQ(node->policy, SCHED_OTHER);
    EXPECT_TRUE(has_degradation(sched, "SCHED_FIFO unavailable"));
    EXPECT_FALSE(sched.has_full_rt());
  }
}

TEST(SchedulerThreads, PriorityWithoutRtIsIgnoredAndReported) {
  auto node = std::make_shared<ThreadProbe>("nofifo");
  horus::Scheduler sched{real()};
  sched.add(node).rate(200_hz).priority(20).build();
  sched.run_for(30_ms);
  ASSERT_TRUE(node->seen);
  EXPECT_EQ(node->policy, SCHED_OTHER);
  EXPECT_TRUE(has_degradation(sched, "priority 20 of node 'nofifo' ignored: rt is off"));
}

TEST(SchedulerThreads, RtThreadsGoToIsolatedCpusOrTheLackIsReported) {
  std::ifstream file("/sys/devices/system/cpu/isolated");
  std::string isolated_text;
  std::getline(file, isolated_text);
  auto node = std::make_shared<ThreadProbe>("control");
  auto best_effort = std::make_shared<ThreadProbe>("display");
  horus::Scheduler sched{real().rt(true)};
  sched.add(node).rate(200_hz).build();
  sched.add(best_effort).build();
  const auto everything = affinity_of_this_thread();
  sched.run_for(50_ms);
  ASSERT_TRUE(node->seen && best_effort->seen);
  const auto isolated = sched.capabilities().isolated_cpus;
  EXPECT_EQ(isolated.empty(), isolated_text.empty());
  if (isolated.empty()) {
    EXPECT_FALSE(sched.capabilities().cpu_isolation);
    EXPECT_TRUE(has_degradation(sched, "no isolated CPUs"));
    EXPECT_EQ(node->cpus, everything);
  } else {
    EXPECT_TRUE(sched.capabilities().cpu_isolation);
    EXPECT_EQ(node->cpus, isolated);
  }
  EXPECT_EQ(best_effort->cpus, everything);  // only Rt threads move
}

// CPUs reserved by a cpuset or a container rather than isolcpus: HORUS_ISOLATED_CPUS names them,
// and the CPUs this process may not use are left out.
TEST(SchedulerThreads, RtThreadsGoToTheCpusHorusIsolatedCpusReserves) {
  const auto everything = affinity_of_this_thread();
  const int reserved = everything.back();
  const std::string list = std::to_string(reserved) + "," + std::to_string(CPU_SETSIZE - 1);
  ::setenv("HORUS_ISOLATED_CPUS", list.c_str(), 1);
  auto node = std::make_shared<ThreadProbe>("control");
  auto best_effort = std::make_shared<ThreadProbe>("display");
  horus::Scheduler sched{real().rt(true)};
  ::unsetenv("HORUS_ISOLATED_CPUS");
  sched.add(node).rate(200_hz).build();
  sched.add(best_effort).build();
  sched.run_for(200_ms);
  ASSERT_TRUE(node->seen) << "rt node never ran";
  ASSERT_TRUE(best_effort->seen) << "best-effort node never ran";
  EXPECT_EQ(sched.capabilities().isolated_cpus, std::vector<int>{reserved});
  EXPECT_TRUE(sched.capabilities().cpu_isolation);
  EXPECT_FALSE(has_degradation(sched, "no isolated CPUs"));
  EXPECT_EQ(node->cpus, std::vector<int>{reserved});
  EXPECT_EQ(best_effort->cpus, everything);
}

TEST(SchedulerThreads, NameIsReportedAndInErrors) {
  horus::Scheduler sched{real().name("agv")};
  EXPECT_EQ(sched.name(), "agv");
  EXPECT_EQ(sched.config().name(), "agv");
  sched.add(std::make_shared<ThreadProbe>("a")).build();
  sched.run_for(10_ms);
  try {
    sched.run_for(10_ms);
    FAIL() << "expected horus::Error";
  } catch (const horus::Error& e) {
    EXPECT_NE(std::string(e.what()).find("horus::Scheduler 'agv'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(horus::Scheduler{horus::SchedulerConfig{}.name("")}, horus::Error);
}

TEST(SchedulerThreads, AnUnnamedSchedulerIsNamedAfterTheProgram) {
  const std::string program = std::filesystem::read_symlink("/proc/self/exe").filename().string();
  EXPECT_EQ(horus::SchedulerConfig{}.name(), program);
  horus::Scheduler sched;
  EXPECT_EQ(sched.name(), program);
}

TEST(SchedulerThreads, VerbosePrintsTheTimingReportAndWhyItStopped) {
  const auto run_and_capture = [](bool verbose) {
    horus::Scheduler sched{real().name("talky").verbose(verbose)};
    sched.add(std::make_shared<ThreadProbe>("reporter")).build();
    testing::internal::CaptureStderr();
    sched.run_for(20_ms);
    sched.stop();
    horus::log::flush();
    return testing::internal::GetCapturedStderr();
  };
  const std::string loud = run_and_capture(true);
  EXPECT_NE(loud.find("node             class"), std::string::npos) << loud;
  EXPECT_NE(loud.find("reporter"), std::string::npos) << loud;
  const std::string quiet = run_and_capture(false);
  EXPECT_EQ(quiet.find("node             class"), std::string::npos) << quiet;
}

TEST(SchedulerThreads, TickForRunsOnlyTheNamedNodesAndKeepsThemAlive) {
  auto chosen = std::make_shared<ThreadProbe>("chosen");
  auto frozen = std::make_shared<ThreadProbe>("frozen");
  horus::Scheduler sched{real()};
  sched.add(chosen).rate(200_hz).build();
  sched.add(frozen).build();
  sched.tick_for(30_ms, {"chosen"});
  const int after_first = chosen->ticks;
  EXPECT_GT(after_first, 0);
  EXPECT_EQ(frozen->ticks, 0);
  EXPECT_EQ(sched.node_info("chosen")->state, horus::NodeState::Running);  // not shut down
  sched.tick_for(30_ms, {"chosen"});
  EXPECT_GT(chosen->ticks, after_first);
  EXPECT_EQ(frozen->ticks, 0);
  try {
    sched.tick_for(10_ms, {"nobody"});
    FAIL() << "expected horus::Error";
  } catch (const horus::Error& e) {
    EXPECT_STREQ(e.what(), "tick_for: no node named 'nobody'");
  }
}
