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
#include "pair_nodes.hpp"
#include "test_nodes.hpp"

namespace {

using test_nodes_user::Talker;

// Says "ready" once the first pose went through.
class Listener : public test_nodes_user::Listener {
 public:
  void tick() override {
    test_nodes_user::Listener::tick();
    if (!ready_ && received() > 0) {
      ready_ = true;
      std::printf("ready\n");
      std::fflush(stdout);
    }
  }

 private:
  bool ready_ = false;
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
