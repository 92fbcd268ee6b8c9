// Recording: sessions written by a Recorder and by SchedulerConfig::recording(true),
// read back with RecordingReader; losses counted; deterministic replay; a changed type refused.
// The independent check of the same files (PyPI `mcap`) is tests/python/runtime/test_recording.py.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "horus/horus.hpp"
#include "horus/recording.hpp"
#include "recordings_folder.hpp"
#include "topic_test/big.hpp"
#include "topic_test/blob.hpp"
#include "topic_test/other.hpp"
#include "topic_test/sample.hpp"
#include "topic_test_support.hpp"

namespace {

using topic_test::Blob;
using topic_test::Other;
using topic_test::Sample;

using horus_test::RecordingsFolder;

horus::RecorderOptions options_for(std::vector<std::string> topics) {
  horus::RecorderOptions options;
  options.topics = std::move(topics);
  return options;
}

std::string hex16(std::uint64_t value) {
  char text[24];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

const horus::RecordedMetadata* metadata_named(const horus::RecordingReader& reader,
                                              std::string_view name) {
  for (const auto& m : reader.metadata()) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

TEST(Recording, RecorderWritesEveryMessageWithItsTypeAndReadsBack) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  horus::Topic<Sample> samples("samples", {.capacity = 4096});
  horus::Topic<Blob> blobs("blobs", {.capacity = 1024});
  horus::Recorder recorder(options_for({"samples", "blobs"}));
  EXPECT_EQ(recorder.path().parent_path(), folder.path());
  EXPECT_THAT(recorder.path().filename().string(), ::testing::StartsWith("session_"));

  for (std::uint64_t i = 0; i < 3000; ++i) ASSERT_TRUE(samples.send(topic_test::sealed<Sample>(i)));
  std::vector<Blob> sent_blobs;
  for (std::uint64_t i = 0; i < 200; ++i) {
    Blob blob;
    blob.seq = i;
    blob.text = "blob " + std::to_string(i);
    blob.data.assign(i % 37, static_cast<std::uint8_t>(i));
    if (i % 3 == 0) blob.note = "third";
    ASSERT_TRUE(blobs.send(blob));
    sent_blobs.push_back(blob);
  }
  const horus::RecordingSummary summary = recorder.stop();
  EXPECT_FALSE(recorder.recording());
  EXPECT_EQ(summary.messages, 3200U);
  EXPECT_EQ(summary.lost_total, 0U);

  const horus::RecordingReader reader(summary.path);
  EXPECT_TRUE(reader.complete());
  EXPECT_GE(reader.chunk_count(), 1U);
  const horus::RecordedChannel* channel = reader.channel("samples");
  ASSERT_NE(channel, nullptr);
  EXPECT_EQ(channel->message_encoding, "horus.pod");
  EXPECT_EQ(channel->metadata.at("horus.fingerprint"), hex16(horus::TypeInfo<Sample>::fingerprint));
  EXPECT_EQ(channel->metadata.at("horus.type"), horus::TypeInfo<Sample>::name);
  EXPECT_EQ(channel->metadata.at("horus.payload_size"), std::to_string(sizeof(Sample)));
  const horus::RecordedSchema& schema = reader.schemas().at(channel->schema_id);
  EXPECT_EQ(schema.name, horus::TypeInfo<Sample>::name);
  EXPECT_EQ(schema.encoding, "horus.hmsg");
  EXPECT_EQ(schema.data, horus::TypeInfo<Sample>::schema);

  const auto recorded = reader.messages_on("samples");
  ASSERT_EQ(recorded.size(), 3000U);
  for (std::size_t i = 0; i < recorded.size(); ++i) {
    const Sample expected = topic_test::sealed<Sample>(i);
    ASSERT_EQ(recorded[i]->data.size(), sizeof(Sample));
    ASSERT_EQ(std::memcmp(recorded[i]->data.data(), &expected, sizeof(Sample)), 0) << i;
    if (i > 0) {
      EXPECT_EQ(recorded[i]->sequence, recorded[i - 1]->sequence + 1);
    }
    EXPECT_GT(recorded[i]->log_time, 0U);
  }
  const horus::RecordedChannel* blob_channel = reader.channel("blobs");
  ASSERT_NE(blob_channel, nullptr);
  EXPECT_EQ(blob_channel->message_encoding, "horus.msgpack");
  const auto recorded_blobs = reader.messages_on("blobs");
  ASSERT_EQ(recorded_blobs.size(), sent_blobs.size());
  for (std::size_t i = 0; i < recorded_blobs.size(); ++i) {
    const auto decoded = horus::try_decode<Blob>(std::span<const std::uint8_t>(
        recorded_blobs[i]->data.data(), recorded_blobs[i]->data.size()));
    ASSERT_TRUE(decoded.has_value()) << i;
    EXPECT_EQ(*decoded, sent_blobs[i]);
  }
  const auto* session = metadata_named(reader, "horus.session");
  ASSERT_NE(session, nullptr);
  EXPECT_EQ(session->entries.at("namespace"), ns.name());
  EXPECT_EQ(session->entries.at("session"), summary.path.stem().string());
  const auto* end = metadata_named(reader, "horus.recorder");
  ASSERT_NE(end, nullptr);
  EXPECT_EQ(end->entries.at("lost_total"), "0");
}

TEST(Recording, WhatTheRecorderCouldNotKeepUpWithIsCountedNotSilent) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  horus::Topic<Sample> fast("fast", {.capacity = 4});
  horus::Recorder recorder(options_for({"fast"}));
  constexpr std::uint64_t kSent = 200'000;
  for (std::uint64_t i = 0; i < kSent; ++i) ASSERT_TRUE(fast.send(topic_test::sealed<Sample>(i)));
  const horus::RecordingSummary summary = recorder.stop();
  const horus::RecordingReader reader(summary.path);
  const auto recorded = reader.messages_on("fast");
  // A 4-slot ring at full speed laps a thread that sleeps between rounds: some are lost, and
  // every message is either recorded or counted as lost.
  EXPECT_GT(summary.lost_total, 0U);
  EXPECT_EQ(recorded.size() + summary.lost.at("fast"), kSent);
  const auto* end = metadata_named(reader, "horus.recorder");
  ASSERT_NE(end, nullptr);
  EXPECT_EQ(end->entries.at("lost.fast"), std::to_string(summary.lost.at("fast")));
  EXPECT_EQ(end->entries.at("lost_total"), std::to_string(summary.lost_total));
  for (const auto* m : recorded) {
    Sample sample;
    std::memcpy(&sample, m->data.data(), sizeof sample);
    EXPECT_TRUE(topic_test::valid(sample));
  }
}

TEST(Recording, AllTopicsFindsTopicsThatAppearLater) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  horus::RecorderOptions options;
  options.all_topics = true;
  horus::Recorder recorder(options);
  horus::Topic<Sample> late("late", {.capacity = 1024});
  // Until the recorder has found the topic, probes (seq 0) go unrecorded or recorded alike.
  for (int i = 0; i < 2000 && recorder.summary().messages == 0; ++i) {
    late.send(topic_test::sealed<Sample>(0));
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_GT(recorder.summary().messages, 0U) << "the recorder never found topic 'late'";
  for (std::uint64_t i = 1; i <= 100; ++i) ASSERT_TRUE(late.send(topic_test::sealed<Sample>(i)));
  const horus::RecordingSummary summary = recorder.stop();
  EXPECT_EQ(summary.lost_total, 0U);
  const horus::RecordingReader reader(summary.path);
  const auto recorded = reader.messages_on("late");
  ASSERT_GE(recorded.size(), 100U);
  for (std::size_t i = 0; i < 100; ++i) {
    Sample sample;
    std::memcpy(&sample, recorded[recorded.size() - 100 + i]->data.data(), sizeof sample);
    EXPECT_EQ(sample.seq, i + 1);
  }
}

/// Publishes its tick index on `topic` each tick.
class Producer : public horus::Node {
 public:
  explicit Producer(std::string topic) : topic_name_(std::move(topic)), out_(topic_name_) {}
  std::string_view name() const override { return "producer"; }
  void tick() override { out_.send(topic_test::sealed<Sample>(next_.fetch_add(1))); }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{topic_name_, std::string(horus::TypeInfo<Sample>::name)}};
  }
  /// Read by the test between runs of the scheduler, whichever thread ticked.
  std::uint64_t sent() const noexcept { return next_.load(); }

 private:
  std::string topic_name_;
  horus::Topic<Sample> out_;
  std::atomic<std::uint64_t> next_ = 0;
};

