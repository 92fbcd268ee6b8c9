// Process announcements (horus/presence.hpp): what a process without a scheduler announces of its
// topic handles, servers and clients, from many threads at once. Each test has its own namespace;
// every wait is bounded.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include <horus/msg/cmd_vel.hpp>
#include <horus/presence.hpp>
#include <horus/scheduler.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>

namespace {

using namespace std::chrono_literals;
using horus::detail::AnnouncedUse;
using horus::detail::ProcessUse;

class PresenceTest : public ::testing::Test {
 protected:
  PresenceTest() {
    name_ = "presence" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name();
    ::setenv("HORUS_NAMESPACE", name_.c_str(), 1);
  }
  ~PresenceTest() override {
    horus::remove_namespace(name_);
    ::unsetenv("HORUS_NAMESPACE");
  }

  /// This process's announcement in the namespace ("" when it has none).
  std::string announcement() const {
    for (const horus::PresenceInfo& info : horus::list_presence(name_)) {
      if (info.pid == static_cast<std::uint32_t>(::getpid()) &&
          info.snapshot_json.find("\"process\"") != std::string::npos) {
        return info.snapshot_json;
      }
    }
    return "";
  }

  /// Waits (bounded) until the announcement holds every text of `wanted`.
  bool announced(const std::vector<std::string>& wanted) const {
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    while (std::chrono::steady_clock::now() < deadline) {
      const std::string text = announcement();
      bool all = !text.empty();
      for (const std::string& part : wanted) all = all && text.find(part) != std::string::npos;
      if (all) return true;
      std::this_thread::sleep_for(5ms);
    }
    return false;
  }

  std::string name_;
};

TEST_F(PresenceTest, ATopicHandleIsAnnouncedWhileItIsOpen) {
  EXPECT_EQ(announcement(), "");
  {
    const horus::Topic<horus::msg::CmdVel> first("cmd_vel");
    // The first use is written before the constructor returns.
    EXPECT_NE(announcement().find(R"({"topic":"cmd_vel","type":"horus.msg.CmdVel","handles":1})"),
              std::string::npos)
        << announcement();
    const horus::Topic<horus::msg::CmdVel> second("cmd_vel");
    EXPECT_TRUE(announced({R"("topic":"cmd_vel","type":"horus.msg.CmdVel","handles":2)"}));
  }
  // The last use gone, the announcement goes at once.
  EXPECT_EQ(announcement(), "");
}

TEST_F(PresenceTest, UsesFromManyThreadsAreAllAnnouncedAndAllWithdrawn) {
  constexpr int kThreads = 8;
  std::vector<std::thread> threads;
  std::vector<AnnouncedUse> uses(kThreads);
  for (int i = 0; i < kThreads; ++i) {
    threads.emplace_back([&uses, i] {
      const auto kind =
          i % 2 == 0 ? ProcessUse::Kind::ServiceServer : ProcessUse::Kind::ServiceClient;
      uses[static_cast<std::size_t>(i)] =
          AnnouncedUse(ProcessUse{kind, {}, "svc" + std::to_string(i), "a.Req", "a.Res"});
    });
  }
  for (std::thread& thread : threads) thread.join();
  std::vector<std::string> wanted;
  for (int i = 0; i < kThreads; ++i) {
    wanted.push_back(std::string(R"({"service":"svc)") + std::to_string(i) + R"(","role":")" +
                     (i % 2 == 0 ? "server" : "client") +
                     R"(","request_type":"a.Req","response_type":"a.Res"})");
  }
  EXPECT_TRUE(announced(wanted)) << announcement();

  threads.clear();
  for (int i = 0; i < kThreads; ++i) {
    threads.emplace_back([&uses, i] { uses[static_cast<std::size_t>(i)] = AnnouncedUse(); });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(announcement(), "");
}

/// The announcement of this process's scheduler `name` ("" when there is none).
std::string scheduler_announcement(const std::string& namespace_name, const std::string& name) {
  for (const horus::PresenceInfo& info : horus::list_presence(namespace_name)) {
    if (info.pid == static_cast<std::uint32_t>(::getpid()) &&
        info.snapshot_json.find("{\"scheduler\":\"" + name + "\"") == 0) {
      return info.snapshot_json;
    }
  }
  return "";
}

class Slow : public horus::Node {
 public:
  std::string_view name() const override { return "slow"; }
  void tick() override { std::this_thread::sleep_for(2ms); }
};

TEST_F(PresenceTest, ASchedulerAnnouncesItsMissesAgainstTheLimit) {
  horus::Scheduler limited{horus::SchedulerConfig{}.name("limited").max_deadline_misses(2)};
  limited.add(std::make_shared<Slow>()).rate(horus::Rate::hz(1000)).deadline(50us).build();
  EXPECT_EQ(limited.run(), 1) << "the miss limit stops it";
  const std::string text = scheduler_announcement(name_, "limited");
  std::smatch found;
  ASSERT_TRUE(std::regex_search(text, found,
                                std::regex(R"("deadline_misses":(\d+),"max_deadline_misses":2,)")))
      << text;
  EXPECT_GE(std::stoul(found[1].str()), 2U) << text;
  EXPECT_NE(text.find(R"("name":"slow")"), std::string::npos) << text;
  EXPECT_NE(text.find(R"("deadline_ns":50000,"deadline_misses":)"), std::string::npos) << text;

  horus::Scheduler unlimited{
      horus::SchedulerConfig{}.name("unlimited").max_deadline_misses(std::nullopt)};
  unlimited.add(std::make_shared<Slow>()).build();
  unlimited.run_for(10ms);
  const std::string other = scheduler_announcement(name_, "unlimited");
  EXPECT_NE(other.find(R"("deadline_misses":0,"max_deadline_misses":null,)"), std::string::npos)
      << other;
  EXPECT_NE(other.find(R"("deadline_ns":null,)"), std::string::npos)
      << "a node without a rate has no deadline: " << other;
}

}  // namespace
