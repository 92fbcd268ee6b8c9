// The tensor pool between real processes: Image, DepthImage and PointCloud sent C++ -> C++ and
// read in place, references back to zero, a receiver killed with kill -9 while holding a frame,
// exhaustion under a stalled subscriber with each policy, and descriptors that must be refused.
// The test binary re-executes itself to play the receivers (topic_test_support.hpp); every wait
// is bounded, so a failure never hangs.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <horus/depth_image.hpp>
#include <horus/image.hpp>
#include <horus/point_cloud.hpp>
#include <horus/tensor.hpp>
#include <horus/tensor_pool.hpp>
#include <horus/topic.hpp>

#include "topic_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using horus::DepthImage;
using horus::Image;
using horus::ImageEncoding;
using horus::PointCloud;
using horus::PoolExhaustion;
using horus::TensorPool;
using horus::TensorPoolOptions;
using topic_test::Child;

constexpr auto kWait = 30s;

/// A private namespace whose pools are removed too.
class PoolNamespace : public topic_test::PrivateNamespace {
 public:
  PoolNamespace() { horus::remove_pools(name()); }
  PoolNamespace(const PoolNamespace&) = delete;
  PoolNamespace& operator=(const PoolNamespace&) = delete;
  ~PoolNamespace() { horus::remove_pools(name()); }
};

// ---- Content: every byte depends on its position and the frame's sequence number -------------

std::uint8_t image_byte(std::size_t index, std::uint64_t seq) {
  return static_cast<std::uint8_t>(index * 7 + index / 4099 + seq * 31);
}

void paint(Image& image, std::uint64_t seq) {
  std::span<std::uint8_t> bytes = image.data_mut();
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    bytes[i] = image_byte(i, seq);
  }
  image.set_timestamp_ns(seq);
  image.set_frame_id("camera");
}

bool painted(const Image& image, std::uint64_t seq) {
  const std::span<const std::uint8_t> bytes = image.data();
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    if (bytes[i] != image_byte(i, seq)) {
      std::fprintf(stderr, "image %llu: byte %zu differs\n", static_cast<unsigned long long>(seq),
                   i);
      return false;
    }
  }
  return image.timestamp_ns() == seq && image.frame_id() == "camera";
}

float depth_at(std::uint32_t x, std::uint32_t y) {
  return 0.25F + static_cast<float>(x) * 0.001F + static_cast<float>(y) * 0.0001F;
}

std::array<float, 3> point_at(std::size_t i) {
  return {static_cast<float>(i), static_cast<float>(i) * 0.5F, -static_cast<float>(i % 1000)};
}

/// Sends `value` to tell the parent something (readiness, a count).
void tell(std::uint64_t value) {
  horus::Topic<std::uint64_t> ack("ack");
  ack.send(value);
}

/// Waits for the child's message on "ack".
std::optional<std::uint64_t> hear(horus::Topic<std::uint64_t>& ack) { return ack.recv(kWait); }

// ---- Roles -------------------------------------------------------------------------------------

/// receive_image <count>: receives `count` 1080p RGB frames, checks every byte and that the data
/// is in the pool, then exits 0.
int role_receive_image(const std::vector<std::string>& args) {
  const std::uint64_t count = std::stoull(args.at(0));
  horus::Topic<Image> topic("camera");
  tell(0);
  for (std::uint64_t seq = 0; seq < count; ++seq) {
    std::optional<Image> image = topic.recv(kWait);
    if (!image) return 10;
    if (image->width() != 1920 || image->height() != 1080 ||
        image->encoding() != ImageEncoding::Rgb8 || image->step() != 1920 * 3) {
      return 11;
    }
    if (!image->pool().contains(image->data().data()) ||
        !image->pool().contains(image->data().data() + image->data().size() - 1)) {
      return 12;
    }
    if (!painted(*image, seq)) return 13;
    if (image->writable()) return 14;
  }
  return topic.refused() == 0 ? 0 : 15;
}