/// Publishes the running sum of what it received, once per tick that received anything.
class Summer : public horus::Node {
 public:
  Summer(std::string in, std::string out)
      : in_name_(std::move(in)), out_name_(std::move(out)), in_(in_name_), out_(out_name_) {}
  std::string_view name() const override { return "summer"; }
  void tick() override {
    bool got = false;
    while (auto msg = in_.try_recv()) {
      sum_ = sum_ * 31 + msg->seq + 1;
      got = true;
    }
    if (got) out_.send(topic_test::sealed<Sample>(sum_));
  }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{out_name_, std::string(horus::TypeInfo<Sample>::name)}};
  }
  std::vector<horus::TopicMetadata> subscribers() const override {
    return {{in_name_, std::string(horus::TypeInfo<Sample>::name)}};
  }

 private:
  std::string in_name_, out_name_;
  horus::Topic<Sample> in_;
  horus::Topic<Sample> out_;
  std::uint64_t sum_ = 0;
};

/// Sends on a topic it does not name in publishers(), as hand-written nodes often do.
class Unnamed : public horus::Node {
 public:
  Unnamed() : out_("unnamed_out") {}
  std::string_view name() const override { return "unnamed"; }
  void tick() override { out_.send(topic_test::sealed<Sample>(next_++)); }

