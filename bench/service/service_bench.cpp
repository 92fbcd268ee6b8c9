// Round-trip latency of a service call between two processes pinned to different cores, against
// the floor of any wake-up based request/response: a two-way futex ping-pong in the same run.
//
//   horus_service_bench [calls]      prints a Markdown table (p50, p99, mean, ratio to the floor)
//
// A third row, a bare request topic and reply topic, shows what the transport alone costs.
#include <linux/futex.h>
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <climits>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include <horus/service.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <service_test/compute.hpp>
#include <service_test/get_robot_pose.hpp>

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using service_test::Compute;
using service_test::ComputeRequest;
using service_test::ComputeResponse;
using service_test::GetRobotPose;
using service_test::GetRobotPoseRequest;
using service_test::GetRobotPoseResponse;

constexpr int kClientCore = 0;
constexpr int kServerCore = 1;
constexpr const char* kStopTopic = "bench.stop";
constexpr const char* kPingTopic = "bench.ping";
constexpr const char* kPongTopic = "bench.pong";
constexpr std::uint32_t kStopBehaviour = 99;

bool pin(int core) {
  if (static_cast<int>(::sysconf(_SC_NPROCESSORS_ONLN)) <= core) {
    return false;
  }
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(core, &set);
  return ::sched_setaffinity(0, sizeof set, &set) == 0;
}

struct Stats {
  double p50_us;
  double p99_us;
  double mean_us;
};

Stats summarize(std::vector<double>& samples) {
  std::sort(samples.begin(), samples.end());
  double sum = 0;
  for (const double s : samples) {
    sum += s;
  }
  const auto at = [&](double q) {
    return samples[std::min(samples.size() - 1,
                            static_cast<std::size_t>(q * static_cast<double>(samples.size())))];
  };
  return {at(0.50), at(0.99), sum / static_cast<double>(samples.size())};
}

/// One kind of round trip: runs one, returns false on a failure.
struct Contender {
  const char* label;
  std::function<bool(int)> round_trip;
  std::vector<double> samples;
};

/// Times every contender `calls` times, in interleaved blocks, so that whatever else runs on the
/// machine meanwhile weighs on all of them alike. Microseconds per round trip.
void measure(std::vector<Contender>& contenders, int calls) {
  constexpr int kBlocks = 40;
  const int per_block = std::max(1, calls / kBlocks);
  int sequence = 0;
  for (int block = 0; block < kBlocks; ++block) {
    for (Contender& contender : contenders) {
      for (int i = 0; i < per_block / 10 + 1; ++i) {
        if (!contender.round_trip(++sequence)) {
          std::fprintf(stderr, "%s: warm-up round trip failed\n", contender.label);
          std::exit(1);
        }
      }
      for (int i = 0; i < per_block; ++i) {
        const auto start = Clock::now();
        if (!contender.round_trip(++sequence)) {
          std::fprintf(stderr, "%s: round trip failed\n", contender.label);
          std::exit(1);
        }
        contender.samples.push_back(
            std::chrono::duration<double, std::micro>(Clock::now() - start).count());
      }
    }
  }
}

// ---- The floor: two processes waking each other through two futex words ----------------------

struct PingPong {
  std::atomic<std::uint32_t> ping;
  std::atomic<std::uint32_t> pong;
  std::atomic<std::uint32_t> stop;
};

void futex_wait(std::atomic<std::uint32_t>& word, std::uint32_t expected) {
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAIT, expected, nullptr,
          nullptr, 0);
}
void futex_wake(std::atomic<std::uint32_t>& word) {
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAKE, INT_MAX, nullptr, nullptr,
          0);
}

[[noreturn]] void futex_responder(PingPong& shared) {
  pin(kServerCore);
  std::uint32_t seen = 0;
  while (shared.stop.load(std::memory_order_acquire) == 0) {
    const std::uint32_t ping = shared.ping.load(std::memory_order_acquire);
    if (ping == seen) {
      futex_wait(shared.ping, seen);
      continue;
    }
    seen = ping;
    shared.pong.store(seen, std::memory_order_release);
    futex_wake(shared.pong);
  }
  ::_exit(0);
}

bool futex_round_trip(PingPong& shared, std::uint32_t sequence) {
  shared.ping.store(sequence, std::memory_order_release);
  futex_wake(shared.ping);
  for (;;) {
    const std::uint32_t pong = shared.pong.load(std::memory_order_acquire);
    if (pong == sequence) {
      return true;
    }
    futex_wait(shared.pong, pong);
  }
}

// ---- The transport alone: a request topic and a reply topic, no service layer ----------------

[[noreturn]] void topic_responder() {
  pin(kServerCore);
  horus::Topic<ComputeRequest> ping(kPingTopic);
  horus::Topic<ComputeResponse> pong(kPongTopic);
  for (;;) {
    const std::optional<ComputeRequest> request = ping.recv(600s);
    if (!request || request->behaviour == kStopBehaviour) {
      ::_exit(0);
    }
    pong.send(ComputeResponse{request->a + request->b, 0});
  }
}