/// receive_depth: one 720p depth image in metres and one in millimetres.
int role_receive_depth(const std::vector<std::string>& /*args*/) {
  horus::Topic<DepthImage> topic("depth");
  tell(0);
  for (const bool meters : {true, false}) {
    std::optional<DepthImage> depth = topic.recv(kWait);
    if (!depth) return 10;
    if (depth->is_meters() != meters || depth->width() != 1280 || depth->height() != 720) {
      return 11;
    }
    if (!depth->pool().contains(depth->data().data())) return 12;
    for (std::uint32_t y = 0; y < depth->height(); ++y) {
      for (std::uint32_t x = 0; x < depth->width(); ++x) {
        const float expected =
            meters ? depth_at(x, y) : std::round(depth_at(x, y) / 0.001F) * 0.001F;
        const std::optional<float> got = depth->get_depth(x, y);
        if (!got || std::fabs(*got - expected) > 1e-6F) return 13;
      }
    }
  }
  return 0;
}

/// receive_cloud: one cloud of a million XYZ points.
int role_receive_cloud(const std::vector<std::string>& /*args*/) {
  horus::Topic<PointCloud> topic("lidar");
  tell(0);
  std::optional<PointCloud> cloud = topic.recv(kWait);
  if (!cloud) return 10;
  if (cloud->point_count() != 1'000'000 || !cloud->is_xyz()) return 11;
  if (!cloud->pool().contains(cloud->data().data())) return 12;
  for (std::size_t i = 0; i < cloud->point_count(); ++i) {
    std::array<float, 3> point{};
    std::memcpy(point.data(), cloud->point_at(i)->data(), sizeof point);
    if (point != point_at(i)) return 13;
  }
  return 0;
}

/// hold_frame: receives one frame, reports its references, and holds it until killed.
int role_hold_frame(const std::vector<std::string>& /*args*/) {
  horus::Topic<Image> topic("camera");
  tell(0);
  std::optional<Image> image = topic.recv(kWait);
  if (!image) return 10;
  tell(1);
  std::this_thread::sleep_for(120s);
  return 11;
}

/// map_pool <name>: opens the pool `name` (mapping it), says so, and keeps it until killed.
int role_map_pool(const std::vector<std::string>& args) {
  const TensorPool pool = TensorPool::open(args.at(0), {.block_size = 1 << 20, .block_count = 2});
  tell(0);
  std::this_thread::sleep_for(120s);
  return pool.block_count() == 2 ? 10 : 11;
}

/// stalled <frames>: subscribes, then reads nothing until the parent says "go" (on "go"), and
/// then every frame left: exits 0 when it got exactly the frames [first, frames) intact, where
/// `first` is the number it expects to be refused (the DropOldest run), and that many refused.
int role_stalled(const std::vector<std::string>& args) {
  const std::uint64_t frames = std::stoull(args.at(0));
  const std::uint64_t first = std::stoull(args.at(1));
  horus::TopicOptions options;
  options.capacity = 16;
  horus::Topic<Image> topic("camera", options);
  horus::Topic<std::uint64_t> go("go");
  tell(0);
  if (!go.recv(kWait)) return 10;
  for (std::uint64_t seq = first; seq < frames; ++seq) {
    std::optional<Image> image = topic.try_recv();
    if (!image) return 11;
    if (image->timestamp_ns() != seq || !painted(*image, seq)) return 12;
  }
  if (topic.try_recv()) return 13;
  return topic.refused() == first ? 0 : 14;
}

const bool kRolesRegistered = [] {
  auto& roles = topic_test::roles();
  roles["receive_image"] = role_receive_image;
  roles["receive_depth"] = role_receive_depth;
  roles["receive_cloud"] = role_receive_cloud;
  roles["hold_frame"] = role_hold_frame;
  roles["stalled"] = role_stalled;
  roles["map_pool"] = role_map_pool;
  return true;
}();
// Runs before main: a re-executed child plays its role and exits here.
const int kRoleStatus = topic_test::dispatch_role();

