// The flight recorder: fixed rings that keep the newest events and ticks, survive concurrent
// writers, round-trip through a file, reject files that are not their own, and are fed by the
// scheduler (its events, and per tick the node, its timing and the topics it touched).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "horus/blackbox.hpp"
#include "horus/clock.hpp"
#include "horus/error.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"
#include "horus/topic.hpp"
#include "private_shm_root.hpp"

using namespace horus::literals;
using horus::BlackboxEventKind;

namespace {

// Every test runs in its own process (gtest_discover_tests): the topics of the scheduler tests
// live under a private root outside /dev/shm, removed when the test ends.
const horus_test::PrivateShmRoot shm_root{"blackbox"};

/// The topics of one tick: `name` sent `sent` and received `received` messages.
horus::detail::TickTopics topics_of(
    std::initializer_list<std::tuple<const char*, int, int>> touched) {
  horus::detail::TickTopics topics;
  for (const auto& [name, sent, received] : touched) {
    horus::detail::TopicTouch* touch = topics.touch(name, name);
    if (touch == nullptr) continue;
    touch->sent = static_cast<std::uint32_t>(sent);
    touch->received = static_cast<std::uint32_t>(received);
  }
  return topics;
}

std::filesystem::path temp_file(const std::string& stem) {
  return std::filesystem::temp_directory_path() /
         (stem + "_" + std::to_string(::getpid()) + ".blackbox");
}

}  // namespace

TEST(Blackbox, KeepsTheNewestEventsInOrder) {
  horus::Blackbox box(4);
  for (int i = 0; i < 10; ++i) {
    box.record(BlackboxEventKind::DeadlineMiss, "motor", static_cast<std::uint64_t>(i), i * 100);
  }
  const auto events = box.snapshot();
  ASSERT_EQ(events.size(), 4U);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(events[i].tick, 6 + i);
    EXPECT_EQ(events[i].value, static_cast<std::int64_t>((6 + i) * 100));
    EXPECT_EQ(events[i].node_name(), "motor");
  }
  EXPECT_EQ(box.recorded(), 10U);
}

TEST(Blackbox, TruncatesLongTextSafely) {
  horus::Blackbox box(2);
  const std::string long_name(100, 'n');
  const std::string long_detail(300, 'd');
  box.record(BlackboxEventKind::NodeError, long_name, 1, 0, long_detail);
  const auto e = box.snapshot().at(0);
  EXPECT_EQ(e.node_name(), std::string(31, 'n'));
  EXPECT_EQ(e.detail_text(), std::string(63, 'd'));
}

TEST(Blackbox, KeepsTheFirstLineOfAMultiLineDetail) {
  horus::Blackbox box(1);
  box.record(BlackboxEventKind::NodeError, "motor", 1, 0,
             "RuntimeError: encoder lost\nTraceback (most recent call last):\n  File ...");
  EXPECT_EQ(box.snapshot().at(0).detail_text(), "RuntimeError: encoder lost");
}

TEST(Blackbox, ConcurrentWritersNeverProduceTornEvents) {
  horus::Blackbox box(64);
  std::vector<std::thread> writers;
  for (int w = 0; w < 4; ++w) {
    writers.emplace_back([&box, w] {
      const std::string name = "writer" + std::to_string(w);
      for (int i = 0; i < 5000; ++i) {
        // value and tick always agree, so a mix of two events is detectable.
        box.record(BlackboxEventKind::BudgetOverrun, name, static_cast<std::uint64_t>(i),
                   i * 3 + w);
      }
    });
  }
  for (int r = 0; r < 50; ++r) {
    for (const auto& e : box.snapshot()) {
      const int w = e.node_name().back() - '0';
      ASSERT_EQ(e.value, static_cast<std::int64_t>(e.tick) * 3 + w);
    }
  }
  for (auto& t : writers) t.join();
  EXPECT_EQ(box.recorded(), 20000U);
  EXPECT_EQ(box.snapshot().size(), 64U);
}

TEST(Blackbox, FileRoundTrip) {
  horus::Blackbox box(8);
  box.record(BlackboxEventKind::SchedulerStart, "robot", 0);
  box.record(BlackboxEventKind::NodeError, "lidar", 42, 0, "serial timeout");
  const auto path = temp_file("roundtrip");
  box.write_to(path);
  const auto events = horus::read_blackbox(path);
  std::filesystem::remove(path);
  ASSERT_EQ(events.size(), 2U);
  EXPECT_EQ(events[1].kind, BlackboxEventKind::NodeError);
  EXPECT_EQ(events[1].tick, 42U);
  EXPECT_EQ(events[1].detail_text(), "serial timeout");
  const std::string line = horus::format_blackbox_event(events[1]);
  EXPECT_NE(line.find("NodeError"), std::string::npos) << line;
  EXPECT_NE(line.find("lidar"), std::string::npos) << line;
  EXPECT_NE(line.find("serial timeout"), std::string::npos) << line;
}