 private:
  horus::Topic<Sample> out_;
  std::uint64_t next_ = 0;
};

horus::SchedulerConfig quiet_config() {
  return horus::SchedulerConfig{}.handle_signals(false).tick_rate(horus::Rate::hz(1000.0));
}

TEST(Recording, SchedulerRecordsItsNodesTopicsAndTicksIntoOneSession) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  std::filesystem::path file;
  {
    horus::Scheduler sched(quiet_config().recording(true));
    sched.add(std::make_shared<Producer>("s_in")).order(0).build();
    sched.add(std::make_shared<Summer>("s_in", "s_out")).order(1).build();
    sched.add(std::make_shared<Unnamed>()).order(2).build();
    EXPECT_FALSE(sched.is_recording());
    for (int i = 0; i < 50; ++i) sched.tick_once();
    EXPECT_TRUE(sched.is_recording());
    const auto files = sched.stop_recording();
    ASSERT_EQ(files.size(), 1U);
    file = files[0];
    EXPECT_FALSE(sched.is_recording());
    EXPECT_THAT(sched.list_recordings(), ::testing::Contains(file.stem().string()));
  }
  const horus::RecordingReader reader(file);
  EXPECT_TRUE(reader.complete());
  const auto inputs = reader.messages_on("s_in");
  const auto outputs = reader.messages_on("s_out");
  ASSERT_EQ(inputs.size(), 50U);
  EXPECT_EQ(outputs.size(), 50U);
  EXPECT_EQ(reader.messages_on("unnamed_out").size(), 50U);  // opened, not named: recorded too
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    Sample sample;
    std::memcpy(&sample, inputs[i]->data.data(), sizeof sample);
    EXPECT_EQ(sample.seq, i);
  }
  const horus::RecordedChannel* ticks = reader.channel("/horus/ticks");
  ASSERT_NE(ticks, nullptr);
  EXPECT_EQ(ticks->message_encoding, "json");
  EXPECT_EQ(reader.schemas().at(ticks->schema_id).name, "horus.recording.Tick");
  const auto tick_records = reader.messages_on("/horus/ticks");
  ASSERT_EQ(tick_records.size(), 150U);
  const std::string first(tick_records[0]->data.begin(), tick_records[0]->data.end());
  EXPECT_THAT(
      first,
      ::testing::MatchesRegex(
          R"(\{"node":"producer","tick":0,"start_ns":[0-9]+,"duration_ns":[0-9]+,"outcome":"ok"\})"));

  horus::Scheduler other(quiet_config());
  EXPECT_TRUE(other.delete_recording(file.stem().string()));
  EXPECT_FALSE(std::filesystem::exists(file));
  EXPECT_THAT(other.list_recordings(), ::testing::Not(::testing::Contains(file.stem().string())));
  EXPECT_FALSE(other.delete_recording(file.stem().string()));
  EXPECT_THROW(other.delete_recording("../escape"), horus::Error);
}