// ---- Tests -------------------------------------------------------------------------------------

TEST(PoolProcess, ImageCrossProcessInPlaceAndReferencesBackToZero) {
  PoolNamespace ns;
  TensorPool pool = horus::default_pool();
  horus::Topic<std::uint64_t> ack("ack");
  std::vector<horus::msg::PoolBlock> blocks;
  {
    horus::Topic<Image> topic("camera");
    Child child("receive_image", {"3"});
    ASSERT_TRUE(hear(ack));
    for (std::uint64_t seq = 0; seq < 3; ++seq) {
      Image image = Image::make(1080, 1920, ImageEncoding::Rgb8);
      paint(image, seq);
      EXPECT_EQ(pool.references(image.block()), 1U);
      ASSERT_TRUE(topic.send(image));
      // This handle and the frame in the ring (and the receiver's, once it has it).
      EXPECT_GE(pool.references(image.block()), 2U);
      blocks.push_back(image.block());
    }
    EXPECT_EQ(child.wait(), 0);
    // The images are gone; the frames are still in the ring until the topic closes.
    for (const auto& block : blocks) {
      EXPECT_EQ(pool.references(block), 1U);
    }
  }
  for (const auto& block : blocks) {
    EXPECT_EQ(pool.references(block), 0U);
  }
  EXPECT_EQ(pool.stats().blocks_in_use, 0U);
  EXPECT_EQ(pool.stats().refused, 0U);
}

TEST(PoolProcess, DepthImagesCrossProcess) {
  PoolNamespace ns;
  horus::Topic<std::uint64_t> ack("ack");
  {
    horus::Topic<DepthImage> topic("depth");
    Child child("receive_depth", {});
    ASSERT_TRUE(hear(ack));
    DepthImage meters = DepthImage::meters(720, 1280);
    DepthImage millimeters = DepthImage::millimeters(720, 1280);
    for (std::uint32_t y = 0; y < 720; ++y) {
      for (std::uint32_t x = 0; x < 1280; ++x) {
        meters.set_depth(x, y, depth_at(x, y));
        millimeters.set_depth(x, y, depth_at(x, y));
      }
    }
    ASSERT_TRUE(topic.send(meters));
    ASSERT_TRUE(topic.send(millimeters));
    EXPECT_EQ(child.wait(), 0);
  }
  EXPECT_EQ(horus::default_pool().stats().blocks_in_use, 0U);
}

TEST(PoolProcess, MillionPointCloudCrossProcess) {
  PoolNamespace ns;
  horus::Topic<std::uint64_t> ack("ack");
  {
    horus::Topic<PointCloud> topic("lidar");
    Child child("receive_cloud", {});
    ASSERT_TRUE(hear(ack));
    std::vector<std::array<float, 3>> points(1'000'000);
    for (std::size_t i = 0; i < points.size(); ++i) {
      points[i] = point_at(i);
    }
    ASSERT_TRUE(topic.send(PointCloud::from_xyz(points)));
    EXPECT_EQ(child.wait(), 0);
  }
  EXPECT_EQ(horus::default_pool().stats().blocks_in_use, 0U);
}

