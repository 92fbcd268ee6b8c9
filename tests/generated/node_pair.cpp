// A real two-node program declared by tests/schemas/test_nodes/{talker,listener}.hnode: the
// talker publishes poses at 200 Hz, the listener (an event node) echoes each one. It prints
// "ready" once the listener has received a pose (both nodes are then initialised and announced
// in the presence registry), and runs until its standard input closes.
//
//   horus_node_pair
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <thread>

#include "horus/scheduler.hpp"
#include "test_nodes.hpp"

namespace {

class Talker : public test_nodes::TalkerBase {
 public:
  void tick() override {
    test_msgs::Pose2 pose{};
    pose.position.x = step_ * static_cast<double>(++sent_);
    pose_.send(pose);
  }
};

class Listener : public test_nodes::ListenerBase {
 public:
  void tick() override {
    while (auto pose = pose_.try_recv()) {
      echo_.send(pose->position);
      if (++received_ == 1) {
        std::printf("ready\n");
        std::fflush(stdout);
      }
    }
  }
};

}  // namespace

int main() {
  horus::Scheduler sched{horus::SchedulerConfig{}.name("node_pair")};
  test_nodes::TalkerBase::add_to(sched, std::make_shared<Talker>()).build();
  test_nodes::ListenerBase::add_to(sched, std::make_shared<Listener>()).build();
  // The test holds stdin open while it looks at the running program; end of input stops it.
  // Detached: when the scheduler stops on its own, main returns without waiting for input.
  std::thread([&sched] {
    std::string line;
    while (std::getline(std::cin, line)) {
    }
    sched.stop();
  }).detach();
  return sched.run();
}