// ---- Services ----------------------------------------------------------------------------------

[[noreturn]] void serve() {
  pin(kServerCore);
  horus::Topic<ComputeRequest> stop(kStopTopic);
  auto compute = horus::ServiceServerBuilder<Compute>()
                     .on_request([](const ComputeRequest& req) {
                       return ComputeResponse{req.a + req.b, 0};
                     })
                     .build();
  auto pose =
      horus::ServiceServerBuilder<GetRobotPose>()
          .on_request([](const GetRobotPoseRequest& req) {
            return GetRobotPoseResponse{static_cast<double>(req.robot_name.size()), 2.0, 0.5, 1};
          })
          .build();
  stop.recv(600s);
  compute.stop();
  pose.stop();
  ::_exit(0);
}

void print_row(const char* what, std::vector<double>& samples, const Stats& floor) {
  const Stats stats = summarize(samples);
  std::printf("| %s | %.1f | %.1f | %.1f | %.2fx | %.2fx |\n", what, stats.p50_us, stats.p99_us,
              stats.mean_us, stats.p50_us / floor.p50_us, stats.p99_us / floor.p99_us);
}

}  // namespace

int main(int argc, char** argv) {
  const int calls = argc > 1 ? std::atoi(argv[1]) : 20000;
  const std::string ns = "bench_service_" + std::to_string(::getpid());
  ::setenv("HORUS_NAMESPACE", ns.c_str(), 1);
  horus::remove_namespace(ns);

  void* memory =
      ::mmap(nullptr, sizeof(PingPong), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  auto* shared = new (memory) PingPong{};
  // Every handle is opened before the children start, so nothing sent is missed.
  horus::Topic<ComputeRequest> stop(kStopTopic);
  horus::Topic<ComputeRequest> ping(kPingTopic);
  horus::Topic<ComputeResponse> pong(kPongTopic);
  std::vector<pid_t> children;
  if (const pid_t child = ::fork(); child == 0) {
    futex_responder(*shared);
  } else {
    children.push_back(child);
  }
  if (const pid_t child = ::fork(); child == 0) {
    topic_responder();
  } else {
    children.push_back(child);
  }
  if (const pid_t child = ::fork(); child == 0) {
    serve();
  } else {
    children.push_back(child);
  }
  const bool pinned = pin(kClientCore);
  horus::ServiceClient<Compute> compute;
  horus::ServiceClient<GetRobotPose> pose;
  if (!compute.wait_for_server(10s) || !pose.wait_for_server(10s)) {
    std::fprintf(stderr, "the server process never registered\n");
    for (const pid_t child : children) {
      ::kill(child, SIGKILL);
    }
    return 1;
  }
  const GetRobotPoseRequest where{"arm_1"};
  std::vector<Contender> contenders;
  contenders.push_back(
      {"futex ping-pong (floor)",
       [&](int i) { return futex_round_trip(*shared, static_cast<std::uint32_t>(i)); },
       {}});
  contenders.push_back({"Topic request + reply topic (no service layer)",
                        [&](int i) {
                          ping.send(ComputeRequest{i, 1, 0, 0});
                          const std::optional<ComputeResponse> answer = pong.recv(1s);
                          return answer && answer->sum == i + 1;
                        },
                        {}});
  contenders.push_back({"Compute service (POD request and response)",
                        [&](int i) {
                          const auto sum = compute.call({i, 1, 0, 0}, 1s);
                          return sum && sum->sum == i + 1;
                        },
                        {}});
  contenders.push_back({"GetRobotPose service (serialized request)",
                        [&](int) {
                          const auto answer = pose.call(where, 1s);
                          return answer.has_value() && answer->x == 5.0;
                        },
                        {}});
  measure(contenders, calls);

  shared->stop.store(1, std::memory_order_release);
  shared->ping.fetch_add(1, std::memory_order_release);
  futex_wake(shared->ping);
  ping.send(ComputeRequest{0, 0, 0, kStopBehaviour});
  stop.send(ComputeRequest{});
  for (const pid_t child : children) {
    ::waitpid(child, nullptr, 0);
  }
  horus::remove_namespace(ns);

  const Stats floor = summarize(contenders.front().samples);
  std::printf("%d round trips each (in %s), client and responders %s.\n\n", calls,
              "40 interleaved blocks",
              pinned ? "pinned to cores 0 and 1" : "not pinned (fewer than 2 cores)");
  std::printf("| round trip | p50 (us) | p99 (us) | mean (us) | p50 / floor | p99 / floor |\n");
  std::printf("|---|---:|---:|---:|---:|---:|\n");
  for (Contender& contender : contenders) {
    print_row(contender.label, contender.samples, floor);
  }
  return 0;
}