TEST(Recording, ADeterministicRunFasterThanRealTimeLosesNothing) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  horus::Scheduler sched(quiet_config().deterministic(true).recording(true));
  sched.add(std::make_shared<Producer>("fast_sim")).order(0).build();
  sched.add(std::make_shared<Summer>("fast_sim", "fast_sum")).order(1).build();
  sched.run_for(std::chrono::seconds(5));  // 5000 simulated ticks, as fast as the CPU goes
  const std::filesystem::path file = sched.stop_recording().at(0);
  const horus::RecordingReader reader(file);
  const auto inputs = reader.messages_on("fast_sim");
  // 64-slot rings, nothing lost: each pass waited for the recorder.
  ASSERT_EQ(inputs.size(), 5000U);
  EXPECT_EQ(reader.messages_on("fast_sum").size(), 5000U);
  EXPECT_EQ(reader.messages_on("/horus/ticks").size(), 10000U);
  const auto* end = metadata_named(reader, "horus.recorder");
  ASSERT_NE(end, nullptr);
  EXPECT_EQ(end->entries.at("lost_total"), "0");
}

/// Records producer -> summer live (real time), then replays the producer's topic into a fresh
/// summer twice under a deterministic scheduler: both runs give the same outputs.
TEST(Recording, DeterministicReplayGivesIdenticalOutputsRunAfterRun) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  std::filesystem::path file;
  {
    horus::Scheduler sched(quiet_config().recording(true));
    const auto producer = std::make_shared<Producer>("r_in");
    sched.add(producer).order(0).rate(horus::Rate::hz(1000.0)).build();
    sched.add(std::make_shared<Summer>("r_in", "r_out")).order(1).build();
    // Real time: a loaded machine may stall the first ticks for seconds, so run until there is
    // something to replay rather than for a fixed 100 ms.
    for (int i = 0; i < 300 && producer->sent() < 50; ++i) {
      sched.tick_for(std::chrono::milliseconds(100));
    }
    file = sched.stop_recording().at(0);
  }
  const horus::RecordingReader reader(file);
  const auto inputs = reader.messages_on("r_in");
  ASSERT_GT(inputs.size(), 10U);
  std::uint64_t expected_sum = 0;
  for (const auto* m : inputs) {
    Sample sample;
    std::memcpy(&sample, m->data.data(), sizeof sample);
    expected_sum = expected_sum * 31 + sample.seq + 1;
  }

  const auto replay = [&] {
    horus::Topic<Sample> watch("r_out", {.capacity = 4096});
    horus::Scheduler sched(quiet_config().deterministic(true).replay(file));
    sched.add(std::make_shared<Summer>("r_in", "r_out")).order(1).build();
    for (int i = 0; i < 400; ++i) sched.tick_once();
    std::vector<std::uint64_t> outputs;
    while (auto msg = watch.try_recv()) outputs.push_back(msg->seq);
    return outputs;
  };
  const std::vector<std::uint64_t> first = replay();
  const std::vector<std::uint64_t> second = replay();
  ASSERT_FALSE(first.empty());
  EXPECT_EQ(first, second);
  EXPECT_EQ(first.back(), expected_sum);  // every recorded input reached the node, in order
}

