// horus-soak: the whole runtime at once for a long time. Publisher, subscriber, service server,
// service client and scheduler processes run on one namespace while a killer sends kill -9 to a
// random one every few hundred milliseconds and restarts it. At the end every process is asked
// to stop, and the figures are checked:
//
//   delivered, gaps (sequence numbers a subscriber never saw) and lost (what the topics counted):
//     every gap is counted, by a lapped ring or by a publisher killed between reserving a
//     sequence number and sending it, so gaps <= lost + publisher kills x subscribers;
//   torn and out-of-order messages: 0;
//   service calls: answered right, or failed with NoServer / Transport / Timeout (the server
//     was killed); wrong answers 0, and no call outlives its timeout by more than a second;
//   stuck processes (did not stop within 5 s when asked): 0;
//   the namespace's /dev/shm entries after clean_namespace(): 0.
//
//   horus_soak [--seconds S] [--publishers N] [--subscribers M] [--clients C] [--seed X]
// Defaults: 600 s, 3 publishers, 3 subscribers, 3 clients. Exit status 0 when every check held.
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <new>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <horus/detail/shm_segment.hpp>
#include <horus/scheduler.hpp>
#include <horus/service.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <service_test/compute.hpp>
#include <topic_test/blob.hpp>
#include <topic_test/sample.hpp>

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using service_test::Compute;
using service_test::ComputeRequest;
using service_test::ComputeResponse;
using topic_test::Blob;
using topic_test::Sample;

constexpr const char* kPodTopics[] = {"soak.pod.0", "soak.pod.1"};
constexpr const char* kBlobTopic = "soak.blob";
constexpr std::size_t kTopicCount = 3;
constexpr std::size_t kMaxPublishers = 16;
constexpr std::size_t kMaxProcesses = 64;
constexpr auto kCallTimeout = 2s;
/// A publisher's sequence numbers carry its id in the top bits.
constexpr int kPublisherShift = 48;

/// Counters of one process slot, in memory shared by the supervisor and every child (forked, so
/// they survive kill -9 and restarts).
struct SlotStats {
  /// Publishers: the next sequence number, reserved before each send so a restart goes on.
  std::atomic<std::uint64_t> next_seq;
  std::atomic<std::uint64_t> sent;
  std::atomic<std::uint64_t> delivered;
  std::atomic<std::uint64_t> gaps;
  std::atomic<std::uint64_t> lost;
  std::atomic<std::uint64_t> torn;
  std::atomic<std::uint64_t> out_of_order;
  std::atomic<std::uint64_t> calls_ok;
  std::atomic<std::uint64_t> calls_wrong;
  std::atomic<std::uint64_t> calls_no_server;
  std::atomic<std::uint64_t> calls_transport;
  std::atomic<std::uint64_t> calls_timeout;
  std::atomic<std::uint64_t> calls_failed;
  std::atomic<std::uint64_t> calls_overdue;
  std::atomic<std::uint64_t> event_ticks;
};

struct Shared {
  std::atomic<bool> stop;
  SlotStats slots[kMaxProcesses];
};

Shared* shared = nullptr;

bool stopping() { return shared->stop.load(std::memory_order_relaxed); }

// ---- Message content: every byte follows from the sequence number ------------------------------

std::uint64_t checksum(const Sample& msg) {
  std::uint64_t sum = 0xcbf29ce484222325ULL ^ msg.seq;
  for (const auto byte : msg.payload) {
    sum = (sum ^ byte) * 0x100000001b3ULL;
  }
  return sum;
}

Sample make_sample(std::uint64_t seq) {
  Sample msg{};
  msg.seq = seq;
  for (std::size_t i = 0; i < msg.payload.size(); ++i) {
    msg.payload[i] = static_cast<std::uint8_t>(seq * 31 + i);
  }
  msg.checksum = checksum(msg);
  return msg;
}

Blob make_blob(std::uint64_t seq) {
  Blob blob;
  blob.seq = seq;
  blob.text = std::string(seq % 40, static_cast<char>('a' + seq % 26));
  blob.data.assign(seq % 700, static_cast<std::uint8_t>(seq));
  if (seq % 3 == 0) {
    blob.note = std::to_string(seq);
  }
  return blob;
}

bool intact(const Sample& msg) { return msg.checksum == checksum(msg); }
bool intact(const Blob& blob) { return blob == make_blob(blob.seq); }

// ---- Roles
// ---------------------------------------------------------------------------------------

