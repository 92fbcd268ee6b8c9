// horus-soak: the whole runtime at once for a long time. Publisher, subscriber, service server,
// service client and scheduler processes run on one namespace while a killer sends kill -9 to a
// random one every few hundred milliseconds and restarts it. Next to those, one "steady" process
// of each kind (a subscriber per topic, and a second server on a namespace of its own that every
// client also calls) is never killed: it lives through every restart of its peers, so a leak
// shows as its footprint growing. Every child advances a heartbeat when it makes progress; the
// supervisor names a live child whose heartbeat stood still too long (a hang). At the end every
// process is asked to stop, and the figures are checked:
//
//   delivered, gaps (sequence numbers a subscriber never saw) and lost (what the topics counted):
//     every gap is counted, by a lapped ring or by a publisher killed between reserving a
//     sequence number and sending it, so gaps <= lost + publisher kills x subscribers;
//   torn and out-of-order messages: 0;
//   service calls: answered right, or failed with NoServer / Transport / Timeout when the server
//     was the killed one; the steady server's calls never fail (counted apart); wrong answers 0,
//     and no call outlives its timeout by more than 5 s;
//   stuck processes (no progress for --stuck-seconds while alive, or did not stop within 5 s
//     when asked): 0; children that died unasked or ended with an error: 0;
//   steady processes: no growth of private memory, mappings, threads or descriptors between the
//     first and the second half of the run (tolerances below);
//   after everything stopped and the namespaces were cleaned: none of the run's /dev/shm entries
//     left, and machine-wide shared memory (/proc/meminfo Shmem, /dev/shm in use) back where it
//     was before the run.
//
//   horus_soak [--seconds S] [--publishers N] [--subscribers M] [--clients C] [--seed X]
//              [--stuck-seconds T]
// Defaults: 600 s, 3 publishers, 3 subscribers, 3 clients, 10 s. Exit status 0 when every check
// held. For the tests of the checks themselves only: --inject-hang ROLE makes the steady process
// of that role hang two seconds after it starts, --inject-leak ROLE makes it leak 1.25 MiB/s.
#include <signal.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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
#include <horus/log.hpp>
#include <horus/presence.hpp>
#include <horus/scheduler.hpp>
#include <horus/service.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <service_test/compute.hpp>
#include <topic_test/blob.hpp>
#include <topic_test/sample.hpp>

#include "proc_figures.hpp"

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
/// The steady server is never killed, so any failed call to it is a fault; its calls get more
/// time, so that a server descheduled on a loaded machine is not taken for one (a lost request
/// or answer still ends in Timeout), and the clients wait for it to register before calling.
constexpr auto kSteadyCallTimeout = 5s;
constexpr auto kSteadyServerStart = 5s;
/// How much later than its timeout a call may return before it counts as hung rather than late.
/// Generous: on a loaded machine (the AddressSanitizer run beside other builds) a descheduled
/// client saw a call come back over a second late; what the check is for is a hang.
constexpr auto kOverdueSlack = 5s;
/// A publisher's sequence numbers carry its id in the top bits.
constexpr int kPublisherShift = 48;
/// How long after its start the steady process chosen by --inject-hang stops making progress.
constexpr auto kInjectedHangAfter = 2s;
/// What the steady process chosen by --inject-leak keeps and never frees: 1.25 MiB a second.
constexpr std::size_t kInjectedLeakBytes = std::size_t{128} * 1024;
constexpr auto kInjectedLeakEvery = 100ms;

// Footprint tolerances of a steady process, second half of the run against the first (both
// after the warm-up). A leak of one allocation per message, call or peer restart grows without
// bound; a process that merely settles does not grow from one half to the other.
//  - private memory (RssAnon): malloc keeps freed chunks, and a burst (a client's 2 s timeout,
//    long Blobs) may grow an arena once; leak-free runs measured 0 kB of growth, so 1 MiB is
//    margin, and still below what one lost Blob (up to ~1 KiB) per message or per call would
//    leak in a few seconds (thousands a second).
//  - mappings (VmSize): one thread stack or one topic segment more is 8 MiB / 1-2 MiB; a
//    handle that forgot to unmap its dead peers' segments grows by one per restart. 4 MiB.
//  - threads and descriptors: counts, so any growth that stays is a leak; the tolerance of 2
//    covers a sample taken while a reconnection briefly holds an old and a new descriptor.
constexpr std::int64_t kAnonGrowthToleranceKb = 1024;
constexpr std::int64_t kMappedGrowthToleranceKb = 4096;
constexpr std::int64_t kCountGrowthTolerance = 2;
// ASan's quarantine and TSan's shadow and history keep freed memory on purpose and grow for
// minutes: under a sanitizer, private memory and mappings are reported, not checked.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
// Machine-wide: /proc/meminfo Shmem and /dev/shm in use after the run against before it, less
// what other programs' files in /dev/shm grew meanwhile (this machine is shared). The run's own
// segments, presence files and log ring hold ~1.4 MiB at its peak (printed); leaving them
// behind moves these figures by that much. 1 MiB is above what the rest of the machine moves
// outside /dev/shm (memfds, other tmpfs; measured: tens of KiB) and below the run's peak; a
// smaller leftover of the run is named by the check of its own entries. A figure over the
// bound is sampled again for a few seconds before it fails, and ctest runs soak.short alone.
constexpr std::int64_t kShmGrowthToleranceKb = 1024;

