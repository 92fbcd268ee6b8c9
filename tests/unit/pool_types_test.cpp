// The pool-backed types in one process: the seed's methods of Image, DepthImage, PointCloud and
// Tensor, their bad input, Topic<T> (read_latest, recv with a timeout, event nodes, frames kept
// alive for the ring's capacity) and log summaries that describe without dumping data.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <horus/depth_image.hpp>
#include <horus/image.hpp>
#include <horus/point_cloud.hpp>
#include <horus/scheduler.hpp>
#include <horus/tensor.hpp>
#include <horus/tensor_pool.hpp>
#include <horus/topic_registry.hpp>

namespace {

using namespace std::chrono_literals;
using horus::DepthImage;
using horus::Image;
using horus::ImageEncoding;
using horus::PointCloud;
using horus::Tensor;
using horus::TensorPool;
using horus::msg::TensorDtype;

class PoolTypes : public ::testing::Test {
 protected:
  void SetUp() override {
    namespace_ = "pool_types_" + std::to_string(::getpid()) + "_" +
                 ::testing::UnitTest::GetInstance()->current_test_info()->name();
    ::setenv("HORUS_NAMESPACE", namespace_.c_str(), 1);
  }
  void TearDown() override {
    horus::remove_namespace(namespace_);
    horus::remove_pools(namespace_);
    ::unsetenv("HORUS_NAMESPACE");
  }
  std::string namespace_;
};

TEST_F(PoolTypes, ImagePixelsRoiFillAndCopy) {
  Image image = Image::make(4, 6, ImageEncoding::Rgb8);
  EXPECT_EQ(image.width(), 6U);
  EXPECT_EQ(image.height(), 4U);
  EXPECT_EQ(image.channels(), 3U);
  EXPECT_EQ(image.step(), 18U);
  EXPECT_EQ(image.data().size(), 72U);
  EXPECT_TRUE(image.writable());
  const std::array<std::uint8_t, 3> red{255, 0, 0};
  image.set_pixel(5, 3, red);
  ASSERT_TRUE(image.pixel(5, 3));
  EXPECT_EQ((*image.pixel(5, 3))[0], 255);
  EXPECT_EQ(image.data()[3 * 18 + 5 * 3], 255);
  EXPECT_FALSE(image.pixel(6, 0));
  EXPECT_FALSE(image.pixel(0, 4));
  EXPECT_THROW(image.set_pixel(6, 0, red), horus::Error);
  EXPECT_THROW(image.set_pixel(0, 0, std::array<std::uint8_t, 2>{1, 2}), horus::Error);

  const std::optional<std::vector<std::uint8_t>> roi = image.roi(4, 2, 2, 2);
  ASSERT_TRUE(roi);
  ASSERT_EQ(roi->size(), 12U);
  EXPECT_EQ((*roi)[9], 255);  // pixel (5, 3) is the region's last
  EXPECT_FALSE(image.roi(5, 0, 2, 1));
  EXPECT_FALSE(image.roi(0, 0, 0, 1));

  image.fill(std::array<std::uint8_t, 3>{1, 2, 3});
  EXPECT_EQ(image.data()[0], 1);
  EXPECT_EQ(image.data()[71], 3);
  image.fill(9);
  EXPECT_EQ(image.data()[40], 9);
  std::vector<std::uint8_t> bytes(72, 7);
  image.copy_from(bytes);
  EXPECT_EQ(image.data()[71], 7);
  EXPECT_THROW(image.copy_from(std::vector<std::uint8_t>(71)), horus::Error);
  image.set_frame_id("cam0");
  image.set_timestamp_ns(42);
  EXPECT_EQ(image.frame_id(), "cam0");
  EXPECT_EQ(image.timestamp_ns(), 42U);
  EXPECT_THROW(image.set_frame_id(std::string(40, 'x')), horus::Error);
}

TEST_F(PoolTypes, ImageRefusesBadGeometry) {
  EXPECT_THROW(Image::make(0, 640, ImageEncoding::Rgb8), horus::Error);
  EXPECT_THROW(Image::make(480, 640, static_cast<ImageEncoding>(77)), horus::Error);
  // 4K RGB32F is 99 MB: more than a block of the default pool.
  EXPECT_THROW(Image::make(2160, 3840, ImageEncoding::Rgb32F), horus::Error);
  TensorPool pool = horus::default_pool();
  EXPECT_EQ(pool.stats().blocks_in_use, 0U);
}

TEST_F(PoolTypes, LogSummaryDescribesWithoutDumpingPixels) {
  Image image = Image::make(1080, 1920, ImageEncoding::Rgb8);
  image.set_frame_id("front");
  const std::string summary = image.log_summary();
  EXPECT_NE(summary.find("1920x1080 Rgb8"), std::string::npos) << summary;
  EXPECT_NE(summary.find("6220800 bytes"), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"front\""), std::string::npos) << summary;
  EXPECT_LT(summary.size(), 160U);
  EXPECT_LT(DepthImage::meters(480, 640).log_summary().size(), 160U);
  const std::vector<std::array<float, 3>> points(1000);
  EXPECT_NE(PointCloud::from_xyz(points).log_summary().find("1000 points x 3 F32"),
            std::string::npos);
  EXPECT_NE(Tensor::make({2, 3, 4}, TensorDtype::F32).log_summary().find("[2, 3, 4] F32"),
            std::string::npos);
}

