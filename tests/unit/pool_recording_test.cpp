// Recording pool-backed topics (issues 19 and 20): a recorder keeps each Image and PointCloud
// frame with its data (descriptor, then the bytes it covers), holds the block only while it
// copies, counts a descriptor whose block is gone as lost, and a deterministic replay makes the
// frames again in the pool so that a subscriber receives the recorded pixels.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "horus/depth_image.hpp"
#include "horus/image.hpp"
#include "horus/internal/replayer.hpp"
#include "horus/point_cloud.hpp"
#include "horus/pool_topic.hpp"
#include "horus/recording.hpp"
#include "horus/tensor_pool.hpp"
#include "horus/topic_registry.hpp"
#include "topic_test_support.hpp"

namespace {

using horus::Image;
using horus::ImageEncoding;
using horus::PointCloud;
using horus::msg::ImageDescriptor;
using horus::msg::PointCloudDescriptor;

/// A private recordings folder and the namespace's pools, both removed afterwards.
class PoolRecording : public ::testing::Test {
 protected:
  PoolRecording()
      : folder_(std::filesystem::temp_directory_path() /
                ("horus_pool_recordings_" + std::to_string(::getpid()) + "_" +
                 ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
    std::filesystem::remove_all(folder_);
    ::setenv("HORUS_RECORDINGS", folder_.c_str(), 1);
  }
  ~PoolRecording() override {
    horus::remove_pools(ns_.name());
    ::unsetenv("HORUS_RECORDINGS");
    std::filesystem::remove_all(folder_);
  }

  topic_test::PrivateNamespace ns_;
  std::filesystem::path folder_;
};

horus::RecorderOptions options_for(std::vector<std::string> topics) {
  horus::RecorderOptions options;
  options.topics = std::move(topics);
  return options;
}

template <class Descriptor>
Descriptor descriptor_of(const horus::RecordedMessage& m) {
  Descriptor descriptor;
  std::memcpy(&descriptor, m.data.data(), sizeof descriptor);
  return descriptor;
}

std::vector<std::uint8_t> data_of(const horus::RecordedMessage& m, std::size_t descriptor) {
  return {m.data.begin() + static_cast<std::ptrdiff_t>(descriptor), m.data.end()};
}

Image gradient(std::uint8_t seed) {
  Image image = Image::make(48, 64, ImageEncoding::Rgb8);
  std::span<std::uint8_t> pixels = image.data_mut();
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    pixels[i] = static_cast<std::uint8_t>(i * 7 + seed);
  }
  image.set_frame_id("camera_" + std::to_string(seed));
  image.set_timestamp_ns(1000 + seed);
  return image;
}

std::vector<std::uint8_t> bytes_of(std::span<const std::uint8_t> data) {
  return {data.begin(), data.end()};
}

TEST_F(PoolRecording, RecorderKeepsImagesAndCloudsWithTheirDataAndLetsTheBlocksGo) {
  const horus::TensorPool pool = horus::default_pool();
  std::vector<Image> images;
  std::vector<std::vector<std::uint8_t>> pixels;
  std::filesystem::path file;
  std::vector<std::array<float, 3>> points;
  for (int i = 0; i < 1000; ++i) {
    points.push_back({static_cast<float>(i), static_cast<float>(-i), 0.5F * static_cast<float>(i)});
  }
  std::optional<PointCloud> cloud;
  {
    horus::Topic<Image> camera("camera");
    horus::Topic<PointCloud> lidar("lidar");
    horus::Recorder recorder(options_for({"camera", "lidar"}));
    for (std::uint8_t seed = 0; seed < 3; ++seed) {
      images.push_back(gradient(seed));
      pixels.push_back(bytes_of(images.back().data()));
      ASSERT_TRUE(camera.send(images.back()));
    }
    cloud = PointCloud::from_xyz(points);
    ASSERT_TRUE(lidar.send(*cloud));
    const horus::RecordingSummary summary = recorder.stop();
    EXPECT_EQ(summary.messages, 4U);
    EXPECT_EQ(summary.lost_total, 0U);
    file = summary.path;
    // The recorder held each block only while copying: what is left is the handle and the frame
    // in flight in the ring.
    for (const Image& image : images) EXPECT_EQ(pool.references(image.block()), 2U);
    EXPECT_EQ(pool.references(cloud->block()), 2U);
  }
  for (const Image& image : images) EXPECT_EQ(pool.references(image.block()), 1U);
  std::vector<horus::msg::PoolBlock> blocks;
  for (const Image& image : images) blocks.push_back(image.block());
  blocks.push_back(cloud->block());
  images.clear();
  cloud.reset();
  for (const horus::msg::PoolBlock& block : blocks) EXPECT_EQ(pool.references(block), 0U);

  const horus::RecordingReader reader(file);
  const horus::RecordedChannel* channel = reader.channel("camera");
  ASSERT_NE(channel, nullptr);
  EXPECT_EQ(channel->message_encoding, "horus.pool");
  EXPECT_EQ(channel->metadata.at("horus.type"), horus::TypeInfo<ImageDescriptor>::name);
  EXPECT_EQ(channel->metadata.at("horus.payload_size"), std::to_string(sizeof(ImageDescriptor)));
  const horus::RecordedSchema& schema = reader.schemas().at(channel->schema_id);
  EXPECT_EQ(schema.name, horus::TypeInfo<ImageDescriptor>::name);
  EXPECT_EQ(schema.data, horus::TypeInfo<ImageDescriptor>::schema);

  const auto frames = reader.messages_on("camera");
  ASSERT_EQ(frames.size(), 3U);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const auto descriptor = descriptor_of<ImageDescriptor>(*frames[i]);
    EXPECT_EQ(descriptor.width, 64U);
    EXPECT_EQ(descriptor.height, 48U);
    EXPECT_EQ(descriptor.encoding, ImageEncoding::Rgb8);
    EXPECT_EQ(descriptor.data_size, 64U * 48U * 3U);
    EXPECT_EQ(descriptor.frame_id.view(), "camera_" + std::to_string(i));
    EXPECT_EQ(descriptor.timestamp_ns, 1000 + i);
    // The block it named ended with the run.
    EXPECT_EQ(descriptor.block.pool_id, 0U);
    EXPECT_EQ(descriptor.block.generation, 0U);
    EXPECT_EQ(data_of(*frames[i], sizeof(ImageDescriptor)), pixels[i]) << "frame " << i;
  }

