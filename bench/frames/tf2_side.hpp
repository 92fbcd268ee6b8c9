// tf2::BufferCore behind a plain interface: Debian's libtf2-dev is ROS 1's tf2, whose message
// headers use std::allocator<void>::rebind (gone in C++20), so only tf2_side.cpp includes them,
// compiled as C++17; the C++20 benchmark sees no ROS type.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

namespace frames_bench {

/// A transform as tf2 gives it: translation (x, y, z), rotation (x, y, z, w), and its stamp.
struct Tf2Answer {
  double translation[3];
  double rotation[4];
  std::uint64_t stamp_ns;
};

class Tf2Buffer {
 public:
  /// A tf2::BufferCore keeping `cache_seconds` of history, as a ROS node's tf2 buffer does.
  explicit Tf2Buffer(double cache_seconds);
  ~Tf2Buffer();
  Tf2Buffer(const Tf2Buffer&) = delete;
  Tf2Buffer& operator=(const Tf2Buffer&) = delete;

  /// BufferCore::setTransform of one geometry_msgs::TransformStamped (what a /tf callback does).
  void set(const std::string& parent, const std::string& child, std::uint64_t stamp_ns,
           const double translation[3], const double rotation[4], bool is_static);
  /// BufferCore::lookupTransform(target, source, time); stamp 0: the latest common time.
  /// Throws std::runtime_error with tf2's message when tf2 cannot answer.
  Tf2Answer lookup(const std::string& target, const std::string& source,
                   std::uint64_t stamp_ns) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace frames_bench