/// Counters of one process slot, in memory shared by the supervisor and every child (forked, so
/// they survive kill -9 and restarts).
struct SlotStats {
  /// Advanced by the child each time it makes progress (a send, a receive or a receive timeout,
  /// a call answered or failed, a request handled, a tick).
  std::atomic<std::uint64_t> heartbeat;
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
  /// Failed calls to the killed server (expected: it dies under them) ...
  std::atomic<std::uint64_t> calls_no_server;
  std::atomic<std::uint64_t> calls_transport;
  std::atomic<std::uint64_t> calls_timeout;
  /// ... and to the steady one (each a fault).
  std::atomic<std::uint64_t> steady_calls_no_server;
  std::atomic<std::uint64_t> steady_calls_transport;
  std::atomic<std::uint64_t> steady_calls_timeout;
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

/// In a child chosen by --inject-hang: when its progress stops for good (never by default).
Clock::time_point hang_at{};
/// In a child chosen by --inject-leak: when it next keeps a block it will never give back.
Clock::time_point next_leak{};
std::vector<std::unique_ptr<char[]>> leaked;

/// Records progress, unless an injected hang is due: then the calling thread blocks for good,
/// holding whatever it holds, as a deadlock would. (A role's beats all come from one thread.)
void beat(SlotStats& stats) {
  if (hang_at != Clock::time_point{} && Clock::now() >= hang_at) {
    for (;;) {
      ::pause();
    }
  }
  if (next_leak != Clock::time_point{} && Clock::now() >= next_leak) {
    leaked.push_back(std::make_unique<char[]>(kInjectedLeakBytes));
    std::memset(leaked.back().get(), 1, kInjectedLeakBytes);  // touched: resident
    next_leak += kInjectedLeakEvery;
  }
  stats.heartbeat.fetch_add(1, std::memory_order_relaxed);
}

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
    beat(stats);
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
    beat(stats);
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

/// Serves Compute in `namespace_name` (every client calls both servers in turn, so each sees
/// clients come and go; the killed one also makes them see it go).
void server(std::size_t slot, const std::string& namespace_name) {
  SlotStats& stats = shared->slots[slot];
  horus::TopicOptions options;
  options.namespace_name = namespace_name;
  horus::ServiceServer<Compute> serving =
      horus::ServiceServerBuilder<Compute>()
          .options(options)
          .on_request([&stats](const ComputeRequest& req) {
            beat(stats);
            return ComputeResponse{req.a + req.b, static_cast<std::uint32_t>(::getpid())};
          })
          .build();
  while (!stopping()) {
    std::this_thread::sleep_for(10ms);
  }
}

void client(std::size_t slot, std::size_t id, const std::string& steady_namespace) {
  SlotStats& stats = shared->slots[slot];
  horus::ServiceClient<Compute> killed_server;
  horus::TopicOptions steady_options;
  steady_options.namespace_name = steady_namespace;
  horus::ServiceClient<Compute> steady_server(steady_options);
  // Not judged here: a server not there in time fails the first call, counted as NoServer.
  static_cast<void>(steady_server.wait_for_server(kSteadyServerStart));
  for (std::int64_t i = 0; !stopping(); ++i) {
    const std::int64_t a = static_cast<std::int64_t>(id) * 1'000'000'000 + i;
    const Clock::time_point start = Clock::now();
    const bool steady = i % 2 != 0;
    const auto timeout = steady ? kSteadyCallTimeout : kCallTimeout;
    const horus::ServiceResult<ComputeResponse> sum =
        (steady ? steady_server : killed_server).call({a, i, 0, 0}, timeout);
    beat(stats);
    if (Clock::now() - start > timeout + kOverdueSlack) {
      stats.calls_overdue.fetch_add(1, std::memory_order_relaxed);
    }
    if (sum) {
      (sum->sum == a + i ? stats.calls_ok : stats.calls_wrong).fetch_add(1);
      // Concurrent clients, not a benchmark: leave the machine's cores to the others too.
      std::this_thread::sleep_for(100us);
      continue;
    }
    if (stopping()) {
      break;  // the servers are stopping too: a call failing now proves nothing
    }
    switch (sum.error().kind()) {
      case horus::ServiceErrorKind::NoServer:
        (steady ? stats.steady_calls_no_server : stats.calls_no_server).fetch_add(1);
        std::this_thread::sleep_for(5ms);
        break;
      case horus::ServiceErrorKind::Transport:
        (steady ? stats.steady_calls_transport : stats.calls_transport).fetch_add(1);
        std::this_thread::sleep_for(5ms);
        break;
      case horus::ServiceErrorKind::Timeout:
        (steady ? stats.steady_calls_timeout : stats.calls_timeout).fetch_add(1);
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
    beat(stats_);
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
constexpr Role kRoles[] = {Role::publisher, Role::subscriber, Role::server, Role::client,
                           Role::scheduler};

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

/// One footprint sample of a steady process, `at` seconds into the run.
struct Footprint {
  double at = 0;
  soak::ProcessMemory memory;
};

struct Process {
  Process(Role role_, std::size_t id_, bool steady_ = false)
      : role(role_), id(id_), steady(steady_) {}

  Role role;
  std::size_t id;
  /// Never killed by the killer: its footprint is sampled over the whole run.
  bool steady = false;
  pid_t pid = -1;
  std::uint64_t kills = 0;
  /// The heartbeat last seen, when it last moved (or the process last started), and whether this
  /// life of the process was already reported stuck.
  std::uint64_t last_beat = 0;
  Clock::time_point last_progress{};
  bool reported_stuck = false;
  std::vector<Footprint> footprints;
};

struct Options {
  double seconds = 600;
  std::size_t publishers = 3;
  std::size_t subscribers = 3;
  std::size_t clients = 3;
  std::uint64_t seed = 1;
  double stuck_seconds = 10;
  std::string inject_hang;
  std::string inject_leak;
};

/// Every name the run uses: its namespace (topics, the killed server, presence, log ring) and
/// the steady server's.
struct Namespaces {
  std::string main;
  std::string steady;
};

pid_t start(std::size_t slot, const Process& process, const Namespaces& names,
            const Options& options) {
  const pid_t pid = ::fork();
  if (pid != 0) {
    return pid;
  }
  if (process.steady && options.inject_hang == role_name(process.role)) {
    hang_at = Clock::now() + kInjectedHangAfter;
  }
  if (process.steady && options.inject_leak == role_name(process.role)) {
    next_leak = Clock::now();
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
        server(slot, process.steady ? names.steady : names.main);
        break;
      case Role::client:
        client(slot, process.id, names.steady);
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

/// How a child asked to stop ended.
enum class Ending { stopped, failed, killed };

/// Waits for a child that was asked to stop, killing it after `patience`.
Ending reap(pid_t pid, Clock::duration patience) {
  const Clock::time_point deadline = Clock::now() + patience;
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (Clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
      return Ending::killed;
    }
    std::this_thread::sleep_for(5ms);
  }
  return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? Ending::stopped : Ending::failed;
}

std::string describe_status(int status) {
  if (WIFSIGNALED(status)) {
    return "signal " + std::to_string(WTERMSIG(status));
  }
  return "exit status " + std::to_string(WEXITSTATUS(status));
}

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
    } else if (flag == "--stuck-seconds") {
      options.stuck_seconds = std::stod(value);
    } else if (flag == "--inject-hang") {
      options.inject_hang = value;
    } else if (flag == "--inject-leak") {
      options.inject_leak = value;
    } else {
      return false;
    }
  }
  const auto known_role = [](const std::string& name) {
    return name.empty() || std::any_of(std::begin(kRoles), std::end(kRoles),
                                       [&](Role role) { return name == role_name(role); });
  };
  // The steady processes: a publisher, a subscriber per topic, a server, a client, a scheduler.
  const std::size_t steady = 1 + kTopicCount + 3;
  return argc % 2 == 1 && options.publishers >= 1 && options.publishers < kMaxPublishers &&
         options.subscribers >= 1 && options.stuck_seconds > 0 && known_role(options.inject_hang) &&
         known_role(options.inject_leak) &&
         options.publishers + options.subscribers + options.clients + 2 + steady <= kMaxProcesses;
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

std::size_t count_of(const std::vector<Process>& processes, Role role) {
  return static_cast<std::size_t>(std::count_if(
      processes.begin(), processes.end(), [role](const Process& p) { return p.role == role; }));
}

int check(bool held, const std::string& what) {
  std::printf("  %-66s %s\n", what.c_str(), held ? "ok" : "FAILED");
  return held ? 0 : 1;
}

/// The supervisor's running state: the children and what it saw of them.
class Supervisor {
 public:
  Supervisor(const Options& options, Namespaces names)
      : options_(options), names_(std::move(names)), begin_(Clock::now()) {
    for (std::size_t i = 0; i < options.publishers; ++i) {
      processes_.emplace_back(Role::publisher, i);
    }
    for (std::size_t i = 0; i < options.subscribers; ++i) {
      processes_.emplace_back(Role::subscriber, i);
    }
    processes_.emplace_back(Role::server, 0);
    for (std::size_t i = 0; i < options.clients; ++i) {
      processes_.emplace_back(Role::client, i);
    }
    processes_.emplace_back(Role::scheduler, 0);
    processes_.emplace_back(Role::publisher, options.publishers, true);
    // Consecutive ids: one steady subscriber on each topic.
    for (std::size_t i = 0; i < kTopicCount; ++i) {
      processes_.emplace_back(Role::subscriber, options.subscribers + i, true);
    }
    processes_.emplace_back(Role::server, 1, true);
    processes_.emplace_back(Role::client, options.clients, true);
    processes_.emplace_back(Role::scheduler, 1, true);
    for (Process& process : processes_) {
      launch(process);
    }
  }

  std::vector<Process>& processes() { return processes_; }
  double elapsed() const { return std::chrono::duration<double>(Clock::now() - begin_).count(); }

  /// (Re)starts a process and its heartbeat watch.
  void launch(Process& process) {
    const std::size_t slot = static_cast<std::size_t>(&process - processes_.data());
    process.pid = start(slot, process, names_, options_);
    process.last_beat = shared->slots[slot].heartbeat.load();
    process.last_progress = Clock::now();
    process.reported_stuck = false;
  }

  /// kill -9 and restart; a child found to have exited by itself before the kill failed.
  void kill_and_restart(Process& process) {
    ::kill(process.pid, SIGKILL);
    int status = 0;
    ::waitpid(process.pid, &status, 0);
    if (!WIFSIGNALED(status) || WTERMSIG(status) != SIGKILL) {
      died_unasked(process, status);
    }
    ++process.kills;
    launch(process);
  }

  /// Restarts every child that ended without being asked (a crash, an exception).
  void restart_the_dead() {
    int status = 0;
    pid_t pid = 0;
    while ((pid = ::waitpid(-1, &status, WNOHANG)) > 0) {
      for (Process& process : processes_) {
        if (process.pid == pid) {
          died_unasked(process, status);
          process.footprints.clear();  // another process now: its growth starts over
          launch(process);
        }
      }
    }
  }

  /// Reports, once per life, each live child whose heartbeat has not moved for --stuck-seconds.
  void watch_heartbeats() {
    const Clock::time_point now = Clock::now();
    for (std::size_t slot = 0; slot < processes_.size(); ++slot) {
      Process& process = processes_[slot];
      const std::uint64_t beat = shared->slots[slot].heartbeat.load(std::memory_order_relaxed);
      if (beat != process.last_beat) {
        process.last_beat = beat;
        process.last_progress = now;
        continue;
      }
      const double still = std::chrono::duration<double>(now - process.last_progress).count();
      if (process.reported_stuck || still < options_.stuck_seconds) {
        continue;
      }
      process.reported_stuck = true;
      ++stuck_alive_;
      std::printf(
          "horus_soak: STUCK %s %zu%s, pid %d: no progress for %.1f s (heartbeat %llu, last "
          "moved %.1f s into the run); threads: %s\n",
          role_name(process.role), process.id, process.steady ? " (steady)" : "",
          static_cast<int>(process.pid), still, static_cast<unsigned long long>(beat),
          elapsed() - still, soak::thread_states(process.pid).c_str());
      std::fflush(stdout);
    }
  }

  void sample_footprints() {
    const double at = elapsed();
    for (Process& process : processes_) {
      if (process.steady) {
        process.footprints.push_back({at, soak::process_memory(process.pid)});
      }
    }
  }

  std::uint64_t crashed() const { return crashed_; }
  std::uint64_t stuck_alive() const { return stuck_alive_; }

 private:
  void died_unasked(const Process& process, int status) {
    ++crashed_;
    std::printf("horus_soak: %s %zu, pid %d, died unasked: %s\n", role_name(process.role),
                process.id, static_cast<int>(process.pid), describe_status(status).c_str());
  }

  Options options_;
  Namespaces names_;
  Clock::time_point begin_;
  std::vector<Process> processes_;
  std::uint64_t crashed_ = 0;
  std::uint64_t stuck_alive_ = 0;
};

// ---- Footprint growth of the steady processes ---------------------------------------------------

struct Growth {
  std::int64_t early = -1;  // the most seen in the first half after the warm-up
  std::int64_t late = -1;   // the most seen in the second half
  std::int64_t grown() const { return late - early; }
};

/// Peaks of one figure in the two halves of [warm_up, end]; -1 where a half has no sample.
Growth growth_of(const std::vector<Footprint>& footprints, double warm_up, double end,
                 std::int64_t soak::ProcessMemory::*figure) {
  Growth growth;
  const double middle = (warm_up + end) / 2;
  for (const Footprint& footprint : footprints) {
    const std::int64_t value = footprint.memory.*figure;
    if (footprint.at < warm_up || value < 0) {
      continue;
    }
    std::int64_t& peak = footprint.at < middle ? growth.early : growth.late;
    peak = std::max(peak, value);
  }
  return growth;
}

/// Prints each steady process's footprint and checks it did not grow; returns the failures.
int check_footprints(const std::vector<Process>& processes, double warm_up, double end) {
  struct Figure {
    const char* name;
    std::int64_t soak::ProcessMemory::*member;
    std::int64_t tolerance;  // -1: reported, not checked
  };
  // RssShmem grows as a process first touches the pages of segments it maps (a ring filling up,
  // the log ring): bounded by the mappings, which VmSize checks.
  const Figure figures[] = {
      {"RssAnon kB", &soak::ProcessMemory::rss_anon_kb, kSanitized ? -1 : kAnonGrowthToleranceKb},
      {"RssShmem kB", &soak::ProcessMemory::rss_shmem_kb, -1},
      {"VmSize kB", &soak::ProcessMemory::vm_size_kb, kSanitized ? -1 : kMappedGrowthToleranceKb},
      {"threads", &soak::ProcessMemory::threads, kCountGrowthTolerance},
      {"descriptors", &soak::ProcessMemory::fds, kCountGrowthTolerance},
  };
  std::printf("  steady processes, peak in the first / second half after %.0f s of warm-up%s:\n",
              warm_up, kSanitized ? " (sanitizer build: RssAnon, VmSize not checked)" : "");
  int failures = 0;
  for (const Process& process : processes) {
    if (!process.steady) {
      continue;
    }
    std::string line = std::string(role_name(process.role)) + " " + std::to_string(process.id);
    bool measured = true;
    bool held = true;
    for (const Figure& figure : figures) {
      const Growth growth = growth_of(process.footprints, warm_up, end, figure.member);
      measured = measured && growth.early >= 0 && growth.late >= 0;
      held = held && (figure.tolerance < 0 || growth.grown() <= figure.tolerance);
      char text[96];
      std::snprintf(text, sizeof text, " | %s %lld / %lld", figure.name,
                    static_cast<long long>(growth.early), static_cast<long long>(growth.late));
      line += text;
    }
    std::printf("    %s\n", line.c_str());
    if (!measured) {
      std::printf("    (%s %zu: too few samples to judge growth; run longer)\n",
                  role_name(process.role), process.id);
      continue;
    }
    failures += held ? 0 : 1;
    if (!held) {
      std::printf("    %s %zu GREW beyond the tolerance\n", role_name(process.role), process.id);
    }
  }
  return failures;
}

// ---- What the run left in shared memory ---------------------------------------------------------

/// Where, besides its namespace folder, the runtime keeps a namespace's files: a Scheduler's
/// announcements (runtime/src/presence/presence.cpp) and the log ring
/// (runtime/src/scheduler/log_ring.cpp).
std::string presence_folder(const std::string& name) {
  return horus::detail::shm_root() + "/@presence/" + name;
}
std::string log_ring(const std::string& name) {
  return horus::detail::shm_root() + "/@logs/" + name;
}

/// Bytes a file or folder really takes on the tmpfs (its blocks, not its apparent size).
std::int64_t allocated_kb(const std::string& path) {
  struct stat status {};
  return ::lstat(path.c_str(), &status) == 0 ? static_cast<std::int64_t>(status.st_blocks) / 2 : 0;
}

/// Every path where the runtime keeps files of the run's namespaces.
std::vector<std::string> run_paths(const Namespaces& names) {
  std::vector<std::string> paths;
  for (const std::string& name : {names.main, names.steady}) {
    paths.push_back(horus::detail::namespace_directory(name));
    paths.push_back(presence_folder(name));
    paths.push_back(log_ring(name));
  }
  return paths;
}

/// The blocks (kB) the run's own files and folders hold.
std::int64_t run_kb(const std::vector<std::string>& paths) {
  std::int64_t kb = 0;
  for (const std::string& path : paths) {
    kb += allocated_kb(path) + soak::tree_kb(path, {});
  }
  return kb;
}

/// The run's own entries under the root, each with its size; empty when there is none.
std::vector<std::string> entries_left(const std::vector<std::string>& paths) {
  std::vector<std::string> left;
  for (const std::string& path : paths) {
    std::error_code error;
    if (!std::filesystem::exists(path, error)) {
      continue;
    }
    left.push_back(path + " (" + std::to_string(allocated_kb(path)) + " kB)");
    if (std::filesystem::is_directory(path, error)) {
      for (const auto& entry : std::filesystem::directory_iterator(path, error)) {
        left.push_back(entry.path().string() + " (" +
                       std::to_string(allocated_kb(entry.path().string())) + " kB)");
      }
    }
  }
  return left;
}

/// The log lines the run's processes wrote (the runtime's warnings about dead peers, a
/// Scheduler's own lines): how many, and the first few warnings or errors.
void report_log(const std::string& name) {
  const horus::LogSnapshot log = horus::read_log(name);
  std::size_t warnings = 0;
  for (const horus::LogRecord& record : log.records) {
    if (record.level >= horus::LogLevel::Warn && ++warnings <= 3) {
      std::printf("    log: %s %s: %s\n", std::string(horus::to_string(record.level)).c_str(),
                  record.source.c_str(), record.message.c_str());
    }
  }
  std::printf("  %-28s %12llu (%zu of the retained ones WARN or ERROR, %llu dropped)\n",
              "log lines written", static_cast<unsigned long long>(log.written), warnings,
              static_cast<unsigned long long>(log.dropped));
}

/// Machine-wide memory, and how much of /dev/shm other programs' files hold (all but the run's).
struct MachineFigures {
  soak::MachineMemory memory;
  std::int64_t others_kb = 0;
};

MachineFigures machine_figures(const std::vector<std::string>& run) {
  return {soak::machine_memory(), soak::tree_kb("/dev/shm", run)};
}

/// Growth since `before` that other programs' /dev/shm files do not account for: of Shmem, and
/// of /dev/shm in use.
std::int64_t unexplained_shmem_kb(const MachineFigures& before, const MachineFigures& after) {
  return after.memory.shmem_kb - before.memory.shmem_kb - (after.others_kb - before.others_kb);
}
std::int64_t unexplained_dev_shm_kb(const MachineFigures& before, const MachineFigures& after) {
  return after.memory.dev_shm_used_kb - before.memory.dev_shm_used_kb -
         (after.others_kb - before.others_kb);
}

/// Machine-wide memory once the run is over. A figure above the tolerance is sampled again for
/// up to five seconds: what another program held for a moment goes, a leak stays.
MachineFigures settled_figures(const MachineFigures& before, const std::vector<std::string>& run) {
  MachineFigures after = machine_figures(run);
  for (int retry = 0; retry < 5; ++retry) {
    if (unexplained_shmem_kb(before, after) <= kShmGrowthToleranceKb &&
        unexplained_dev_shm_kb(before, after) <= kShmGrowthToleranceKb) {
      break;
    }
    std::this_thread::sleep_for(1s);
    after = machine_figures(run);
  }
  return after;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  if (!parse(argc, argv, options)) {
    std::fprintf(stderr,
                 "usage: horus_soak [--seconds S] [--publishers N<16] [--subscribers M] "
                 "[--clients C] [--seed X] [--stuck-seconds T]\n");
    return 2;
  }
  void* memory =
      ::mmap(nullptr, sizeof(Shared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (memory == MAP_FAILED) {
    std::perror("mmap");
    return 2;
  }
  shared = new (memory) Shared{};
  const Namespaces names{"soak_" + std::to_string(::getpid()),
                         "soak_" + std::to_string(::getpid()) + ".steady"};
  // Before any thread or child exists.
  ::setenv("HORUS_NAMESPACE", names.main.c_str(), 1);  // NOLINT(concurrency-mt-unsafe)

  // Before any child exists (the counters above are already mapped: they count in both).
  const std::vector<std::string> paths = run_paths(names);
  const MachineFigures before = machine_figures(paths);
  soak::MachineMemory peak = before.memory;
  std::int64_t run_peak_kb = 0;
  Supervisor supervisor(options, names);
  std::vector<Process>& processes = supervisor.processes();
  std::vector<std::size_t> mortal;
  for (std::size_t slot = 0; slot < processes.size(); ++slot) {
    if (!processes[slot].steady) {
      mortal.push_back(slot);
    }
  }

  std::mt19937_64 random(options.seed);
  std::uniform_int_distribution<int> pause_ms(100, 600);
  std::uniform_int_distribution<std::size_t> victim(0, mortal.size() - 1);
  const Clock::time_point begin = Clock::now();
  const Clock::time_point end = begin + std::chrono::duration_cast<Clock::duration>(
                                            std::chrono::duration<double>(options.seconds));
  Clock::time_point next_kill = begin + std::chrono::milliseconds(pause_ms(random));
  Clock::time_point next_sample = begin;
  while (Clock::now() < end) {
    std::this_thread::sleep_for(20ms);
    supervisor.restart_the_dead();
    supervisor.watch_heartbeats();
    const Clock::time_point now = Clock::now();
    if (now >= next_sample) {
      supervisor.sample_footprints();
      const soak::MachineMemory machine = soak::machine_memory();
      peak.shmem_kb = std::max(peak.shmem_kb, machine.shmem_kb);
      peak.dev_shm_used_kb = std::max(peak.dev_shm_used_kb, machine.dev_shm_used_kb);
      peak.dev_shm_entries = std::max(peak.dev_shm_entries, machine.dev_shm_entries);
      run_peak_kb = std::max(run_peak_kb, run_kb(paths));
      next_sample += 1s;
    }
    if (now >= next_kill) {
      supervisor.kill_and_restart(processes[mortal[victim(random)]]);
      next_kill = now + std::chrono::milliseconds(pause_ms(random));
    }
  }
  const double run_seconds = supervisor.elapsed();

  shared->stop.store(true);
  std::uint64_t not_stopping = 0;
  std::uint64_t failed_at_stop = 0;
  for (const Process& process : processes) {
    const Ending ending = reap(process.pid, 5s);
    not_stopping += ending == Ending::killed ? 1 : 0;
    failed_at_stop += ending == Ending::failed ? 1 : 0;
    if (ending != Ending::stopped) {
      std::printf("horus_soak: %s %zu, pid %d, %s when asked to stop\n", role_name(process.role),
                  process.id, static_cast<int>(process.pid),
                  ending == Ending::killed ? "did not stop within 5 s" : "ended with an error");
    }
  }

  // What `horus shm clean` does for a namespace: segments and announcements of dead processes.
  for (const std::string& name : {names.main, names.steady}) {
    horus::clean_namespace(name);
    horus::clean_presence(name);
  }
  std::printf(
      "horus_soak: %.0f s, %zu publishers, %zu subscribers, %zu clients, seed %llu, "
      "steady: 1 publisher, %zu subscribers, 1 server, 1 client, 1 scheduler\n",
      options.seconds, options.publishers, options.subscribers, options.clients,
      static_cast<unsigned long long>(options.seed), kTopicCount);
  report_log(names.main);
  // Cleaning removes what no live process uses, the log ring and the presence folder included;
  // only the main namespace's ring may stay, and only while this process writes it (the runtime
  // logged here). The run's namespaces are its own, so it then removes them whole.
  bool ring_in_use = false;
  for (const horus::NamespaceObjectInfo& object : horus::list_namespace_objects(names.main)) {
    ring_in_use = ring_in_use || (object.kind == "@logs" && object.in_use);
  }
  const std::vector<std::string> left = entries_left(paths);
  bool only_kept_by_design = true;
  for (const std::string& entry : left) {
    const bool kept = ring_in_use && entry.starts_with(log_ring(names.main) + " ");
    only_kept_by_design = only_kept_by_design && kept;
    std::printf("    left after cleaning: %s%s\n", entry.c_str(),
                kept ? " (this process writes it)" : "");
  }
  for (const std::string& name : {names.main, names.steady}) horus::remove_namespace(name);
  const MachineFigures after = settled_figures(before, paths);

  const std::uint64_t delivered = total(processes, &SlotStats::delivered);
  const std::uint64_t gaps = total(processes, &SlotStats::gaps);
  const std::uint64_t lost = total(processes, &SlotStats::lost);
  const std::uint64_t publisher_kills = kills_of(processes, Role::publisher);
  for (const Role role : kRoles) {
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
  figure("killed server: NoServer", total(processes, &SlotStats::calls_no_server));
  figure("killed server: Transport", total(processes, &SlotStats::calls_transport));
  figure("killed server: Timeout", total(processes, &SlotStats::calls_timeout));
  figure("steady server: NoServer", total(processes, &SlotStats::steady_calls_no_server));
  figure("steady server: Transport", total(processes, &SlotStats::steady_calls_transport));
  figure("steady server: Timeout", total(processes, &SlotStats::steady_calls_timeout));
  figure("calls failed: ServiceFailed", total(processes, &SlotStats::calls_failed));
  figure("calls overdue (> timeout+5s)", total(processes, &SlotStats::calls_overdue));
  figure("children that died unasked", supervisor.crashed() + failed_at_stop);
  figure("stuck while alive", supervisor.stuck_alive());
  figure("did not stop when asked", not_stopping);
  const auto memory_figure = [](const char* what, std::int64_t from, std::int64_t top,
                                std::int64_t to) {
    std::printf("  %-28s %10lld before, %10lld peak, %10lld after (%+lld)\n", what,
                static_cast<long long>(from), static_cast<long long>(top),
                static_cast<long long>(to), static_cast<long long>(to - from));
  };
  std::printf("  machine-wide:\n");
  memory_figure("Shmem kB (/proc/meminfo)", before.memory.shmem_kb, peak.shmem_kb,
                after.memory.shmem_kb);
  memory_figure("/dev/shm in use kB", before.memory.dev_shm_used_kb, peak.dev_shm_used_kb,
                after.memory.dev_shm_used_kb);
  memory_figure("/dev/shm entries", before.memory.dev_shm_entries, peak.dev_shm_entries,
                after.memory.dev_shm_entries);
  memory_figure("  the run's own files kB", 0, run_peak_kb, run_kb(paths));
  std::printf("  %-28s %10lld before, %10lld after (%+lld)\n", "  other programs' files kB",
              static_cast<long long>(before.others_kb), static_cast<long long>(after.others_kb),
              static_cast<long long>(after.others_kb - before.others_kb));
  std::printf(
      "  growth not explained by other programs' files: Shmem %+lld kB, /dev/shm %+lld "
      "kB\n",
      static_cast<long long>(unexplained_shmem_kb(before, after)),
      static_cast<long long>(unexplained_dev_shm_kb(before, after)));
  // Not checked: the page cache and every other program on the machine move it by far more
  // than a leak of this run could; what it would show is checked directly above and below
  // (shared memory, each steady process's private memory, processes that did not end).
  std::printf(
      "  %-28s %10lld before, %10lld after (%+lld; not checked, see the source)\n",
      "MemAvailable kB", static_cast<long long>(before.memory.mem_available_kb),
      static_cast<long long>(after.memory.mem_available_kb),
      static_cast<long long>(after.memory.mem_available_kb - before.memory.mem_available_kb));
  const double warm_up = std::max(3.0, run_seconds / 10);
  const int grown = check_footprints(processes, warm_up, run_seconds);

  int failures = check(delivered > 0, "messages were delivered");
  failures += check(gaps <= lost + publisher_kills * count_of(processes, Role::subscriber),
                    "every gap is counted (gaps <= lost + publisher kills x subscribers)");
  failures += check(total(processes, &SlotStats::torn) == 0, "no torn message");
  failures += check(total(processes, &SlotStats::out_of_order) == 0, "no message out of order");
  failures += check(total(processes, &SlotStats::calls_ok) > 0, "calls were answered");
  failures += check(total(processes, &SlotStats::calls_wrong) == 0, "no call answered wrong");
  failures += check(total(processes, &SlotStats::calls_failed) == 0,
                    "no call failed as ServiceFailed (the handler never fails)");
  failures +=
      check(total(processes, &SlotStats::calls_overdue) == 0, "no call outlived its timeout");
  failures += check(total(processes, &SlotStats::steady_calls_no_server) +
                            total(processes, &SlotStats::steady_calls_transport) +
                            total(processes, &SlotStats::steady_calls_timeout) ==
                        0,
                    "no call to the steady server failed (it is never killed)");
  failures += check(total(processes, &SlotStats::event_ticks) > 0, "the event node ticked");
  failures += check(supervisor.crashed() + failed_at_stop == 0, "no child died unasked");
  failures += check(supervisor.stuck_alive() == 0,
                    "no live child without progress for " +
                        std::to_string(static_cast<int>(options.stuck_seconds)) + " s");
  failures += check(not_stopping == 0, "every process stopped when asked");
  failures +=
      check(grown == 0, "no steady process grew (RssAnon 1 MiB, VmSize 4 MiB, threads, fds 2)");
  failures += check(only_kept_by_design,
                    "after cleaning, /dev/shm holds none of the run's entries (but a ring in use)");
  failures += check(unexplained_shmem_kb(before, after) <= kShmGrowthToleranceKb,
                    "machine-wide Shmem back within 1 MiB of before (others' files aside)");
  failures += check(unexplained_dev_shm_kb(before, after) <= kShmGrowthToleranceKb,
                    "/dev/shm in use back within 1 MiB of before (others' files aside)");
  return failures == 0 ? 0 : 1;
}