TEST_F(PoolTypes, DepthImageMetersMillimetersAndStatistics) {
  DepthImage meters = DepthImage::meters(2, 3);
  EXPECT_TRUE(meters.is_meters());
  EXPECT_FALSE(meters.is_millimeters());
  EXPECT_EQ(meters.dtype(), TensorDtype::F32);
  EXPECT_FLOAT_EQ(meters.depth_scale(), 1.0F);
  meters.set_depth(0, 0, 1.5F).set_depth(2, 1, 3.5F);
  EXPECT_FLOAT_EQ(*meters.get_depth(0, 0), 1.5F);
  EXPECT_FALSE(meters.get_depth(3, 0));
  EXPECT_FALSE(meters.get_depth_u16(0, 0));
  const horus::DepthStatistics stats = meters.depth_statistics();
  EXPECT_FLOAT_EQ(stats.min, 1.5F);
  EXPECT_FLOAT_EQ(stats.max, 3.5F);
  EXPECT_FLOAT_EQ(stats.mean, 2.5F);  // zeros are invalid depths, not counted
  EXPECT_THROW(meters.set_depth(3, 0, 1.0F), horus::Error);

  DepthImage millimeters = DepthImage::millimeters(2, 2);
  EXPECT_TRUE(millimeters.is_millimeters());
  EXPECT_EQ(millimeters.dtype(), TensorDtype::U16);
  millimeters.set_depth(1, 1, 1.234F);
  EXPECT_EQ(millimeters.get_depth_u16(1, 1), std::optional<std::uint16_t>(1234));
  EXPECT_NEAR(*millimeters.get_depth(1, 1), 1.234F, 1e-6F);
  millimeters.set_depth(0, 0, 1000.0F);  // beyond U16: clamped
  EXPECT_EQ(millimeters.get_depth_u16(0, 0), std::optional<std::uint16_t>(65535));
  EXPECT_EQ(DepthImage::meters(1, 1).depth_statistics().max, 0.0F);
}

TEST_F(PoolTypes, PointCloudKindsAndAccess) {
  const std::vector<std::array<float, 4>> xyzi{{1, 2, 3, 0.5F}, {4, 5, 6, 0.25F}};
  PointCloud cloud = PointCloud::from_xyzi(xyzi);
  EXPECT_EQ(cloud.point_count(), 2U);
  EXPECT_EQ(cloud.fields_per_point(), 4U);
  EXPECT_TRUE(cloud.has_intensity());
  EXPECT_FALSE(cloud.is_xyz());
  EXPECT_FALSE(cloud.has_color());
  EXPECT_EQ(cloud.point_at(1)->size(), 16U);
  EXPECT_FALSE(cloud.point_at(2));
  const auto xyz = cloud.extract_xyz();
  ASSERT_TRUE(xyz);
  EXPECT_EQ((*xyz)[1], (std::array<float, 3>{4, 5, 6}));
  const std::vector<std::array<float, 6>> xyzrgb(3);
  EXPECT_TRUE(PointCloud::from_xyzrgb(xyzrgb).has_color());
  PointCloud bytes = PointCloud::make(10, 3, TensorDtype::U8);
  EXPECT_FALSE(bytes.extract_xyz());
  EXPECT_THROW(bytes.copy_from(std::vector<std::uint8_t>(29)), horus::Error);
  EXPECT_THROW(PointCloud::make(0, 3, TensorDtype::F32), horus::Error);
}

TEST_F(PoolTypes, TensorShapeStridesAndTopic) {
  Tensor tensor = Tensor::make({2, 3, 4}, TensorDtype::F32);
  EXPECT_EQ(tensor.ndim(), 3U);
  EXPECT_EQ(std::vector<std::uint64_t>(tensor.shape().begin(), tensor.shape().end()),
            (std::vector<std::uint64_t>{2, 3, 4}));
  EXPECT_EQ(std::vector<std::uint64_t>(tensor.strides().begin(), tensor.strides().end()),
            (std::vector<std::uint64_t>{48, 16, 4}));
  EXPECT_EQ(tensor.element_count(), 24U);
  EXPECT_EQ(tensor.size(), 96U);
  tensor.data_mut()[95] = 0xab;
  EXPECT_THROW(Tensor::make({1, 2, 3, 4, 5, 6, 7, 8, 9}, TensorDtype::U8), horus::Error);

  horus::Topic<Tensor> topic("tensors");
  ASSERT_TRUE(topic.send(tensor));
  std::optional<Tensor> got = topic.try_recv();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->data().data(), tensor.data().data());
  EXPECT_EQ(got->data()[95], 0xab);
  EXPECT_FALSE(got->writable());
  EXPECT_THROW(got->data_mut(), horus::Error);

  // A descriptor whose strides reach past its data is refused.
  horus::msg::TensorDescriptor reaching = tensor.descriptor();
  reaching.strides[0] = 1 << 20;
  horus::Topic<horus::msg::TensorDescriptor> raw("tensors");
  ASSERT_TRUE(raw.send(reaching));
  EXPECT_FALSE(topic.try_recv());
  EXPECT_EQ(topic.refused(), 1U);
}

