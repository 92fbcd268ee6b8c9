// The talker of talker.hnode as both the node test and the two-node program write it.
#pragma once

#include <cstdint>

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

}  // namespace test_nodes_user
