// The tf2 side of the frames benchmark (tf2_side.hpp says why it is a C++17 file of its own).
#include "tf2_side.hpp"

#include <tf2/buffer_core.h>
#include <tf2/exceptions.h>

#include <stdexcept>

namespace frames_bench {

struct Tf2Buffer::Impl {
  tf2::BufferCore buffer;
  explicit Impl(double cache_seconds) : buffer(ros::Duration(cache_seconds)) {}
};

Tf2Buffer::Tf2Buffer(double cache_seconds) : impl_(std::make_unique<Impl>(cache_seconds)) {}
Tf2Buffer::~Tf2Buffer() = default;

void Tf2Buffer::set(const std::string& parent, const std::string& child, std::uint64_t stamp_ns,
                    const double translation[3], const double rotation[4], bool is_static) {
  geometry_msgs::TransformStamped message;
  message.header.stamp.fromNSec(stamp_ns);
  message.header.frame_id = parent;
  message.child_frame_id = child;
  message.transform.translation.x = translation[0];
  message.transform.translation.y = translation[1];
  message.transform.translation.z = translation[2];
  message.transform.rotation.x = rotation[0];
  message.transform.rotation.y = rotation[1];
  message.transform.rotation.z = rotation[2];
  message.transform.rotation.w = rotation[3];
  if (!impl_->buffer.setTransform(message, "frames_bench", is_static)) {
    throw std::runtime_error("tf2 refused " + parent + " <- " + child);
  }
}

Tf2Answer Tf2Buffer::lookup(const std::string& target, const std::string& source,
                            std::uint64_t stamp_ns) const {
  ros::Time time;
  time.fromNSec(stamp_ns);
  geometry_msgs::TransformStamped answer;
  try {
    answer = impl_->buffer.lookupTransform(target, source, time);
  } catch (const tf2::TransformException& error) {
    throw std::runtime_error(std::string("tf2: ") + error.what());
  }
  const auto& t = answer.transform;
  return {{t.translation.x, t.translation.y, t.translation.z},
          {t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w},
          answer.header.stamp.toNSec()};
}

}  // namespace frames_bench