/// Sends on every topic in turn, forever (until asked to stop).
void publisher(std::size_t slot, std::size_t id) {
  SlotStats& stats = shared->slots[slot];
  horus::Topic<Sample> pod0(kPodTopics[0]);
  horus::Topic<Sample> pod1(kPodTopics[1]);
  horus::Topic<Blob> blobs(kBlobTopic);
  const std::uint64_t base = std::uint64_t{id} << kPublisherShift;
  while (!stopping()) {
    const std::uint64_t n = stats.next_seq.fetch_add(1, std::memory_order_relaxed);
    const std::uint64_t seq = base | n;
    const bool sent = n % kTopicCount == 0   ? pod0.send(make_sample(seq))
                      : n % kTopicCount == 1 ? pod1.send(make_sample(seq))
                                             : blobs.send(make_blob(seq));
    stats.sent.fetch_add(sent ? 1 : 0, std::memory_order_relaxed);
    std::this_thread::sleep_for(100us);
  }
}

/// Receives one topic, checking every message and the sequence of every publisher.
template <class Msg>
void subscribe(std::size_t slot, const char* name) {
  SlotStats& stats = shared->slots[slot];
  horus::Topic<Msg> topic(name);
  std::map<std::uint64_t, std::uint64_t> last;
  std::uint64_t lost_seen = 0;
  std::uint64_t invalid_seen = 0;
  while (!stopping()) {
    const std::optional<Msg> msg = topic.recv(10ms);
    stats.lost.fetch_add(topic.lost() - lost_seen, std::memory_order_relaxed);
    lost_seen = topic.lost();
    stats.torn.fetch_add(topic.stats().invalid - invalid_seen, std::memory_order_relaxed);
    invalid_seen = topic.stats().invalid;
    if (!msg) {
      continue;
    }
    stats.delivered.fetch_add(1, std::memory_order_relaxed);
    if (!intact(*msg)) {
      stats.torn.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    const std::uint64_t publisher = msg->seq >> kPublisherShift;
    // Each publisher spreads its numbers over the topics: this one sees every third.
    const std::uint64_t n = (msg->seq & ((std::uint64_t{1} << kPublisherShift) - 1)) / kTopicCount;
    const auto found = last.find(publisher);
    if (found != last.end()) {
      if (n <= found->second) {
        stats.out_of_order.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      stats.gaps.fetch_add(n - found->second - 1, std::memory_order_relaxed);
    }
    last[publisher] = n;
  }
}

void subscriber(std::size_t slot, std::size_t id) {
  if (id % kTopicCount == 2) {
    subscribe<Blob>(slot, kBlobTopic);
  } else {
    subscribe<Sample>(slot, kPodTopics[id % kTopicCount]);
  }
}

void server(std::size_t) {
  horus::ServiceServer<Compute> serving =
      horus::ServiceServerBuilder<Compute>()
          .on_request([](const ComputeRequest& req) {
            return ComputeResponse{req.a + req.b, static_cast<std::uint32_t>(::getpid())};
          })
          .build();
  while (!stopping()) {
    std::this_thread::sleep_for(10ms);
  }
}

void client(std::size_t slot, std::size_t id) {
  SlotStats& stats = shared->slots[slot];
  horus::ServiceClient<Compute> compute;
  for (std::int64_t i = 0; !stopping(); ++i) {
    const std::int64_t a = static_cast<std::int64_t>(id) * 1'000'000'000 + i;
    const Clock::time_point start = Clock::now();
    const horus::ServiceResult<ComputeResponse> sum = compute.call({a, i, 0, 0}, kCallTimeout);
    if (Clock::now() - start > kCallTimeout + 1s) {
      stats.calls_overdue.fetch_add(1, std::memory_order_relaxed);
    }
    if (sum) {
      (sum->sum == a + i ? stats.calls_ok : stats.calls_wrong).fetch_add(1);
      // Concurrent clients, not a benchmark: leave the machine's cores to the others too.
      std::this_thread::sleep_for(100us);
      continue;
    }
    switch (sum.error().kind()) {
      case horus::ServiceErrorKind::NoServer:
        stats.calls_no_server.fetch_add(1, std::memory_order_relaxed);
        std::this_thread::sleep_for(5ms);
        break;
      case horus::ServiceErrorKind::Transport:
        stats.calls_transport.fetch_add(1, std::memory_order_relaxed);
        std::this_thread::sleep_for(5ms);
        break;
      case horus::ServiceErrorKind::Timeout:
        stats.calls_timeout.fetch_add(1, std::memory_order_relaxed);
        break;
      case horus::ServiceErrorKind::ServiceFailed:
        stats.calls_failed.fetch_add(1, std::memory_order_relaxed);
        break;
    }
  }
}

/// An event node: ticked once per message of the first POD topic.
class CountingNode : public horus::Node {
 public:
  explicit CountingNode(SlotStats& stats) : stats_(stats), topic_(kPodTopics[0]) {}
  std::string_view name() const override { return "soak_counter"; }
  void tick() override {
    stats_.event_ticks.fetch_add(1, std::memory_order_relaxed);
    while (const std::optional<Sample> msg = topic_.try_recv()) {
      stats_.delivered.fetch_add(1, std::memory_order_relaxed);
      stats_.torn.fetch_add(intact(*msg) ? 0 : 1, std::memory_order_relaxed);
    }
  }

 private:
  SlotStats& stats_;
  horus::Topic<Sample> topic_;
};

void scheduler(std::size_t slot) {
  horus::Scheduler sched;
  sched.add(std::make_shared<CountingNode>(shared->slots[slot])).on(kPodTopics[0]).build();
  std::thread watcher([&sched] {
    while (!stopping()) {
      std::this_thread::sleep_for(10ms);
    }
    sched.stop();
  });
  sched.run();
  watcher.join();
}

// ---- The supervisor
// ------------------------------------------------------------------------------

enum class Role { publisher, subscriber, server, client, scheduler };

const char* role_name(Role role) {
  switch (role) {
    case Role::publisher:
      return "publisher";
    case Role::subscriber:
      return "subscriber";
    case Role::server:
      return "server";
    case Role::client:
      return "client";
    case Role::scheduler:
      return "scheduler";
  }
  return "?";
}

struct Process {
  Role role;
  std::size_t id;
  pid_t pid = -1;
  std::uint64_t kills = 0;
};

pid_t start(std::size_t slot, const Process& process) {
  const pid_t pid = ::fork();
  if (pid != 0) {
    return pid;
  }
  int status = 0;
  try {
    switch (process.role) {
      case Role::publisher:
        publisher(slot, process.id);
        break;
      case Role::subscriber:
        subscriber(slot, process.id);
        break;
      case Role::server:
        server(slot);
        break;
      case Role::client:
        client(slot, process.id);
        break;
      case Role::scheduler:
        scheduler(slot);
        break;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s %zu: %s\n", role_name(process.role), process.id, e.what());
    status = 1;
  }
  ::_exit(status);
}

/// Waits for a child that was asked to stop; false when it had to be killed.
bool reap(pid_t pid, Clock::duration patience) {
  const Clock::time_point deadline = Clock::now() + patience;
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (Clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
      return false;
    }
    std::this_thread::sleep_for(5ms);
  }
  return true;
}

struct Options {
  double seconds = 600;
  std::size_t publishers = 3;
  std::size_t subscribers = 3;
  std::size_t clients = 3;
  std::uint64_t seed = 1;
};

bool parse(int argc, char** argv, Options& options) {
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    const std::string value = argv[i + 1];
    if (flag == "--seconds") {
      options.seconds = std::stod(value);
    } else if (flag == "--publishers") {
      options.publishers = std::stoul(value);
    } else if (flag == "--subscribers") {
      options.subscribers = std::stoul(value);
    } else if (flag == "--clients") {
      options.clients = std::stoul(value);
    } else if (flag == "--seed") {
      options.seed = std::stoull(value);
    } else {
      return false;
    }
  }
  return argc % 2 == 1 && options.publishers >= 1 && options.publishers <= kMaxPublishers &&
         options.subscribers >= 1 &&
         options.publishers + options.subscribers + options.clients + 2 <= kMaxProcesses;
}

std::uint64_t total(const std::vector<Process>& processes,
                    std::atomic<std::uint64_t> SlotStats::*counter) {
  std::uint64_t sum = 0;
  for (std::size_t slot = 0; slot < processes.size(); ++slot) {
    sum += (shared->slots[slot].*counter).load();
  }
  return sum;
}

std::uint64_t kills_of(const std::vector<Process>& processes, Role role) {
  std::uint64_t sum = 0;
  for (const Process& process : processes) {
    sum += process.role == role ? process.kills : 0;
  }
  return sum;
}

int check(bool held, const char* what) {
  std::printf("  %-58s %s\n", what, held ? "ok" : "FAILED");
  return held ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  if (!parse(argc, argv, options)) {
    std::fprintf(stderr,
                 "usage: horus_soak [--seconds S] [--publishers N<=16] [--subscribers M] "
                 "[--clients C] [--seed X]\n");
    return 2;
  }
  void* memory =
      ::mmap(nullptr, sizeof(Shared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (memory == MAP_FAILED) {
    std::perror("mmap");
    return 2;
  }
  shared = new (memory) Shared{};
  const std::string ns = "soak_" + std::to_string(::getpid());
  ::setenv("HORUS_NAMESPACE", ns.c_str(), 1);

  std::vector<Process> processes;
  for (std::size_t i = 0; i < options.publishers; ++i) {
    processes.push_back({Role::publisher, i});
  }
  for (std::size_t i = 0; i < options.subscribers; ++i) {
    processes.push_back({Role::subscriber, i});
  }
  processes.push_back({Role::server, 0});
  for (std::size_t i = 0; i < options.clients; ++i) {
    processes.push_back({Role::client, i});
  }
  processes.push_back({Role::scheduler, 0});
  for (std::size_t slot = 0; slot < processes.size(); ++slot) {
    processes[slot].pid = start(slot, processes[slot]);
  }

  std::mt19937_64 random(options.seed);
  std::uniform_int_distribution<int> pause_ms(100, 600);
  std::uniform_int_distribution<std::size_t> victim(0, processes.size() - 1);
  const Clock::time_point end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                   std::chrono::duration<double>(options.seconds));
  std::uint64_t crashed = 0;
  while (Clock::now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(pause_ms(random)));
    Process& process = processes[victim(random)];
    ::kill(process.pid, SIGKILL);
    int status = 0;
    ::waitpid(process.pid, &status, 0);
    // A child that exited on its own before the kill failed.
    crashed += WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL ? 0 : 1;
    ++process.kills;
    process.pid = start(static_cast<std::size_t>(&process - processes.data()), process);
  }

  shared->stop.store(true);
  std::uint64_t stuck = 0;
  for (const Process& process : processes) {
    stuck += reap(process.pid, 5s) ? 0 : 1;
  }
  horus::clean_namespace(ns);
  const bool shm_left = std::filesystem::exists(horus::detail::namespace_directory(ns));

  const std::uint64_t delivered = total(processes, &SlotStats::delivered);
  const std::uint64_t gaps = total(processes, &SlotStats::gaps);
  const std::uint64_t lost = total(processes, &SlotStats::lost);
  const std::uint64_t publisher_kills = kills_of(processes, Role::publisher);
  std::printf("horus_soak: %.0f s, %zu publishers, %zu subscribers, %zu clients, seed %llu\n",
              options.seconds, options.publishers, options.subscribers, options.clients,
              static_cast<unsigned long long>(options.seed));
  for (const Role role :
       {Role::publisher, Role::subscriber, Role::server, Role::client, Role::scheduler}) {
    std::printf("  kill -9 of %-10s %8llu\n", role_name(role),
                static_cast<unsigned long long>(kills_of(processes, role)));
  }
  const auto figure = [](const char* what, std::uint64_t value) {
    std::printf("  %-28s %12llu\n", what, static_cast<unsigned long long>(value));
  };
  figure("messages sent", total(processes, &SlotStats::sent));
  figure("messages delivered", delivered);
  figure("sequence gaps", gaps);
  figure("lost (counted by topics)", lost);
  figure("torn", total(processes, &SlotStats::torn));
  figure("out of order", total(processes, &SlotStats::out_of_order));
  figure("event node ticks", total(processes, &SlotStats::event_ticks));
  figure("calls answered right", total(processes, &SlotStats::calls_ok));
  figure("calls answered wrong", total(processes, &SlotStats::calls_wrong));
  figure("calls failed: NoServer", total(processes, &SlotStats::calls_no_server));
  figure("calls failed: Transport", total(processes, &SlotStats::calls_transport));
  figure("calls failed: Timeout", total(processes, &SlotStats::calls_timeout));
  figure("calls failed: ServiceFailed", total(processes, &SlotStats::calls_failed));
  figure("calls overdue (> timeout+1s)", total(processes, &SlotStats::calls_overdue));
  figure("children that died unasked", crashed);
  figure("stuck processes", stuck);

  int failures = 0;
  failures += check(delivered > 0, "messages were delivered");
  failures += check(gaps <= lost + publisher_kills * options.subscribers,
                    "every gap is counted (gaps <= lost + publisher kills x subscribers)");
  failures += check(total(processes, &SlotStats::torn) == 0, "no torn message");
  failures += check(total(processes, &SlotStats::out_of_order) == 0, "no message out of order");
  failures += check(total(processes, &SlotStats::calls_ok) > 0, "calls were answered");
  failures += check(total(processes, &SlotStats::calls_wrong) == 0, "no call answered wrong");
  failures += check(total(processes, &SlotStats::calls_failed) == 0,
                    "no call failed as ServiceFailed (the handler never fails)");
  failures +=
      check(total(processes, &SlotStats::calls_overdue) == 0, "no call outlived its timeout");
  failures += check(total(processes, &SlotStats::event_ticks) > 0, "the event node ticked");
  failures += check(crashed == 0, "no child died unasked");
  failures += check(stuck == 0, "every process stopped when asked");
  failures += check(!shm_left, "nothing left in /dev/shm after clean_namespace()");
  return failures == 0 ? 0 : 1;
}
