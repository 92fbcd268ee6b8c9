// The C++ side of the Python pool tests (test_runtime_pool.py): sends or receives one Image
// (1080p RGB), DepthImage (720p metres) or PointCloud (a million XYZ points) whose every value
// follows a formula both languages compute.
//   pool_peer send <image|depth|cloud> <topic>: prints "open", waits for a line on stdin, sends,
//     and keeps the frame alive until the next line (the receiver is done)
//   pool_peer recv <image|depth|cloud> <topic>: opens the topic, prints "ready", receives,
//     checks, exits 0
// It prints what went wrong on stderr and exits non-zero; every wait is bounded.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>

#include <horus/depth_image.hpp>
#include <horus/image.hpp>
#include <horus/point_cloud.hpp>
#include <horus/topic.hpp>
#include <iostream>

namespace {

using namespace std::chrono_literals;
constexpr auto kWait = 30s;

std::uint8_t image_byte(std::size_t i) { return static_cast<std::uint8_t>(i * 7 + i / 4099); }
float depth_at(std::uint32_t x, std::uint32_t y) {
  return 0.25F + static_cast<float>(x) * 0.001F + static_cast<float>(y) * 0.0001F;
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
    horus::Image image = horus::Image::make(1080, 1920, horus::ImageEncoding::Rgb8);
    auto bytes = image.data_mut();
    for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = image_byte(i);
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
    if (image->width() != 1920 || image->height() != 1080 ||
        image->encoding() != horus::ImageEncoding::Rgb8) {
      return fail("wrong geometry");
    }
    const auto bytes = image->data();
    for (std::size_t i = 0; i < bytes.size(); ++i) {
      if (bytes[i] != image_byte(i)) return fail("wrong pixel");
    }
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
  if (argc != 4) return fail("usage: pool_peer send|recv image|depth|cloud <topic>");
  const std::string mode = argv[1];
  try {
    return mode == "send" ? send_kind(argv[2], argv[3]) : recv_kind(argv[2], argv[3]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pool_peer: %s\n", e.what());
    return 2;
  }
}
