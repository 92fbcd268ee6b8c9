// The C++ side of the Python pool tests (test_runtime_pool.py): sends or receives one Image
// (1080p RGB), DepthImage (720p metres, or millimetres for depth_mm) or PointCloud (a million
// XYZ points) whose every value follows a formula both languages compute.
//   pool_peer send <image|depth|depth_mm|cloud> <topic>: prints "open", waits for a line on
//     stdin, sends, and keeps the frame alive until the next line (the receiver is done)
//   pool_peer recv <image|depth|depth_mm|cloud> <topic>: opens the topic, prints "ready",
//     receives, checks, exits 0
//   pool_peer node-send image <topic> <count>: a scheduler whose C++ node publishes one image a
//     tick (timestamp_ns = 1..count); prints "open", waits for a line, ticks until all are sent,
//     waits for a line (the receiver is done), drops its scheduler and prints "references N",
//     the sum of the references its blocks still have
//   pool_peer node-recv image <topic> <count>: a scheduler whose C++ node subscribes; prints
//     "ready", ticks until it has checked `count` images, prints their timestamps, exits 0
// It prints what went wrong on stderr and exits non-zero; every wait is bounded.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>

#include <horus/depth_image.hpp>
#include <horus/image.hpp>
#include <horus/node.hpp>
#include <horus/point_cloud.hpp>
#include <horus/scheduler.hpp>
#include <horus/topic.hpp>
#include <iostream>
#include <memory>
#include <thread>
#include <vector>

namespace {

using namespace std::chrono_literals;
constexpr auto kWait = 30s;

std::uint8_t image_byte(std::size_t i) { return static_cast<std::uint8_t>(i * 7 + i / 4099); }
float depth_at(std::uint32_t x, std::uint32_t y) {
  return 0.25F + static_cast<float>(x) * 0.001F + static_cast<float>(y) * 0.0001F;
}
std::uint16_t depth_mm_at(std::uint32_t x, std::uint32_t y) {
  return static_cast<std::uint16_t>(300 + x + 2 * y);
}
float point_value(std::size_t i, int field) {
  switch (field) {
    case 0:
      return static_cast<float>(i);
    case 1:
      return static_cast<float>(i) * 0.5F;
    default:
      return -static_cast<float>(i % 1000);
  }
}

int fail(const char* what) {
  std::fprintf(stderr, "pool_peer: %s\n", what);
  return 1;
}

horus::Image rgb_frame() {
  horus::Image image = horus::Image::make(1080, 1920, horus::ImageEncoding::Rgb8);
  auto bytes = image.data_mut();
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = image_byte(i);
  return image;
}

/// Whether `image` is the 1080p frame of the formula, read in place in the pool.
bool is_rgb_frame(const horus::Image& image) {
  if (image.width() != 1920 || image.height() != 1080 ||
      image.encoding() != horus::ImageEncoding::Rgb8 ||
      !image.pool().contains(image.data().data())) {
    return false;
  }
  const auto bytes = image.data();
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    if (bytes[i] != image_byte(i)) return false;
  }
  return true;
}

/// Publishes one frame a tick until `count` are out, keeping the blocks it sent.
class CameraNode : public horus::Node {
 public:
  CameraNode(std::string topic, int count)
      : topic_name_(std::move(topic)), out_(topic_name_), count_(count) {}
  std::string_view name() const override { return "cpp_camera"; }
  void tick() override {
    if (done()) return;
    horus::Image image = rgb_frame();
    image.set_frame_id("cpp");
    image.set_timestamp_ns(blocks_.size() + 1);
    if (!out_.send(image)) failed_ = true;
    blocks_.push_back(image.block());
  }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{topic_name_, std::string(horus::TypeInfo<horus::Image>::name)}};
  }
  bool done() const { return blocks_.size() >= static_cast<std::size_t>(count_); }
  bool failed() const { return failed_; }
  const std::vector<horus::msg::PoolBlock>& blocks() const { return blocks_; }

 private:
  std::string topic_name_;
  horus::Topic<horus::Image> out_;
  int count_;
  bool failed_ = false;
  std::vector<horus::msg::PoolBlock> blocks_;
};

