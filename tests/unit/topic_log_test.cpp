// Verbose topics (seed 002's Topic::verbose flag with LogSummary): a verbose handle's messages
// reach the runtime's log ring (what `horus log` reads) with their summaries, in the running
// node's name, at most ten lines a second with a count of what it suppressed; a quiet handle logs
// nothing, and a plain value's line is formatted without allocating.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <memory>
#include <new>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "allocation_counter.hpp"
#include "horus/literals.hpp"
#include "horus/log.hpp"
#include "horus/scheduler.hpp"
#include "horus/topic.hpp"
#include "private_shm_root.hpp"
#include "topic_test/blob.hpp"

namespace {

// Every test runs in its own process (gtest_discover_tests): a private root for its topics and
// log ring, outside /dev/shm, removed when it ends.
const horus_test::PrivateShmRoot shm_root{"topiclog"};

using horus_test::allocations;

horus::TopicOptions verbose() {
  horus::TopicOptions options;
  options.verbose = true;
  return options;
}

std::vector<horus::LogRecord> lines_starting(std::string_view prefix) {
  std::vector<horus::LogRecord> out;
  for (horus::LogRecord& r : horus::read_log().records) {
    if (r.message.starts_with(prefix)) out.push_back(std::move(r));
  }
  return out;
}

class Lambda : public horus::Node {
 public:
  Lambda(std::string name, std::function<void()> body)
      : name_(std::move(name)), body_(std::move(body)) {}
  std::string_view name() const override { return name_; }
  void tick() override { body_(); }

 private:
  std::string name_;
  std::function<void()> body_;
};

}  // namespace

TEST(VerboseTopic, SendAndReceiveLinesCarryTheMessagesSummary) {
  horus::Topic<topic_test::Blob> out("blobs", verbose());
  horus::Topic<topic_test::Blob> in("blobs", verbose());
  topic_test::Blob blob;
  blob.seq = 7;
  blob.text = "left wheel";
  ASSERT_TRUE(out.send(blob));
  ASSERT_TRUE(in.try_recv().has_value());

  const auto sent = lines_starting("blobs send: ");
  const auto received = lines_starting("blobs recv: ");
  ASSERT_EQ(sent.size(), 1U);
  ASSERT_EQ(received.size(), 1U);
  EXPECT_EQ(sent[0].message, "blobs send: " + blob.log_summary());
  EXPECT_EQ(received[0].message, "blobs recv: " + blob.log_summary());
  EXPECT_NE(sent[0].message.find("left wheel"), std::string::npos) << sent[0].message;
  EXPECT_EQ(sent[0].level, horus::LogLevel::Info);
  EXPECT_EQ(sent[0].source, "-") << "outside a node's callbacks";
}

TEST(VerboseTopic, PlainValuesAreSummarisedAsNumbersAndText) {
  horus::Topic<double> speed("speed", verbose());
  horus::Topic<std::string> status("status", verbose());
  horus::Topic<std::array<float, 3>> accel("accel", verbose());
  horus::Topic<bool> armed("armed", verbose());
  ASSERT_TRUE(speed.send(1.5));
  ASSERT_TRUE(status.send(std::string("docking")));
  ASSERT_TRUE(accel.send({0.5F, -1.0F, 9.81F}));
  ASSERT_TRUE(armed.send(true));

  ASSERT_EQ(lines_starting("speed send: ").size(), 1U);
  EXPECT_EQ(lines_starting("speed send: ")[0].message, "speed send: 1.5");
  ASSERT_EQ(lines_starting("status send: ").size(), 1U);
  EXPECT_EQ(lines_starting("status send: ")[0].message, "status send: \"docking\"");
  ASSERT_EQ(lines_starting("accel send: ").size(), 1U);
  EXPECT_EQ(lines_starting("accel send: ")[0].message, "accel send: [0.5, -1, 9.81]");
  ASSERT_EQ(lines_starting("armed send: ").size(), 1U);
  EXPECT_EQ(lines_starting("armed send: ")[0].message, "armed send: true");
  // The same text horus::log_summary() gives (and Python's plain values print).
  EXPECT_EQ(lines_starting("accel send: ")[0].message,
            "accel send: " + horus::log_summary(std::array<float, 3>{0.5F, -1.0F, 9.81F}));
}

