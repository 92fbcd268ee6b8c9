// The flight recorder: a fixed ring that keeps the newest events, survives concurrent writers,
// round-trips through a file, rejects files that are not its own, and is fed by the scheduler.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "horus/blackbox.hpp"
#include "horus/error.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;
using horus::BlackboxEventKind;

namespace {

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