  const auto clouds = reader.messages_on("lidar");
  ASSERT_EQ(clouds.size(), 1U);
  EXPECT_EQ(reader.channel("lidar")->message_encoding, "horus.pool");
  const auto descriptor = descriptor_of<PointCloudDescriptor>(*clouds[0]);
  EXPECT_EQ(descriptor.point_count, points.size());
  EXPECT_EQ(descriptor.fields_per_point, 3U);
  const std::vector<std::uint8_t> recorded = data_of(*clouds[0], sizeof(PointCloudDescriptor));
  ASSERT_EQ(recorded.size(), points.size() * sizeof(points[0]));
  EXPECT_EQ(std::memcmp(recorded.data(), points.data(), recorded.size()), 0);
}

TEST_F(PoolRecording, ADescriptorWhoseBlockWasFreedIsCountedLostNotRead) {
  horus::TensorPoolOptions small;
  small.block_size = 4096;
  small.block_count = 2;
  const horus::TensorPool pool = horus::TensorPool::open("small", small);
  horus::Topic<Image> camera("camera");
  horus::Topic<ImageDescriptor> forger("camera", horus::pool_topic_options());
  horus::Recorder recorder(options_for({"camera"}));

  ImageDescriptor stale;
  {
    Image gone = Image::make(8, 8, ImageEncoding::Mono8, pool);
    stale = gone.descriptor();
  }
  // Both blocks taken: the allocation that finds none free frees and reuses the one above.
  Image first = Image::make(8, 8, ImageEncoding::Mono8, pool);
  Image second = Image::make(8, 8, ImageEncoding::Mono8, pool);
  ASSERT_EQ(second.block().index, stale.block.index);
  ASSERT_NE(second.block().generation, stale.block.generation);
  second.fill(42);

  ASSERT_TRUE(forger.send(stale));
  ASSERT_TRUE(camera.send(second));
  const horus::RecordingSummary summary = recorder.stop();
  EXPECT_EQ(summary.messages, 1U);
  EXPECT_EQ(summary.lost_total, 1U);
  EXPECT_EQ(summary.lost.at("camera"), 1U);

  const horus::RecordingReader reader(summary.path);
  const auto frames = reader.messages_on("camera");
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(data_of(*frames[0], sizeof(ImageDescriptor)), std::vector<std::uint8_t>(64, 42));
}

TEST_F(PoolRecording, DeterministicReplayMakesTheFramesAgainInThePool) {
  std::vector<std::vector<std::uint8_t>> pixels;
  std::filesystem::path file;
  {
    horus::Topic<Image> camera("camera");
    horus::Recorder recorder(options_for({"camera"}));
    for (std::uint8_t seed = 10; seed < 13; ++seed) {
      const Image image = gradient(seed);
      pixels.push_back(bytes_of(image.data()));
      ASSERT_TRUE(camera.send(image));
    }
    file = recorder.stop().path;
  }
  const horus::TensorPool pool = horus::default_pool();
  horus::Topic<Image> subscriber("camera");
  std::vector<horus::msg::PoolBlock> blocks;
  {
    horus::detail::Replayer replayer(file, ns_.name(), {});
    replayer.deliver_before_cycle(0);
    EXPECT_EQ(replayer.delivered(), 3U);
    for (std::size_t i = 0; i < pixels.size(); ++i) {
      std::optional<Image> frame = subscriber.try_recv();
      ASSERT_TRUE(frame) << "frame " << i;
      EXPECT_EQ(frame->width(), 64U);
      EXPECT_EQ(frame->frame_id(), "camera_" + std::to_string(10 + i));
      EXPECT_TRUE(pool.contains(frame->data().data()));
      EXPECT_EQ(bytes_of(frame->data()), pixels[i]) << "frame " << i;
      blocks.push_back(frame->block());
    }
    EXPECT_FALSE(subscriber.try_recv());
    EXPECT_EQ(subscriber.refused(), 0U);
  }
  // The replayer's frames in flight went with it.
  for (const horus::msg::PoolBlock& block : blocks) EXPECT_EQ(pool.references(block), 0U);
}

}  // namespace