TEST(PoolProcess, ReceiverKilledWhileHoldingAFrameGivesItBack) {
  PoolNamespace ns;
  // One block: while the receiver holds it, nothing else can be allocated.
  TensorPool pool = TensorPool::open("one", {.block_size = 8 << 20, .block_count = 1});
  horus::Topic<std::uint64_t> ack("ack");
  Child child("hold_frame", {});
  ASSERT_TRUE(hear(ack));
  horus::msg::PoolBlock block{};
  {
    horus::Topic<Image> topic("camera");
    Image image = Image::make(1080, 1920, ImageEncoding::Rgb8, pool);
    paint(image, 0);
    block = image.block();
    ASSERT_TRUE(topic.send(image));
    ASSERT_EQ(hear(ack), std::optional<std::uint64_t>(1));
  }
  // Only the receiver holds it now.
  EXPECT_EQ(pool.references(block), 1U);
  EXPECT_THROW(Image::make(1080, 1920, ImageEncoding::Rgb8, pool), horus::Error);
  EXPECT_EQ(pool.stats().exhausted, 1U);
  child.kill();
  // The allocation notices the dead holder and takes its block back.
  Image again = Image::make(1080, 1920, ImageEncoding::Rgb8, pool);
  EXPECT_EQ(again.block().index, block.index);
  EXPECT_NE(again.block().generation, block.generation);
  EXPECT_EQ(pool.references(block), 0U);
  EXPECT_EQ(pool.stats().reclaimed, 1U);
}

