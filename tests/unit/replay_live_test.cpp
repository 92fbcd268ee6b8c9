// Deterministic replay against the live run it replays: a live session of a publisher of random
// values and a node folding whatever arrived into a running sum, on threads of their own at
// rates that share no period, replayed into the folding node alone. Its outputs must be the ones
// it recorded live, byte for byte, from its first tick (docs/recording.md), not only equal from
// one replay to the next.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "horus/horus.hpp"
#include "horus/recording.hpp"
#include "recordings_folder.hpp"
#include "topic_test/sample.hpp"
#include "topic_test_support.hpp"

namespace {

using topic_test::Sample;

using horus_test::RecordingsFolder;

horus::SchedulerConfig quiet_config() {
  return horus::SchedulerConfig{}.handle_signals(false).tick_rate(horus::Rate::hz(1000.0));
}

/// Publishes a random value each tick: what the live run got can only be known from its file.
class Source : public horus::Node {
 public:
  std::string_view name() const override { return "source"; }
  void tick() override { out_.send(topic_test::sealed<Sample>(random_())); }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{"values", std::string(horus::TypeInfo<Sample>::name)}};
  }

 private:
  horus::Topic<Sample> out_{"values"};
  std::mt19937_64 random_{std::random_device{}()};
};

/// Folds whatever arrived into a running sum and publishes it every tick, also when nothing
/// arrived: an input one tick late, or one tick too many, changes its outputs.
class Fold : public horus::Node {
 public:
  std::string_view name() const override { return "fold"; }
  void tick() override {
    while (auto msg = in_.try_recv()) sum_ = sum_ * 31 + msg->seq;
    out_.send(topic_test::sealed<Sample>(sum_));
  }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{"sum", std::string(horus::TypeInfo<Sample>::name)}};
  }
  std::vector<horus::TopicMetadata> subscribers() const override {
    return {{"values", std::string(horus::TypeInfo<Sample>::name)}};
  }

 private:
  horus::Topic<Sample> in_{"values", {.capacity = 1024}};
  horus::Topic<Sample> out_{"sum", {.capacity = 1024}};
  std::uint64_t sum_ = 0;
};

std::vector<std::vector<std::uint8_t>> outputs(const std::filesystem::path& file) {
  const horus::RecordingReader reader(file);
  std::vector<std::vector<std::uint8_t>> out;
  for (const auto* m : reader.messages_on("sum")) out.push_back(m->data);
  return out;
}

TEST(ReplayLive, AReplayedNodeGivesTheOutputsItRecordedLiveFromItsFirstTick) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  std::filesystem::path live_file;
  {
    horus::Scheduler sched(quiet_config().recording(true));
    sched.add(std::make_shared<Source>()).order(0).rate(horus::Rate::hz(200.0)).build();
    sched.add(std::make_shared<Fold>()).order(1).rate(horus::Rate::hz(70.0)).build();
    // Real time on threads of their own: the fold starts once the source has run for a while, so
    // its ticks fall in other cycles than they do in a replay, and values arrive while it ticks.
    sched.tick_for(std::chrono::milliseconds(50), {"source"});
    sched.tick_for(std::chrono::seconds(1));
    live_file = sched.stop_recording().at(0);
  }
  const std::vector<std::vector<std::uint8_t>> live = outputs(live_file);
  ASSERT_GE(live.size(), 20U);
  const horus::RecordingReader recording(live_file);
  ASSERT_GT(recording.messages_on("values").size(), live.size());

  const auto replay = [&] {
    horus::Scheduler sched(quiet_config().deterministic(true).recording(true).replay(live_file));
    sched.add(std::make_shared<Fold>()).order(1).rate(horus::Rate::hz(70.0)).build();
    // Simulated time: a few ticks more than the live run had.
    sched.tick_for(std::chrono::milliseconds(1000 * (live.size() + 3) / 70));
    return outputs(sched.stop_recording().at(0));
  };
  const std::vector<std::vector<std::uint8_t>> first = replay();
  ASSERT_GT(first.size(), live.size());
  for (std::size_t i = 0; i < live.size(); ++i) EXPECT_EQ(first[i], live[i]) << "output " << i;
  EXPECT_EQ(replay(), first);
}

}  // namespace
