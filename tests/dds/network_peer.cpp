// A C++ program with SchedulerConfig::network(), for test_network_cpp.py:
//
//   horus_dds_network_peer export DOMAIN        publishes cmd_vel (CmdVel, stamp_nanos = i,
//                                               linear = i / 2) at 100 Hz, exported to DDS,
//                                               until SIGINT or SIGTERM; exits with run()'s
//                                               status
//   horus_dds_network_peer import DOMAIN COUNT  imports cmd_vel, prints "seen S1 S2 ..." (-1 for
//                                               altered content) after COUNT messages
//   horus_dds_network_peer options DOMAIN       every Network field set, runs until stopped
//   horus_dds_network_peer relay DOMAIN export|import|export-service|import-service PATTERN
//                                               a scheduler that only carries the topics (or
//                                               services) PATTERN names (types it was not
//                                               compiled with too), until SIGINT or SIGTERM
//   horus_dds_network_peer frames DOMAIN        sets odom -> base_link at (0, 0, 7) at 100 Hz and
//                                               carries every frame both ways (export_frames,
//                                               import_frames), until SIGINT or SIGTERM
//   horus_dds_network_peer invalid              one line "refused: MESSAGE" per invalid Network
//
// A Scheduler that cannot start its bridge prints "error: MESSAGE" and exits with 2; one that
// stopped prints "stopped: REASON" on stderr.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <horus/frames.hpp>
#include <horus/horus.hpp>
#include <horus/msg/cmd_vel.hpp>

namespace {

using namespace std::chrono_literals;
using horus::msg::CmdVel;

// Rings as deep as the Python side's (test_bridge.py): seconds of a stalled process on a loaded
// machine, so that the sequence check is about the bridge.
const horus::TopicOptions kRing{.capacity = 512};

class Talker : public horus::Node {
 public:
  std::string_view name() const override { return "talker"; }
  void tick() override {
    topic_.send(CmdVel{.stamp_nanos = sent_, .linear = 0.5F * static_cast<float>(sent_)});
    ++sent_;
  }

 private:
  horus::Topic<CmdVel> topic_{"cmd_vel", kRing};
  std::uint64_t sent_ = 0;
};

class Listener : public horus::Node {
 public:
  explicit Listener(std::size_t count) : count_(count) {}
  std::string_view name() const override { return "listener"; }
  void tick() override {
    while (seen_.size() < count_) {
      const auto message = topic_.try_recv();
      if (!message) break;
      const bool intact = message->linear == 0.5F * static_cast<float>(message->stamp_nanos);
      seen_.push_back(intact ? static_cast<std::int64_t>(message->stamp_nanos) : -1);
    }
    if (seen_.size() >= count_) request_stop();
  }
  const std::vector<std::int64_t>& seen() const { return seen_; }

 private:
  horus::Topic<CmdVel> topic_{"cmd_vel", kRing};
  std::size_t count_;
  std::vector<std::int64_t> seen_;
};

// Does nothing: the scheduler of `relay` has a node only because a scheduler runs nodes.
class Idle : public horus::Node {
 public:
  std::string_view name() const override { return "idle"; }
  void tick() override {}
};

// Sets base_link, whose authority this process (and so its scheduler's bridge) is.
class Odometry : public horus::Node {
 public:
  std::string_view name() const override { return "odometry"; }
  void tick() override {
    frames_.set_transform("odom", "base_link", {{0, 0, 7}, {}}, horus::now());
  }

 private:
  horus::FrameTree frames_;
};

int run(horus::Network network, const std::shared_ptr<horus::Node>& node) {
  horus::Scheduler scheduler{horus::SchedulerConfig{}
                                 .name("network_peer")
                                 .tick_rate(horus::Rate::hz(100.0))
                                 .network(std::move(network))};
  scheduler.add(node).rate(horus::Rate::hz(100.0)).build();
  const int status = scheduler.run();
  std::fprintf(stderr, "stopped: %s\n", scheduler.stop_reason().c_str());
  return status;
}

void refuse(const std::string& what, horus::Network network) {
  try {
    horus::Scheduler scheduler{horus::SchedulerConfig{}.network(std::move(network))};
    std::printf("accepted: %s\n", what.c_str());
  } catch (const horus::Error& e) {
    std::printf("refused: %s\n", e.what());
  }
}

int invalid() {
  refuse("nothing", {.domain = 3});
  refuse("domain", {.export_ = {"a"}, .domain = 233});
  refuse("negative domain", {.export_ = {"a"}, .domain = -1});
  refuse("depth", {.import_ = {"a"}, .depth = 0});
  refuse("deadline", {.export_ = {"a"}, .deadlines = {{"a", 0ms}}});
  refuse("empty pattern", {.export_ = {""}});
  refuse("service timeout", {.export_services = {"a"}, .service_timeout = 0s});
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  const std::string role = args.empty() ? "" : args[0];
  try {
    if (role == "export" && args.size() == 2) {
      return run({.export_ = {"cmd_vel"}, .domain = std::stoi(args[1]), .depth = 1000},
                 std::make_shared<Talker>());
    }
    if (role == "import" && args.size() == 3) {
      auto listener = std::make_shared<Listener>(std::stoul(args[2]));
      const int status =
          run({.import_ = {"cmd_vel"}, .domain = std::stoi(args[1]), .depth = 1000}, listener);
      std::printf("seen");
      for (const std::int64_t stamp : listener->seen())
        std::printf(" %lld", static_cast<long long>(stamp));
      std::printf("\n");
      return status;
    }
    if (role == "options" && args.size() == 2) {
      return run({.export_ = {"cmd_*", "-odd"},
                  .import_ = {"map"},
                  .domain = std::stoi(args[1]),
                  .reliable = false,
                  .depth = 7,
                  .transient_local = {"map"},
                  .deadlines = {{"cmd_*", 200ms}, {"map", 2s}},
                  .export_services = {"get_*"},
                  .import_services = {"plan"},
                  .service_timeout = 2500ms,
                  .ros2_types = {"cmd_vel"},
                  .accept_untyped_writers = true},
                 std::make_shared<Talker>());
    }
    if (role == "relay" && args.size() == 4) {
      horus::Network network{.domain = std::stoi(args[1]), .depth = 1000};
      const std::map<std::string, std::vector<std::string>*> kinds{
          {"export", &network.export_},
          {"import", &network.import_},
          {"export-service", &network.export_services},
          {"import-service", &network.import_services}};
      if (const auto kind = kinds.find(args[2]); kind != kinds.end()) {
        kind->second->push_back(args[3]);
        return run(std::move(network), std::make_shared<Idle>());
      }
    }
    if (role == "frames" && args.size() == 2) {
      return run({.domain = std::stoi(args[1]), .export_frames = {"*"}, .import_frames = {"*"}},
                 std::make_shared<Odometry>());
    }
    if (role == "invalid" && args.size() == 1) return invalid();
  } catch (const horus::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  std::fprintf(stderr,
               "usage: %s export DOMAIN | import DOMAIN COUNT | options DOMAIN | relay DOMAIN "
               "export|import|export-service|import-service PATTERN | frames DOMAIN | "
               "invalid\n",
               argv[0]);
  return 2;
}