/// A 4-block pool and a 16-slot ring whose subscriber reads nothing until told: sends `frames`
/// painted 1080p frames (as many as the pool lets `policy` make), then lets the subscriber read,
/// expecting it to refuse the first `refused` and get the rest intact. Returns the pool's stats.
horus::TensorPoolStats stalled_subscriber(PoolExhaustion policy, std::uint64_t frames,
                                          std::uint64_t refused) {
  TensorPool pool =
      TensorPool::open("small", {.block_size = 8 << 20, .block_count = 4, .on_exhaustion = policy});
  horus::Topic<std::uint64_t> ack("ack");
  horus::Topic<std::uint64_t> go("go");
  horus::TopicOptions options;
  options.capacity = 16;
  horus::Topic<Image> topic("camera", options);
  Child child("stalled", {std::to_string(frames), std::to_string(refused)});
  EXPECT_TRUE(hear(ack));
  for (std::uint64_t seq = 0; seq < frames; ++seq) {
    Image image = Image::make(1080, 1920, ImageEncoding::Rgb8, pool);
    paint(image, seq);
    EXPECT_TRUE(topic.send(image));
  }
  if (policy == PoolExhaustion::Fail) {
    // The frames in the ring hold every block: the next allocation says so.
    try {
      (void)Image::make(1080, 1920, ImageEncoding::Rgb8, pool);
      ADD_FAILURE() << "the allocation should have failed";
    } catch (const horus::Error& e) {
      EXPECT_NE(std::string(e.what()).find("exhausted"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(go.send(1));
  EXPECT_EQ(child.wait(), 0);
  return pool.stats();
}

TEST(PoolProcess, ExhaustionUnderAStalledSubscriberFailsTheAllocation) {
  PoolNamespace ns;
  const horus::TensorPoolStats stats = stalled_subscriber(PoolExhaustion::Fail, 4, 0);
  EXPECT_EQ(stats.exhausted, 1U);
  EXPECT_EQ(stats.dropped, 0U);
}

TEST(PoolProcess, ExhaustionUnderAStalledSubscriberDropsTheOldestUnreadFrames) {
  PoolNamespace ns;
  // Ten frames through four blocks: the six oldest unread ones are given up, and the subscriber
  // refuses them and reads the last four intact.
  const horus::TensorPoolStats stats = stalled_subscriber(PoolExhaustion::DropOldest, 10, 6);
  EXPECT_EQ(stats.exhausted, 0U);
  EXPECT_EQ(stats.dropped, 6U);
}

TEST(PoolProcess, FreedForeignAndMalformedDescriptorsAreRefused) {
  PoolNamespace ns;
  TensorPool pool = horus::default_pool();
  horus::TopicOptions options;
  options.capacity = 8;
  horus::Topic<Image> receiver("camera", options);
  horus::Topic<horus::msg::ImageDescriptor> raw("camera");

  Image image = Image::make(480, 640, ImageEncoding::Rgb8);
  const horus::msg::ImageDescriptor good = image.descriptor();

  horus::msg::ImageDescriptor foreign = good;
  foreign.block.pool_id ^= 0x5a5a5a5a5a5a5a5aULL;
  horus::msg::ImageDescriptor out_of_range = good;
  out_of_range.block.index = 1'000'000;
  horus::msg::ImageDescriptor too_big = good;
  too_big.height = 100'000;
  too_big.data_size = std::uint64_t{too_big.step} * too_big.height;
  horus::msg::ImageDescriptor inconsistent = good;
  inconsistent.data_size += 1;
  // A descriptor of another namespace's pool.
  horus::msg::ImageDescriptor other_namespace{};
  {
    TensorPoolOptions options;
    options.namespace_name = ns.name() + "_other";
    horus::remove_pools(options.namespace_name);
    TensorPool other = TensorPool::open("default", options);
    Image elsewhere = Image::make(480, 640, ImageEncoding::Rgb8, other);
    other_namespace = elsewhere.descriptor();
  }
  horus::remove_pools(ns.name() + "_other");

  for (const auto& descriptor : {foreign, out_of_range, too_big, inconsistent, other_namespace}) {
    ASSERT_TRUE(raw.send(descriptor));
  }
  EXPECT_FALSE(receiver.try_recv());
  EXPECT_EQ(receiver.refused(), 5U);

  // Freed: the image is gone, its block free (a release leaves freeing to the next allocation
  // that needs a block, or to reclaim()); then reused by another image (new generation).
  image = Image();
  EXPECT_EQ(pool.references(good.block), 0U);
  EXPECT_GE(pool.reclaim(), 1U);
  ASSERT_TRUE(raw.send(good));
  EXPECT_FALSE(receiver.try_recv());
  Image reuse = Image::make(480, 640, ImageEncoding::Rgb8);
  ASSERT_TRUE(raw.send(good));
  EXPECT_FALSE(receiver.try_recv());
  EXPECT_EQ(receiver.refused(), 7U);
  // Refusing took no reference.
  EXPECT_EQ(pool.references(reuse.block()), 1U);
  // The current one is accepted.
  ASSERT_TRUE(raw.send(reuse.descriptor()));
  std::optional<Image> accepted = receiver.try_recv();
  ASSERT_TRUE(accepted);
  EXPECT_EQ(accepted->data().data(), reuse.data().data());
  EXPECT_EQ(pool.references(reuse.block()), 2U);
}

TEST(PoolProcess, CleanRemovesOnlyPoolsNoLiveProcessMaps) {
  PoolNamespace ns;
  const std::string folder = horus::detail::shm_root() + "/@pool/" + ns.name() + "/";
  const TensorPool mine = TensorPool::open("mine", {.block_size = 1 << 20, .block_count = 2});
  horus::Topic<std::uint64_t> ack("ack");
  Child child("map_pool", {"theirs"});
  ASSERT_TRUE(hear(ack));
  // Mapped by this process and by a live child: both kept.
  EXPECT_EQ(horus::clean_pools(ns.name()), 0U);
  EXPECT_EQ(::access((folder + "mine").c_str(), F_OK), 0);
  EXPECT_EQ(::access((folder + "theirs").c_str(), F_OK), 0);
  child.kill();
  // Its only user died: removed; this process's pool stays.
  EXPECT_EQ(horus::clean_pools(ns.name()), 1U);
  EXPECT_NE(::access((folder + "theirs").c_str(), F_OK), 0);
  EXPECT_EQ(::access((folder + "mine").c_str(), F_OK), 0);
  // Opening it again makes a fresh pool under the same name.
  const TensorPool again = TensorPool::open("theirs", {.block_size = 1 << 20, .block_count = 2});
  EXPECT_EQ(again.block_count(), 2U);
  EXPECT_EQ(horus::clean_pools(ns.name()), 0U);
}

}  // namespace