/// Publishes its tick count on two ticks of three.
class Pulse : public horus::Node {
 public:
  std::string_view name() const override { return "pulse"; }
  void tick() override {
    if (ticks_ % 3 != 1) out_.send(topic_test::sealed<Sample>(ticks_));
    ++ticks_;
  }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{"pulse", std::string(horus::TypeInfo<Sample>::name)}};
  }

 private:
  horus::Topic<Sample> out_{"pulse"};
  std::uint64_t ticks_ = 0;
};

/// Notes on which of its ticks each pulse arrived, and publishes that pairing.
class Listener : public horus::Node {
 public:
  explicit Listener(std::string name) : name_(std::move(name)), out_(name_ + "_out") {}
  std::string_view name() const override { return name_; }
  void tick() override {
    while (auto msg = in_.try_recv()) {
      arrivals.emplace_back(msg->seq, ticks_);
      out_.send(topic_test::sealed<Sample>(msg->seq * 1000 + ticks_));
    }
    ++ticks_;
  }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{name_ + "_out", std::string(horus::TypeInfo<Sample>::name)}};
  }
  std::vector<horus::TopicMetadata> subscribers() const override {
    return {{"pulse", std::string(horus::TypeInfo<Sample>::name)}};
  }

  std::vector<std::pair<std::uint64_t, std::uint64_t>> arrivals;  // (pulse, tick it arrived on)

 private:
  std::string name_;
  horus::Topic<Sample> in_{"pulse"};
  horus::Topic<Sample> out_;
  std::uint64_t ticks_ = 0;
};

/// A live run records which tick of each reader a message reached; a deterministic replay
/// delivers it so that a reader of the same name gets it on that same tick: the one ordered
/// after the publisher in the same cycle, the one ordered before it in the next. Two replays
/// recorded in turn hold the same outputs.
TEST(Recording, DeterministicReplayDeliversEachMessageOnTheTickItWasReceived) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  constexpr int kCycles = 60;
  std::filesystem::path file;
  const auto early = std::make_shared<Listener>("early");
  const auto late = std::make_shared<Listener>("late");
  {
    horus::Scheduler sched(quiet_config().recording(true));  // live: the recorder lags as it may
    sched.add(early).order(0).build();
    sched.add(std::make_shared<Pulse>()).order(1).build();
    sched.add(late).order(2).build();
    for (int i = 0; i < kCycles; ++i) sched.tick_once();
    file = sched.stop_recording().at(0);
  }
  ASSERT_EQ(late->arrivals.size(), 40U);
  ASSERT_EQ(late->arrivals.front(), std::make_pair(std::uint64_t{0}, std::uint64_t{0}));
  ASSERT_EQ(early->arrivals.front(), std::make_pair(std::uint64_t{0}, std::uint64_t{1}));
  const horus::RecordingReader recording(file);
  const auto ticks = recording.messages_on("/horus/ticks");
  ASSERT_FALSE(ticks.empty());
  EXPECT_THAT(std::string(ticks.front()->data.begin(), ticks.front()->data.end()),
              ::testing::HasSubstr(R"("received":{"pulse":)"));

  const auto replay = [&] {
    const auto early_again = std::make_shared<Listener>("early");
    const auto late_again = std::make_shared<Listener>("late");
    horus::Scheduler sched(quiet_config().deterministic(true).recording(true).replay(file));
    sched.add(early_again).order(0).build();
    sched.add(late_again).order(2).build();
    for (int i = 0; i < kCycles; ++i) sched.tick_once();
    EXPECT_EQ(early_again->arrivals, early->arrivals);
    EXPECT_EQ(late_again->arrivals, late->arrivals);
    return sched.stop_recording().at(0);
  };
  const horus::RecordingReader first(replay());
  const horus::RecordingReader second(replay());
  for (const char* topic : {"early_out", "late_out"}) {
    const auto a = first.messages_on(topic);
    const auto b = second.messages_on(topic);
    ASSERT_EQ(a.size(), b.size()) << topic;
    EXPECT_FALSE(a.empty()) << topic;
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i]->data, b[i]->data) << topic << i;
  }
}

