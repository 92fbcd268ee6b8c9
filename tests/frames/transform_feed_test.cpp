// What carriers of frames read (horus/transform_feed.hpp): the feed's batches, history_since(),
// the FrameTransform records, and the tree as `horus shm list` and `clean` see it.
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "frame_test_support.hpp"
#include "horus/frames.hpp"
#include "horus/topic_registry.hpp"
#include "horus/transform_feed.hpp"
#include "private_shm_root.hpp"

namespace {

using namespace std::chrono_literals;
using frames_test::FrameTreeTest;
using frames_test::planar;
using horus::FrameTree;
using horus::StampedTransform;
using horus::TransformBatch;
using horus::TransformFeed;

const horus_test::PrivateShmRoot private_root("transform_feed_test");

constexpr std::chrono::nanoseconds kEpoch = std::chrono::seconds(1000);

std::chrono::nanoseconds at_ms(int ms) { return kEpoch + std::chrono::milliseconds(ms); }

/// "parent>child@ms" for each entry: batches compared as text, so a failure shows them whole.
std::string entries_text(const std::vector<StampedTransform>& entries) {
  std::string out;
  for (const StampedTransform& t : entries) {
    if (!out.empty()) out += ' ';
    out += t.parent + ">" + t.child + "@" +
           std::to_string(
               std::chrono::duration_cast<std::chrono::milliseconds>(t.stamp - kEpoch).count());
  }
  return out;
}

std::string statics_text(const TransformBatch& batch) {
  if (!batch.statics) return "(unchanged)";
  std::string out;
  for (const StampedTransform& t : *batch.statics) {
    if (!out.empty()) out += ' ';
    out += t.parent + ">" + t.child;
  }
  return out;
}

TEST_F(FrameTreeTest, FirstBatchIsTheNewestOfEachFrameAndTheStaticSet) {
  FrameTree tree(options());
  tree.set_transform("map", "odom", planar(0, 0, 0, 0), at_ms(0));
  tree.set_transform("map", "odom", planar(1, 0, 0, 0), at_ms(10));
  tree.set_transform("odom", "base_link", planar(0, 1, 0, 0), at_ms(5));
  tree.set_static_transform("base_link", "lidar", planar(0.2, 0, 0.1, 0));

  TransformFeed feed(tree);
  const TransformBatch first = feed.poll();
  EXPECT_EQ(entries_text(first.dynamic), "map>odom@10 odom>base_link@5");
  EXPECT_EQ(statics_text(first), "base_link>lidar");
  EXPECT_NEAR(first.dynamic[0].transform.translation.x, 1, 1e-12);
  EXPECT_TRUE(feed.poll().empty()) << "nothing changed since";
}

TEST_F(FrameTreeTest, LaterBatchesGiveEveryNewEntryInOrder) {
  FrameTree tree(options());
  tree.set_transform("map", "odom", planar(0, 0, 0, 0), at_ms(0));
  TransformFeed feed(tree);
  (void)feed.poll();
  for (int ms = 10; ms <= 50; ms += 10) {
    tree.set_transform("map", "odom", planar(0, 0, 0, 0), at_ms(ms));
  }
  tree.set_transform("odom", "base_link", planar(0, 0, 0, 0), at_ms(50));
  const TransformBatch batch = feed.poll();
  EXPECT_EQ(entries_text(batch.dynamic),
            "map>odom@10 map>odom@20 map>odom@30 map>odom@40 map>odom@50 odom>base_link@50");
  EXPECT_FALSE(batch.statics) << "no static frame changed";
  EXPECT_EQ(feed.lost(), 0U);
}

TEST_F(FrameTreeTest, StaticSetIsSentWholeWhenItChanges) {
  FrameTree tree(options());
  tree.set_static_transform("base_link", "lidar", planar(0.2, 0, 0.1, 0));
  TransformFeed feed(tree);
  EXPECT_EQ(statics_text(feed.poll()), "base_link>lidar");

  tree.set_static_transform("base_link", "camera", planar(0.1, 0, 0.3, 0));
  EXPECT_EQ(statics_text(feed.poll()), "base_link>lidar base_link>camera");

  // A static frame that becomes dynamic leaves the set and goes with the dynamic entries.
  tree.set_transform("base_link", "lidar", planar(0.2, 0, 0.1, 0.1), at_ms(0));
  const TransformBatch batch = feed.poll();
  EXPECT_EQ(statics_text(batch), "base_link>camera");
  EXPECT_EQ(entries_text(batch.dynamic), "base_link>lidar@0");
}

TEST_F(FrameTreeTest, FramesNotCarriedNeverShowAndRestartGivesTheStateAgain) {
  FrameTree tree(options());
  bool carry_goal = false;
  TransformFeed feed(tree, [&](std::string_view child) { return child != "goal" || carry_goal; });
  tree.set_transform("map", "odom", planar(0, 0, 0, 0), at_ms(0));
  tree.set_transform("map", "goal", planar(5, 0, 0, 0), at_ms(0));
  tree.set_static_transform("map", "dock", planar(9, 0, 0, 0));
  TransformBatch batch = feed.poll();
  EXPECT_EQ(entries_text(batch.dynamic), "map>odom@0");
  EXPECT_EQ(statics_text(batch), "map>dock");

  tree.set_transform("map", "goal", planar(6, 0, 0, 0), at_ms(10));
  EXPECT_TRUE(feed.poll().empty()) << "only a frame it does not carry changed";

  // A frame that starts being carried starts with its newest entry, not its history.
  carry_goal = true;
  tree.set_transform("map", "goal", planar(7, 0, 0, 0), at_ms(20));
  EXPECT_EQ(entries_text(feed.poll().dynamic), "map>goal@20");

  feed.restart();
  batch = feed.poll();
  EXPECT_EQ(entries_text(batch.dynamic), "map>odom@0 map>goal@20");
  EXPECT_EQ(statics_text(batch), "map>dock");
}

TEST_F(FrameTreeTest, NextSleepsUntilAWriteAndCountsWhatALappingWriterTookAway) {
  FrameTree tree(options());
  tree.set_transform("map", "odom", planar(0, 0, 0, 0), at_ms(0));
  TransformFeed feed(tree);
  (void)feed.poll();

  const auto before = std::chrono::steady_clock::now();
  EXPECT_TRUE(feed.next(50ms).empty());
  EXPECT_GE(std::chrono::steady_clock::now() - before, 45ms) << "it waited, asleep";

  std::thread writer([&] {
    std::this_thread::sleep_for(20ms);
    tree.set_transform("map", "odom", planar(0, 0, 0, 0), at_ms(10));
  });
  const TransformBatch woken = feed.next(10s);
  writer.join();
  EXPECT_EQ(entries_text(woken.dynamic), "map>odom@10");

  // More writes than a frame's history holds between two calls: the overwritten ones are lost.
  const int written = static_cast<int>(horus::kFrameHistoryEntries) + 100;
  for (int i = 1; i <= written; ++i) {
    tree.set_transform("map", "odom", planar(0, 0, 0, 0), at_ms(10 + i));
  }
  const TransformBatch lapped = feed.poll();
  EXPECT_EQ(lapped.dynamic.back().stamp, at_ms(10 + written));
  EXPECT_EQ(lapped.dynamic.size() + feed.lost(), static_cast<std::size_t>(written));
  EXPECT_GT(feed.lost(), 0U);
}

TEST_F(FrameTreeTest, ADeadWritersFrameCanBeLeftOutUntilALiveOneTakesItOver) {
  // Another process sets "imported" and exits, as a bridge that brought it in would.
  const pid_t writer = ::fork();
  ASSERT_GE(writer, 0);
  if (writer == 0) {
    FrameTree own(options());
    own.set_transform("map", "imported", planar(1, 0, 0, 0), at_ms(0));
    own.set_static_transform("map", "dock", planar(9, 0, 0, 0));
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(writer, &status, 0), writer);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);

