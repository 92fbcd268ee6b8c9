// The talker and the listener of talker.hnode and listener.hnode, written as a user writes them
// (tick() only, the rest is generated): shared by the node test and the two-node program.
#pragma once

#include <cstddef>
#include <cstdint>

#include "test_nodes/listener.hpp"
#include "test_nodes/talker.hpp"

namespace test_nodes_user {

/// Publishes poses at x = step, 2 * step, ...
class Talker : public test_nodes::TalkerBase {
 public:
  void tick() override {
    test_msgs::Pose2 pose{};
    pose.position.x = step_ * static_cast<double>(++sent_);
    pose_.send(pose);
  }
  std::uint64_t sent() const { return sent_; }
  double step() const { return step_; }
};

/// Ticks on each pose and echoes its position.
class Listener : public test_nodes::ListenerBase {
 public:
  void tick() override {
    while (auto pose = pose_.try_recv()) {
      ++received_;
      last_x_ = pose->position.x;
      echo_.send(pose->position);
    }
  }
  std::uint64_t received() const { return received_; }
  double last_x() const { return last_x_; }
  std::size_t pose_capacity() const { return pose_.capacity(); }

 private:
  double last_x_ = 0.0;
};

}  // namespace test_nodes_user