TEST(VerboseTopic, ALoanedMessageIsLoggedWhenPublished) {
  horus::Topic<double> speed("speed", verbose());
  auto loan = speed.loan();
  *loan = 2.5;
  EXPECT_TRUE(lines_starting("speed send: ").empty()) << "nothing is sent before publish()";
  ASSERT_TRUE(speed.publish(std::move(loan)));
  const auto lines = lines_starting("speed send: ");
  ASSERT_EQ(lines.size(), 1U);
  EXPECT_EQ(lines[0].message, "speed send: 2.5");
}

TEST(VerboseTopic, APlainValuesLineAllocatesNothing) {
  horus::Topic<double> speed("speed", verbose());
  ASSERT_TRUE(speed.send(0.25));  // the first line opens the log ring
  const long before = allocations.load();
  ASSERT_TRUE(speed.send(0.5));
  EXPECT_EQ(allocations.load() - before, 0);
  EXPECT_EQ(lines_starting("speed send: ").size(), 2U);
}

TEST(VerboseTopic, AQuietHandleLogsNothingAndVerboseCanBeSwitched) {
  horus::Topic<std::uint32_t> topic("counts");
  EXPECT_FALSE(topic.verbose());
  ASSERT_TRUE(topic.send(1));
  EXPECT_TRUE(lines_starting("counts ").empty());
  topic.set_verbose(true);
  EXPECT_TRUE(topic.verbose());
  ASSERT_TRUE(topic.send(2));
  topic.set_verbose(false);
  ASSERT_TRUE(topic.send(3));
  const auto lines = lines_starting("counts ");
  ASSERT_EQ(lines.size(), 1U);
  EXPECT_EQ(lines[0].message, "counts send: 2");
}

TEST(VerboseTopic, LinesFromANodesTickCarryItsName) {
  horus::Topic<std::int32_t> topic("steps", verbose());
  horus::Scheduler sched{horus::SchedulerConfig{}.name("topiclog").deterministic(true)};
  std::int32_t step = 0;
  sched.add(std::make_shared<Lambda>("stepper", [&] { topic.send(++step); })).build();
  sched.tick_once();
  const auto lines = lines_starting("steps send: ");
  ASSERT_EQ(lines.size(), 1U);
  EXPECT_EQ(lines[0].message, "steps send: 1");
  EXPECT_EQ(lines[0].source, "stepper");
}

TEST(VerboseTopic, AThousandHertzSenderIsRateLimitedWithACountOfWhatWasSuppressed) {
  constexpr int kMessages = 1000;
  using Clock = std::chrono::steady_clock;
  const auto started = Clock::now();
  {
    horus::Topic<std::uint32_t> topic("fast", verbose());
    auto next = started;
    for (int i = 0; i < kMessages; ++i) {
      next += std::chrono::milliseconds(1);
      std::this_thread::sleep_until(next);
      ASSERT_TRUE(topic.send(static_cast<std::uint32_t>(i)));
    }
  }  // dropping the handle reports what it still held back
  const double seconds = std::chrono::duration<double>(Clock::now() - started).count();

  const auto logged = lines_starting("fast send: ");
  const auto reports = lines_starting("fast: ");
  std::uint64_t suppressed = 0;
  for (const horus::LogRecord& r : reports) {
    const std::string expected_tail =
        " lines suppressed (a verbose topic logs at most 10 lines a second)";
    ASSERT_TRUE(r.message.ends_with(expected_tail)) << r.message;
    suppressed += std::stoull(r.message.substr(6));
  }
  EXPECT_FALSE(reports.empty()) << "no count of suppressed lines";
  EXPECT_EQ(logged.size() + suppressed, static_cast<std::uint64_t>(kMessages))
      << logged.size() << " lines logged, " << suppressed << " suppressed";
  // One window of ten lines per second begun, whatever the machine's speed.
  EXPECT_LE(logged.size(), 10U * (static_cast<std::size_t>(std::ceil(seconds)) + 1))
      << "in " << seconds << " s";
  ASSERT_FALSE(logged.empty());
  EXPECT_EQ(logged.front().message, "fast send: 0");
}