/// Checks every image it receives; keeps their timestamps.
class ViewerNode : public horus::Node {
 public:
  explicit ViewerNode(std::string topic) : topic_name_(std::move(topic)), in_(topic_name_) {}
  std::string_view name() const override { return "cpp_viewer"; }
  void tick() override {
    while (std::optional<horus::Image> image = in_.try_recv()) {
      if (!is_rgb_frame(*image) || image->frame_id() != "python") bad_ = true;
      timestamps_.push_back(image->timestamp_ns());
    }
  }
  std::vector<horus::TopicMetadata> subscribers() const override {
    return {{topic_name_, std::string(horus::TypeInfo<horus::Image>::name)}};
  }
  bool bad() const { return bad_; }
  const std::vector<std::uint64_t>& timestamps() const { return timestamps_; }

 private:
  std::string topic_name_;
  horus::Topic<horus::Image> in_;
  bool bad_ = false;
  std::vector<std::uint64_t> timestamps_;
};

horus::SchedulerConfig quiet_config() { return horus::SchedulerConfig{}.handle_signals(false); }

int node_send(const std::string& topic, int count) {
  auto camera = std::make_shared<CameraNode>(topic, count);
  std::vector<horus::msg::PoolBlock> blocks;
  {
    horus::Scheduler sched(quiet_config());
    sched.add(camera).order(0).build();
    std::printf("open\n");
    std::fflush(stdout);
    std::string line;
    if (!std::getline(std::cin, line)) return fail("no ready");
    while (!camera->done()) sched.tick_once();
    if (camera->failed()) return fail("send failed");
    blocks = camera->blocks();
    // The topic's ring holds the frames until the receiver is done and the node is gone.
    if (!std::getline(std::cin, line)) return fail("no done");
  }
  camera.reset();
  std::uint64_t references = 0;
  for (const auto& block : blocks) references += horus::default_pool().references(block);
  std::printf("references %llu\n", static_cast<unsigned long long>(references));
  return 0;
}

int node_recv(const std::string& topic, int count) {
  auto viewer = std::make_shared<ViewerNode>(topic);
  horus::Scheduler sched(quiet_config());
  sched.add(viewer).order(0).build();
  sched.tick_once();  // opens the subscription before the sender is told to start
  std::printf("ready\n");
  std::fflush(stdout);
  const auto deadline = std::chrono::steady_clock::now() + kWait;
  while (viewer->timestamps().size() < static_cast<std::size_t>(count) &&
         std::chrono::steady_clock::now() < deadline) {
    sched.tick_once();
    std::this_thread::sleep_for(1ms);
  }
  if (viewer->bad()) return fail("a received image differs");
  for (std::uint64_t timestamp : viewer->timestamps()) {
    std::printf("%llu\n", static_cast<unsigned long long>(timestamp));
  }
  return viewer->timestamps().size() == static_cast<std::size_t>(count) ? 0 : fail("too few");
}

template <class T>
int send(const std::string& topic_name, const T& value) {
  horus::Topic<T> topic(topic_name);
  std::printf("open\n");
  std::fflush(stdout);
  std::string line;
  if (!std::getline(std::cin, line)) return fail("no ready");
  if (!topic.send(value)) return fail("send failed");
  // The frame stays alive while this handle is open: until the receiver is done with it.
  if (!std::getline(std::cin, line)) return fail("no done");
  return 0;
}