TEST(Recording, ReplayRefusesATopicWhoseTypeChangedNamingIt) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  std::filesystem::path file;
  {
    horus::Topic<Sample> typed("typed");
    horus::Recorder recorder(options_for({"typed"}));
    typed.send(topic_test::sealed<Sample>(1));
    file = recorder.stop().path;
  }
  horus::remove_namespace(ns.name());
  horus::Topic<Other> now("typed");
  horus::Scheduler sched(quiet_config().deterministic(true).replay(file));
  sched.add(std::make_shared<Producer>("unrelated")).build();
  try {
    sched.tick_once();
    FAIL() << "a replay into a re-typed topic was accepted";
  } catch (const horus::Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("topic 'typed' was recorded as topic_test.Sample"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("topic_test.Other"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("type changed"));
  }
}

/// A recorder killed with kill -9 leaves its complete chunks, then a cut one: every cut point
/// reads back as a prefix of the messages, and the file says it is incomplete.
TEST(Recording, AFileCutAnywhereReadsBackItsCompleteChunks) {
  topic_test::PrivateNamespace ns;
  RecordingsFolder folder;
  horus::Topic<topic_test::Big> big("big", {.capacity = 4096});
  horus::Recorder recorder(options_for({"big"}));
  for (std::uint64_t i = 0; i < 1500; ++i)
    ASSERT_TRUE(big.send(topic_test::sealed<topic_test::Big>(i)));
  const horus::RecordingSummary summary = recorder.stop();
  ASSERT_EQ(summary.lost_total, 0U);
  std::ifstream in(summary.path, std::ios::binary);
  const std::string whole((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const horus::RecordingReader full(summary.path);
  ASSERT_GE(full.chunk_count(), 4U);
  const auto all = full.messages_on("big");
  ASSERT_EQ(all.size(), 1500U);

  const std::filesystem::path cut_path = folder.path() / "cut.mcap";
  std::size_t previous = 0;
  for (std::size_t cut = 64; cut < whole.size(); cut += whole.size() / 23) {
    std::ofstream(cut_path, std::ios::binary | std::ios::trunc)
        .write(whole.data(), static_cast<std::streamsize>(cut));
    const horus::RecordingReader reader(cut_path);
    EXPECT_FALSE(reader.complete());
    const auto got = reader.messages_on("big");
    EXPECT_GE(got.size(), previous);  // a longer prefix never reads fewer messages
    previous = got.size();
    for (std::size_t i = 0; i < got.size(); ++i) {
      ASSERT_EQ(got[i]->data, all[i]->data) << "cut at " << cut << ", message " << i;
    }
  }
  EXPECT_GT(previous, 0U);
  // A damaged byte inside a complete chunk is reported, not read as data.
  std::string damaged = whole;
  damaged[whole.size() / 2] ^= 0x5a;
  std::ofstream(cut_path, std::ios::binary | std::ios::trunc)
      .write(damaged.data(), static_cast<std::streamsize>(damaged.size()));
  EXPECT_THROW(horus::RecordingReader{cut_path}, horus::Error);
}

TEST(Recording, ReplayNeedsDeterministicMode) {
  EXPECT_THROW(horus::Scheduler(quiet_config().replay("x.mcap")), horus::Error);
}

}  // namespace