TEST(Blackbox, RejectsMissingForeignAndTruncatedFiles) {
  EXPECT_THROW(horus::read_blackbox("/nonexistent/horus.blackbox"), horus::Error);
  const auto path = temp_file("bad");
  { std::ofstream(path) << "this is not a blackbox, it is a text file of some length"; }
  try {
    horus::read_blackbox(path);
    FAIL() << "a text file was accepted";
  } catch (const horus::Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a horus blackbox file"), std::string::npos);
  }
  horus::Blackbox box(8);
  box.record(BlackboxEventKind::NodeInit, "a", 0);
  box.write_to(path);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) - 10);
  try {
    horus::read_blackbox(path);
    FAIL() << "a truncated file was accepted";
  } catch (const horus::Error& e) {
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
  EXPECT_THROW(box.write_to("/nonexistent/dir/x.blackbox"), horus::Error);
}

TEST(Blackbox, SchedulerRecordsLifecycleErrorsAndMisses) {
  class Troubled : public horus::Node {
   public:
    std::string_view name() const override { return "troubled"; }
    void tick() override {
      std::this_thread::sleep_for(2_ms);
      if (++n_ == 2) throw std::runtime_error("bus error on CAN0");
    }
    void on_error(std::string_view) override {}
    int n_ = 0;
  };
  horus::Scheduler sched{horus::SchedulerConfig{}.blackbox_mb(1).name("agv")};
  sched.add(std::make_unique<Troubled>())
      .rate(1000_hz)
      .deadline(100_us)
      .failure_policy(horus::FailurePolicy::Ignore{})
      .build();
  sched.tick_once();
  sched.tick_once();
  std::vector<BlackboxEventKind> kinds;
  for (const auto& e : sched.blackbox()->snapshot()) kinds.push_back(e.kind);
  // Both ticks overrun the automatic budget (800 us) and miss the deadline; the second throws.
  const std::vector<BlackboxEventKind> expected{
      BlackboxEventKind::SchedulerStart, BlackboxEventKind::NodeInit,
      BlackboxEventKind::BudgetOverrun,  BlackboxEventKind::DeadlineMiss,
      BlackboxEventKind::NodeError,      BlackboxEventKind::BudgetOverrun,
      BlackboxEventKind::DeadlineMiss};
  EXPECT_EQ(kinds, expected);
  const auto path = temp_file("sched");
  sched.dump_blackbox(path);
  EXPECT_EQ(horus::read_blackbox(path).size(), expected.size());
  std::filesystem::remove(path);

  horus::Scheduler without;
  EXPECT_EQ(without.blackbox(), nullptr);
  EXPECT_THROW(without.dump_blackbox(path), horus::Error);
}

TEST(Blackbox, KeepsTheNewestTicksWithTheirTopicsAndWrapsAtItsSize) {
  horus::Blackbox box(4, 3);
  for (std::uint64_t i = 0; i < 5; ++i) {
    box.record_tick("motor", i, static_cast<std::int64_t>(1000 * (i + 1)),
                    topics_of({{"cmd_vel", 0, static_cast<int>(i)}, {"odom", 1, 0}}));
  }
  EXPECT_EQ(box.tick_capacity(), 3U);
  EXPECT_EQ(box.ticks_recorded(), 5U);
  const auto ticks = box.tick_snapshot();
  ASSERT_EQ(ticks.size(), 3U);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(ticks[i].tick, 2 + i);
    EXPECT_EQ(ticks[i].node_name(), "motor");
    EXPECT_EQ(ticks[i].duration_ns, static_cast<std::int64_t>(1000 * (3 + i)));
    ASSERT_EQ(ticks[i].topic_count, 2U);
    EXPECT_EQ(ticks[i].topics[0].topic_name(), "cmd_vel");
    EXPECT_EQ(ticks[i].topics[0].received, 2 + i);
    EXPECT_EQ(ticks[i].topics[1].topic_name(), "odom");
    EXPECT_EQ(ticks[i].topics[1].sent, 1U);
  }
  EXPECT_TRUE(box.snapshot().empty()) << "ticks are not events";
}

TEST(Blackbox, ATickKeepsEightTopicsAndCountsTheMessagesOfFurtherOnes) {
  horus::detail::TickTopics topics;
  const std::vector<std::string> names{"t0", "t1", "t2", "t3", "t4", "t5", "t6", "t7", "t8"};
  for (const std::string& name : names) {
    if (auto* touch = topics.touch(&name, name)) ++touch->sent;
  }
  if (auto* touch = topics.touch(&names[8], names[8])) ++touch->sent;
  if (auto* touch = topics.touch(&names[0], names[0])) ++touch->sent;
  horus::Blackbox box(1, 1);
  box.record_tick("mapper", 0, 10, topics);
  const auto tick = box.tick_snapshot().at(0);
  EXPECT_EQ(tick.topic_count, 8U);
  EXPECT_EQ(tick.other_messages, 2U);
  EXPECT_EQ(tick.topics[0].sent, 2U);
  const std::string line = horus::format_blackbox_tick(tick);
  EXPECT_NE(line.find("t0 2/0, t1 1/0"), std::string::npos) << line;
  EXPECT_NE(line.find("+2 messages on further topics"), std::string::npos) << line;
}