  FrameTree tree(options());
  tree.set_transform("map", "odom", planar(0, 0, 0, 0), at_ms(0));
  TransformFeed everything(tree);
  EXPECT_EQ(entries_text(everything.poll().dynamic), "map>imported@0 map>odom@0");

  TransformFeed live_only(tree, {}, {.skip_dead_authorities = true});
  const TransformBatch first = live_only.poll();
  EXPECT_EQ(entries_text(first.dynamic), "map>odom@0");
  EXPECT_EQ(statics_text(first), "map>dock") << "static frames are carried whoever set them";
  tree.set_static_transform("map", "charger", planar(8, 0, 0, 0));
  EXPECT_EQ(statics_text(live_only.poll()), "map>dock map>charger");
  tree.set_transform("map", "odom", planar(0, 0, 0, 0), at_ms(10));
  EXPECT_EQ(entries_text(live_only.poll().dynamic), "map>odom@10") << "still left out";

  tree.set_transform("map", "imported", planar(2, 0, 0, 0), at_ms(20));  // taken over
  EXPECT_EQ(entries_text(live_only.poll().dynamic), "map>imported@20");
  live_only.restart();
  EXPECT_EQ(entries_text(live_only.poll().dynamic), "map>imported@20 map>odom@10");
}

TEST_F(FrameTreeTest, HistorySinceGivesTheUpdatesFromANumberOn) {
  FrameTree tree(options());
  for (int i = 0; i < 4; ++i) tree.set_transform("map", "odom", planar(i, 0, 0, 0), at_ms(i));
  const horus::FrameUpdates updates = tree.history_since("odom", 2);
  EXPECT_EQ(entries_text(updates.entries), "map>odom@2 map>odom@3");
  EXPECT_EQ(updates.next, 4U);
  EXPECT_EQ(updates.lost, 0U);
  EXPECT_TRUE(tree.history_since("odom", 4).entries.empty());
  EXPECT_EQ(tree.history_since("odom", 4).next, 4U);
  EXPECT_THROW((void)tree.history_since("nowhere", 0), horus::UnknownFrameError);
}