int send_kind(const std::string& kind, const std::string& topic) {
  if (kind == "image") {
    horus::Image image = rgb_frame();
    image.set_frame_id("cpp");
    return send(topic, image);
  }
  if (kind == "depth") {
    horus::DepthImage depth = horus::DepthImage::meters(720, 1280);
    for (std::uint32_t y = 0; y < 720; ++y) {
      for (std::uint32_t x = 0; x < 1280; ++x) depth.set_depth(x, y, depth_at(x, y));
    }
    return send(topic, depth);
  }
  if (kind == "depth_mm") {
    horus::DepthImage depth = horus::DepthImage::millimeters(720, 1280);
    auto bytes = depth.data_mut();
    for (std::uint32_t y = 0; y < 720; ++y) {
      for (std::uint32_t x = 0; x < 1280; ++x) {
        const std::uint16_t millimetres = depth_mm_at(x, y);
        std::memcpy(bytes.data() + (std::size_t{y} * 1280 + x) * 2, &millimetres, 2);
      }
    }
    return send(topic, depth);
  }
  horus::PointCloud cloud = horus::PointCloud::make(1'000'000, 3, horus::msg::TensorDtype::F32);
  auto bytes = cloud.data_mut();
  for (std::size_t i = 0; i < 1'000'000; ++i) {
    for (int field = 0; field < 3; ++field) {
      const float value = point_value(i, field);
      std::memcpy(bytes.data() + (i * 3 + field) * sizeof(float), &value, sizeof value);
    }
  }
  return send(topic, cloud);
}

template <class T>
std::optional<T> receive(const std::string& topic_name) {
  horus::Topic<T> topic(topic_name);
  std::printf("ready\n");
  std::fflush(stdout);
  std::optional<T> value = topic.recv(kWait);
  if (value && !value->pool().contains(value->data().data())) {
    std::fprintf(stderr, "pool_peer: the data is not in the pool\n");
    return std::nullopt;
  }
  return value;
}

int recv_kind(const std::string& kind, const std::string& topic) {
  if (kind == "image") {
    std::optional<horus::Image> image = receive<horus::Image>(topic);
    if (!image) return fail("no image");
    if (!is_rgb_frame(*image)) return fail("wrong geometry or pixels");
    return image->frame_id() == "python" ? 0 : fail("wrong frame id");
  }
  if (kind == "depth") {
    std::optional<horus::DepthImage> depth = receive<horus::DepthImage>(topic);
    if (!depth) return fail("no depth image");
    if (!depth->is_meters() || depth->width() != 1280 || depth->height() != 720) {
      return fail("wrong geometry");
    }
    for (std::uint32_t y = 0; y < 720; ++y) {
      for (std::uint32_t x = 0; x < 1280; ++x) {
        if (std::fabs(*depth->get_depth(x, y) - depth_at(x, y)) > 1e-6F) return fail("depth");
      }
    }
    return 0;
  }
  if (kind == "depth_mm") {
    std::optional<horus::DepthImage> depth = receive<horus::DepthImage>(topic);
    if (!depth) return fail("no depth image");
    if (!depth->is_millimeters() || depth->width() != 1280 || depth->height() != 720) {
      return fail("wrong geometry");
    }
    for (std::uint32_t y = 0; y < 720; ++y) {
      for (std::uint32_t x = 0; x < 1280; ++x) {
        if (depth->get_depth_u16(x, y) != depth_mm_at(x, y)) return fail("depth");
      }
    }
    return 0;
  }
  std::optional<horus::PointCloud> cloud = receive<horus::PointCloud>(topic);
  if (!cloud) return fail("no cloud");
  if (cloud->point_count() != 1'000'000 || !cloud->is_xyz()) return fail("wrong geometry");
  for (std::size_t i = 0; i < 1'000'000; ++i) {
    float xyz[3];
    std::memcpy(xyz, cloud->point_at(i)->data(), sizeof xyz);
    for (int field = 0; field < 3; ++field) {
      if (xyz[field] != point_value(i, field)) return fail("wrong point");
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  const bool node = mode == "node-send" || mode == "node-recv";
  if (argc != (node ? 5 : 4)) {
    return fail(
        "usage: pool_peer send|recv image|depth|depth_mm|cloud <topic>, or node-send|node-recv "
        "image <topic> <count>");
  }
  try {
    if (node) {
      const int count = std::atoi(argv[4]);
      if (std::string_view(argv[2]) != "image" || count <= 0) return fail("bad kind or count");
      return mode == "node-send" ? node_send(argv[3], count) : node_recv(argv[3], count);
    }
    return mode == "send" ? send_kind(argv[2], argv[3]) : recv_kind(argv[2], argv[3]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pool_peer: %s\n", e.what());
    return 2;
  }
}