TEST(Blackbox, MegabytesGoMostlyToTicks) {
  const auto capacity = horus::Blackbox::capacity_for_mb(16);
  const std::size_t bytes = capacity.events * 136 + capacity.ticks * 392;
  EXPECT_LE(bytes, std::size_t{16} << 20);
  EXPECT_GT(bytes, (std::size_t{16} << 20) - 392 - 136);
  EXPECT_GT(capacity.ticks * 392, capacity.events * 136 * 6);
}

TEST(Blackbox, TicksRoundTripThroughAFile) {
  horus::Blackbox box(2, 4);
  box.record(BlackboxEventKind::NodeInit, "planner", 0);
  box.record_tick("planner", 41, 2'500'000, topics_of({{"goal", 0, 1}, {"path", 1, 0}}));
  box.record_tick("planner", 42, 1'000, topics_of({}));
  const auto path = temp_file("ticks");
  box.write_to(path);
  const auto ticks = horus::read_blackbox_ticks(path);
  const auto events = horus::read_blackbox(path);
  std::filesystem::remove(path);
  ASSERT_EQ(events.size(), 1U);
  ASSERT_EQ(ticks.size(), 2U);
  EXPECT_EQ(ticks[0].tick, 41U);
  EXPECT_EQ(ticks[0].duration_ns, 2'500'000);
  const std::string line = horus::format_blackbox_tick(ticks[0]);
  EXPECT_NE(line.find("planner"), std::string::npos) << line;
  EXPECT_NE(line.find("2500.0"), std::string::npos) << line;
  EXPECT_NE(line.find("goal 0/1, path 1/0"), std::string::npos) << line;
  EXPECT_TRUE(horus::format_blackbox_tick(ticks[1]).ends_with(" -"))
      << horus::format_blackbox_tick(ticks[1]);
}

TEST(Blackbox, SchedulerRecordsEveryTickWithTheTopicsItsNodeTouched) {
  class Driver : public horus::Node {
   public:
    std::string_view name() const override { return "driver"; }
    void tick() override {
      cmd_.send(1.0);
      cmd_.send(2.0);
    }
    horus::Topic<double> cmd_{"bb.cmd"};
  };
  class Motor : public horus::Node {
   public:
    std::string_view name() const override { return "motor"; }
    void tick() override {
      while (cmd_.try_recv()) {
      }
      odom_.send(static_cast<std::int32_t>(horus::tick_index()));
    }
    horus::Topic<double> cmd_{"bb.cmd"};
    horus::Topic<std::int32_t> odom_{"bb.odom"};
  };
  horus::Scheduler sched{horus::SchedulerConfig{}.blackbox_mb(1).name("rover").deterministic(true)};
  sched.add(std::make_shared<Driver>()).order(0).build();
  sched.add(std::make_shared<Motor>()).order(1).build();
  for (int i = 0; i < 3; ++i) sched.tick_once();

  const auto ticks = sched.blackbox()->tick_snapshot();
  ASSERT_EQ(ticks.size(), 6U);
  for (std::size_t i = 0; i < ticks.size(); ++i) {
    const horus::BlackboxTick& t = ticks[i];
    EXPECT_EQ(t.tick, i / 2);
    EXPECT_GE(t.duration_ns, 0);
    if (i % 2 == 0) {
      EXPECT_EQ(t.node_name(), "driver");
      ASSERT_EQ(t.topic_count, 1U);
      EXPECT_EQ(t.topics[0].topic_name(), "bb.cmd");
      EXPECT_EQ(t.topics[0].sent, 2U);
      EXPECT_EQ(t.topics[0].received, 0U);
    } else {
      EXPECT_EQ(t.node_name(), "motor");
      ASSERT_EQ(t.topic_count, 2U);
      EXPECT_EQ(t.topics[0].topic_name(), "bb.cmd");
      EXPECT_EQ(t.topics[0].received, 2U);
      EXPECT_EQ(t.topics[1].topic_name(), "bb.odom");
      EXPECT_EQ(t.topics[1].sent, 1U);
    }
  }
  // A scheduler without a blackbox counts messages without noting topics.
  horus::Scheduler quiet{horus::SchedulerConfig{}.name("quiet").deterministic(true)};
  auto driver = std::make_shared<Driver>();
  quiet.add(driver).build();
  quiet.tick_once();
  EXPECT_EQ(quiet.node_metrics("driver")->messages_sent, 2U);
}