TEST_F(PoolTypes, TopicReadLatestTimeoutAndRingKeepsFramesAlive) {
  TensorPool pool = horus::default_pool();
  horus::Topic<Image> topic("camera");  // capacity 4: four frames stay alive
  horus::Topic<Image> subscriber("camera");
  EXPECT_FALSE(subscriber.recv(1ms));
  EXPECT_FALSE(subscriber.read_latest());
  std::vector<horus::msg::PoolBlock> blocks;
  for (std::uint8_t seq = 0; seq < 6; ++seq) {
    Image image = Image::make(2, 2, ImageEncoding::Mono8);
    image.fill(seq);
    ASSERT_TRUE(topic.send(image));
    blocks.push_back(image.block());
  }
  // The ring moved on from the first two: their blocks are free, the last four held once.
  EXPECT_EQ(pool.references(blocks[0]), 0U);
  EXPECT_EQ(pool.references(blocks[1]), 0U);
  for (std::size_t i = 2; i < 6; ++i) {
    EXPECT_EQ(pool.references(blocks[i]), 1U);
  }
  std::optional<Image> latest = subscriber.read_latest();
  ASSERT_TRUE(latest);
  EXPECT_EQ(latest->data()[0], 5);
  // The subscriber lost the two oldest (the ring's capacity) and gets the rest in order.
  for (std::uint8_t seq = 2; seq < 6; ++seq) {
    std::optional<Image> image = subscriber.recv(1s);
    ASSERT_TRUE(image);
    EXPECT_EQ(image->data()[0], seq);
  }
  EXPECT_EQ(subscriber.lost(), 2U);
}

class ImageHandler : public horus::Node {
 public:
  ImageHandler() : topic_("camera") {}
  std::string_view name() const override { return "image_handler"; }
  void tick() override {
    while (std::optional<Image> image = topic_.try_recv()) {
      last_width = image->width();
      ++frames;
    }
  }
  std::uint32_t last_width = 0;
  int frames = 0;

 private:
  horus::Topic<Image> topic_;
};

TEST_F(PoolTypes, EventNodeTicksOnAnImage) {
  horus::Scheduler scheduler;
  auto node = std::make_unique<ImageHandler>();
  ImageHandler* handler = node.get();
  scheduler.add(std::move(node)).on("camera").build();
  horus::Topic<Image> publisher("camera");
  scheduler.tick_once();
  EXPECT_EQ(handler->frames, 0);
  ASSERT_TRUE(publisher.send(Image::make(480, 640, ImageEncoding::Bgr8)));
  scheduler.tick_once();
  EXPECT_EQ(handler->frames, 1);
  EXPECT_EQ(handler->last_width, 640U);
}

}  // namespace

namespace {

TEST_F(PoolTypes, ThreadsExchangeFramesWithoutTearingOrLeaks) {
  TensorPool pool = TensorPool::open("threads", {.block_size = 4096, .block_count = 8});
  constexpr int kFrames = 2000;
  std::atomic<bool> done{false};
  std::atomic<int> torn{0};
  std::atomic<int> received{0};
  horus::Topic<Image> subscriber("frames");
  std::thread reader([&] {
    while (!done.load() || subscriber.has_msg()) {
      if (std::optional<Image> image = subscriber.recv(10ms)) {
        const std::span<const std::uint8_t> bytes = image->data();
        for (const std::uint8_t byte : bytes) {
          torn += byte != bytes[0] ? 1 : 0;
        }
        ++received;
      }
    }
  });
  {
    horus::Topic<Image> publisher("frames");
    for (int i = 0; i < kFrames; ++i) {
      // The reader may hold a frame and four are in flight: a block is always free.
      Image image = Image::make(64, 64, ImageEncoding::Mono8, pool);
      image.fill(static_cast<std::uint8_t>(i));
      EXPECT_TRUE(publisher.send(image));
    }
    done = true;
    reader.join();
  }
  EXPECT_EQ(torn.load(), 0);
  EXPECT_GT(received.load(), 0);
  EXPECT_EQ(pool.stats().blocks_in_use, 0U);
  EXPECT_EQ(pool.stats().exhausted, 0U);
}

}  // namespace