TEST(FrameTransformJson, RoundTripsAndRefusesOtherShapes) {
  const StampedTransform original{
      "map",
      "base \"link\"",
      std::chrono::nanoseconds(1'700'000'000'123'456'789LL),
      {{1.5, -2.25, 1e-9}, {0, 0, 0.38268343236508978, 0.92387953251128674}}};
  const std::string json = horus::frame_transform_json(original);
  EXPECT_EQ(json.substr(0, 57), R"({"timestamp":{"sec":1700000000,"nsec":123456789},"parent_)");
  std::string why;
  const auto back = horus::frame_transform_from_json(json, &why);
  ASSERT_TRUE(back) << why;
  EXPECT_EQ(back->parent, original.parent);
  EXPECT_EQ(back->child, original.child);
  EXPECT_EQ(back->stamp, original.stamp);
  EXPECT_EQ(back->transform.translation.z, 1e-9);
  EXPECT_EQ(back->transform.rotation.z, original.transform.rotation.z) << "bit-exact doubles";

  EXPECT_FALSE(horus::frame_transform_from_json(json + " ", &why));
  EXPECT_NE(why.find("trailing text"), std::string::npos) << why;
  EXPECT_FALSE(
      horus::frame_transform_from_json(R"({"timestamp":{"sec":1,"nsec":2000000000}})", &why));
  EXPECT_NE(why.find("timestamp out of range"), std::string::npos) << why;
  EXPECT_FALSE(horus::frame_transform_from_json("{}"));
}

TEST_F(FrameTreeTest, ShmListShowsTheTreeAndCleanRemovesItOnlyWhenNobodyHasItOpen) {
  const auto tree_object = [&]() -> const horus::NamespaceObjectInfo* {
    static std::vector<horus::NamespaceObjectInfo> objects;
    objects = horus::list_namespace_objects(namespace_name_);
    for (const auto& object : objects) {
      if (object.kind == "@frames") return &object;
    }
    return nullptr;
  };
  {
    FrameTree tree(options());
    tree.set_static_transform("base_link", "lidar", planar(0.2, 0, 0.1, 0));
    const horus::NamespaceObjectInfo* object = tree_object();
    ASSERT_NE(object, nullptr);
    EXPECT_EQ(object->path, tree.path());
    EXPECT_TRUE(object->in_use);
    EXPECT_GT(object->size, 0U);
    EXPECT_LT(object->size, 1U << 20) << "only the pages written hold memory";
    horus::clean_namespace(namespace_name_);
    EXPECT_TRUE(horus::frame_tree_exists(namespace_name_)) << "in use: left alone";
  }
  const horus::NamespaceObjectInfo* object = tree_object();
  ASSERT_NE(object, nullptr);
  EXPECT_FALSE(object->in_use);
  horus::clean_namespace(namespace_name_);
  EXPECT_FALSE(horus::frame_tree_exists(namespace_name_));
  EXPECT_EQ(tree_object(), nullptr);
}

}  // namespace
