// Topic<T> against the raw floors, in one run, with the two processes pinned to two cores:
//   latency     one-way (round trip / 2) p50/p99/p99.9, busy-polling try_recv, per size,
//               against a raw shared-memory ping-pong (a sequence counter and a memcpy);
//   wake-up     one-way through blocking recv() (futex), on a topic with one publisher, on one
//               whose ring a second publisher shared, and on a single-publisher topic, against a
//               raw futex ping-pong;
//   iceoryx     when built with iceoryx and its daemon runs (bench/topic/run.sh does both), the
//               latency table's ping-pong through iceoryx side by side, in the same rounds;
//   throughput  messages per second through a 1024-slot topic (send() by its one publisher and
//               after a second one shared the ring; single-publisher send() and loan()), against
//               a raw seqlock ring carrying the same messages: all writers fill in message i and
//               hand it over, all readers check that message i arrives i-th. Two reference rows
//               add to the raw ring one thing each that a topic's send may do: the last-send
//               stamp for tools, and a shared ring's claim. Then every writer alone, with nobody
//               reading.
// The second process is this binary re-executed with --role.
#include <fcntl.h>
#include <sched.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <thread>
#include <tuple>
#include <type_traits>
#include <vector>

#include <horus/detail/futex.hpp>
#include <horus/detail/ring.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <topic_bench/msg1536.hpp>
#include <topic_bench/msg16.hpp>
#include <topic_bench/msg4096.hpp>
#include <topic_bench/msg64.hpp>
#include <topic_bench/msg65536.hpp>

#if defined(HORUS_BENCH_ICEORYX)
#include <iceoryx_hoofs/log/logmanager.hpp>
#include <iceoryx_posh/popo/publisher.hpp>
#include <iceoryx_posh/popo/subscriber.hpp>
#include <iceoryx_posh/runtime/posh_runtime.hpp>
#endif

extern char** environ;

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr std::size_t kMaxPayload = 65536;
constexpr std::uint64_t kStop = UINT64_MAX;
constexpr std::size_t kRingSlots = 1024;
constexpr std::size_t kRingPayload = 64;
constexpr std::uint64_t kThroughputMessages = 1'000'000;
constexpr std::uint64_t kAckEvery = 64;
constexpr std::uint64_t kWindow = kRingSlots / 2;

/// The raw floors' shared region: two one-message mailboxes, two futex words, a raw ring, and
/// the results the second process reports.
struct alignas(64) Mailbox {
  std::atomic<std::uint64_t> seq;
  alignas(64) std::byte payload[kMaxPayload];
};
struct alignas(64) RawSlot {
  std::atomic<std::uint64_t> seq;
  /// Written only by the reference row, as a topic writes its slot's last-send stamp.
  std::atomic<std::uint32_t> send_time_s;
  alignas(8) std::byte payload[kRingPayload];
};
static_assert(sizeof(topic_bench::Msg64) == kRingPayload);
struct Shared {
  Mailbox ping;
  Mailbox pong;
  alignas(64) std::atomic<std::uint32_t> ping_word;
  alignas(64) std::atomic<std::uint32_t> pong_word;
  alignas(64) std::atomic<std::uint64_t> ready;
  std::atomic<std::uint64_t> stop;
  std::atomic<std::uint64_t> received;
  std::atomic<std::uint64_t> lost;
  /// Messages that arrived out of place: must stay 0.
  std::atomic<std::uint64_t> misordered;
  std::atomic<std::int64_t> finished_ns;
  /// The reader's position, published every kAckEvery messages: the writer's back-pressure.
  alignas(64) std::atomic<std::uint64_t> consumed;
  alignas(64) RawSlot ring[kRingSlots];
  /// The claimed-ring reference's tickets and per-slot claim words, apart from the slots as a
  /// topic keeps them.
  alignas(64) std::atomic<std::uint64_t> tickets;
  alignas(64) std::atomic<std::uint64_t> claims[kRingSlots];
};

Shared* map_shared(const std::string& name, bool create) {
  const int fd = ::shm_open(name.c_str(), O_RDWR | (create ? O_CREAT : 0), 0600);
  if (fd < 0 || (create && ::posix_fallocate(fd, 0, sizeof(Shared)) != 0)) {
    std::perror("bench shared region");
    std::exit(2);
  }
  void* base = ::mmap(nullptr, sizeof(Shared), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  ::close(fd);
  if (base == MAP_FAILED) {
    std::perror("mmap");
    std::exit(2);
  }
  return static_cast<Shared*>(base);
}

void pin(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu % static_cast<int>(std::max(1u, std::thread::hardware_concurrency())), &set);
  if (::sched_setaffinity(0, sizeof set, &set) != 0) {
    std::perror("sched_setaffinity");
  }
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

struct Percentiles {
  double p50, p99, p999;
};

Percentiles percentiles(std::vector<std::int64_t>& samples) {
  std::sort(samples.begin(), samples.end());
  auto at = [&](double q) {
    return static_cast<double>(samples[static_cast<std::size_t>(q * (samples.size() - 1))]) / 2;
  };
  return {at(0.50), at(0.99), at(0.999)};
}

/// "ping.64" and the like (append, not operator+: GCC 12 -Wrestrict false positive, PR105651).
std::string topic_name(const char* prefix, std::size_t size) {
  return std::string(prefix).append(".").append(std::to_string(size));
}

std::size_t iterations(std::size_t size) { return size >= 65536 ? 5000 : 50000; }
constexpr std::size_t kWarmup = 2000;
/// Ping-pong keeps one message in flight; a ring of 64 large slots would only measure L2 misses.
constexpr std::size_t kLatencyCapacity = 4;

/// The message types of the latency table, each exactly its size in bytes.
using LatencyMessages = std::tuple<topic_bench::Msg16, topic_bench::Msg64, topic_bench::Msg1536,
                                   topic_bench::Msg4096, topic_bench::Msg65536>;

/// Calls `run.template operator()<M>()` for every message type of the latency table.
template <class Run>
void for_each_latency_message(Run&& run) {
  [&]<class... M>(std::type_identity<std::tuple<M...>>) {
    (run.template operator()<M>(), ...);
  }(std::type_identity<LatencyMessages>{});
}

/// Calls `run.template operator()<M>()` with the message type of `size` bytes; false for a size
/// the benchmark has none of.
template <class Run>
bool with_message_of_size(std::size_t size, Run&& run) {
  bool found = false;
  for_each_latency_message([&]<class M>() {
    if (sizeof(M) == size) {
      run.template operator()<M>();
      found = true;
    }
  });
  return found;
}

#if defined(HORUS_BENCH_ICEORYX)
/// Whether iceoryx runs side by side: its daemon (RouDi) is up, which bench/topic/run.sh says
/// with HORUS_BENCH_ICEORYX=1 (without RouDi, registering would wait for it forever).
bool iceoryx_enabled() {
  const char* flag = std::getenv("HORUS_BENCH_ICEORYX");
  return flag != nullptr && std::string_view(flag) == "1";
}

/// The iceoryx service of one direction of a ping-pong: ("horus_bench", "ping", "64").
iox::capro::ServiceDescription iceoryx_service(const char* direction, std::size_t size) {
  const std::string event = std::to_string(size);
  return {"horus_bench", iox::capro::IdString_t(iox::cxx::TruncateToCapacity, direction),
          iox::capro::IdString_t(iox::cxx::TruncateToCapacity, event.c_str())};
}

/// Registers this process with RouDi, once (iceoryx allows one registration per process).
void iceoryx_register(const char* role) {
  static const bool registered = [role] {
    const std::string name = std::string("horus_bench_") + role + "_" + std::to_string(::getpid());
    // Its default, every registration at length, would interleave with the tables.
    iox::log::LogManager::GetLogManager().SetDefaultLogLevel(
        iox::log::LogLevel::kWarn, iox::log::LogLevelOutput::kHideLogLevel);
    iox::runtime::PoshRuntime::initRuntime(
        iox::RuntimeName_t(iox::cxx::TruncateToCapacity, name.c_str()));
    return true;
  }();
  static_cast<void>(registered);
}

/// Until RouDi has connected this process's subscriber and someone subscribes to its publisher.
template <class Publisher, class Subscriber>
void wait_for_iceoryx_peer(Publisher& publisher, Subscriber& subscriber) {
  while (subscriber.getSubscriptionState() != iox::SubscribeState::SUBSCRIBED ||
         !publisher.hasSubscribers()) {
    std::this_thread::sleep_for(1ms);
  }
}

/// iceoryx's publisher writes the whole message into its loan, as a topic's send() copies it.
template <class M>
void iceoryx_publish(iox::popo::Publisher<M>& publisher, const M& msg) {
  publisher.loan()
      .and_then([&](auto& sample) {
        *sample = msg;
        sample.publish();
      })
      .or_else([](auto&) {
        std::fprintf(stderr, "iceoryx refused a loan\n");
        std::exit(2);
      });
}
#endif

// ---- Second process --------------------------------------------------------------------------

/// Topic names of a ping-pong; single-publisher topics have their own ("sping.64").
std::string ping_name(std::size_t size, bool single) {
  return topic_name(single ? "sping" : "ping", size);
}
std::string pong_name(std::size_t size, bool single) {
  return topic_name(single ? "spong" : "pong", size);
}

template <class M>
void echo_topic(std::size_t size, bool blocking, bool single, Shared& shared) {
  horus::Topic<M> ping(ping_name(size, single));
  horus::Topic<M> pong(pong_name(size, single));
  shared.ready.store(1, std::memory_order_release);
  for (;;) {
    if (blocking) {
      const std::optional<M> msg = ping.recv(5s);
      if (!msg || msg->seq == kStop) {
        return;
      }
      pong.send(*msg);
    } else if (const std::optional<M> msg = ping.try_recv()) {
      if (msg->seq == kStop) {
        return;
      }
      pong.send(*msg);
    }
  }
}

#if defined(HORUS_BENCH_ICEORYX)
template <class M>
void echo_iceoryx(std::size_t size, Shared& shared) {
  iceoryx_register("echo");
  iox::popo::Subscriber<M> ping(iceoryx_service("ping", size));
  iox::popo::Publisher<M> pong(iceoryx_service("pong", size));
  wait_for_iceoryx_peer(pong, ping);
  shared.ready.store(1, std::memory_order_release);
  while (shared.stop.load(std::memory_order_acquire) == 0) {
    ping.take().and_then([&](auto& sample) { iceoryx_publish(pong, *sample); });
  }
}
#endif

void echo_raw(std::size_t size, Shared& shared) {
  std::vector<std::byte> local(size);
  shared.ready.store(1, std::memory_order_release);
  for (std::uint64_t expect = 1;; ++expect) {
    std::uint64_t seq = 0;
    while ((seq = shared.ping.seq.load(std::memory_order_acquire)) < expect) {
    }
    if (seq == kStop) {
      return;
    }
    std::memcpy(local.data(), shared.ping.payload, size);
    std::memcpy(shared.pong.payload, local.data(), size);
    shared.pong.seq.store(seq, std::memory_order_release);
  }
}

void echo_futex(Shared& shared) {
  shared.ready.store(1, std::memory_order_release);
  std::uint32_t seen = 0;
  for (;;) {
    std::uint32_t value = 0;
    while ((value = shared.ping_word.load(std::memory_order_acquire)) == seen) {
      horus::detail::futex_wait(shared.ping_word, seen, 5s);
      if (shared.stop.load(std::memory_order_acquire) != 0) {
        return;
      }
    }
    seen = value;
    shared.pong_word.fetch_add(1, std::memory_order_release);
    horus::detail::futex_wake_all(shared.pong_word);
  }
}

/// What both readers do with a message: check that it is the one expected next.
struct OrderCheck {
  std::uint64_t received = 0;
  std::uint64_t misordered = 0;

  void take(const topic_bench::Msg64& msg, std::uint64_t expected) {
    misordered += msg.seq != expected ? 1 : 0;
    ++received;
  }
  void report(Shared& shared, std::uint64_t lost) const {
    shared.finished_ns.store(now_ns());
    shared.received.store(received);
    shared.lost.store(lost);
    shared.misordered.store(misordered);
  }
};

void consume_topic(const char* name, Shared& shared) {
  horus::Topic<topic_bench::Msg64> topic(name);
  shared.consumed.store(0);
  shared.ready.store(1, std::memory_order_release);
  OrderCheck check;
  while (check.received + topic.lost() < kThroughputMessages) {
    if (const std::optional<topic_bench::Msg64> msg = topic.try_recv()) {
      check.take(*msg, check.received + topic.lost());
      if (check.received % kAckEvery == 0) {
        shared.consumed.store(check.received + topic.lost(), std::memory_order_release);
      }
    }
  }
  check.report(shared, topic.lost());
}

void consume_raw(Shared& shared) {
  shared.consumed.store(0);
  shared.ready.store(1, std::memory_order_release);
  OrderCheck check;
  std::uint64_t lost = 0;
  std::uint64_t next = 0;
  topic_bench::Msg64 msg;
  while (next < kThroughputMessages) {
    RawSlot& slot = shared.ring[next % kRingSlots];
    const std::uint64_t committed = 2 * next + 2;
    const std::uint64_t before = slot.seq.load(std::memory_order_acquire);
    if (before == committed) {
      std::memcpy(&msg, slot.payload, sizeof msg);
      std::atomic_thread_fence(std::memory_order_acquire);
      if (slot.seq.load(std::memory_order_relaxed) == before) {
        check.take(msg, next);
        ++next;
        if (check.received % kAckEvery == 0) {
          shared.consumed.store(next, std::memory_order_release);
        }
        continue;
      }
    }
    if (before > committed) {
      ++lost;
      ++next;
    }
  }
  check.report(shared, lost);
}

int run_role(const std::string& role, std::size_t size, const std::string& region) {
  pin(1);
  Shared& shared = *map_shared(region, false);
  if (role == "echo_topic" || role == "wake_topic" || role == "wake_single") {
    const bool blocking = role != "echo_topic";
    const bool single = role == "wake_single";
    if (!with_message_of_size(size,
                              [&]<class M>() { echo_topic<M>(size, blocking, single, shared); })) {
      return 3;
    }
#if defined(HORUS_BENCH_ICEORYX)
  } else if (role == "echo_iceoryx") {
    if (!with_message_of_size(size, [&]<class M>() { echo_iceoryx<M>(size, shared); })) {
      return 3;
    }
#endif
  } else if (role == "echo_raw") {
    echo_raw(size, shared);
  } else if (role == "echo_futex") {
    echo_futex(shared);
  } else if (role == "consume_topic") {
    consume_topic("throughput", shared);
  } else if (role == "consume_single") {
    consume_topic("throughput.single", shared);
  } else if (role == "consume_raw") {
    consume_raw(shared);
  } else {
    return 3;
  }
  return 0;
}

// ---- First process ---------------------------------------------------------------------------

class Peer {
 public:
  Peer(const std::string& role, std::size_t size, const std::string& region, Shared& shared)
      : shared_(shared) {
    shared.ready.store(0);
    shared.stop.store(0);
    std::string exe = "/proc/self/exe";
    std::string role_arg = role;
    std::string size_arg = std::to_string(size);
    std::string region_arg = region;
    std::string flag = "--role";
    char* argv[] = {exe.data(),      flag.data(),       role_arg.data(),
                    size_arg.data(), region_arg.data(), nullptr};
    if (::posix_spawn(&pid_, exe.c_str(), nullptr, nullptr, argv, environ) != 0) {
      std::perror("posix_spawn");
      std::exit(2);
    }
    const auto deadline = Clock::now() + 10s;
    while (shared.ready.load(std::memory_order_acquire) == 0) {
      if (Clock::now() > deadline) {
        std::fprintf(stderr, "peer %s never became ready\n", role.c_str());
        std::exit(2);
      }
      std::this_thread::sleep_for(1ms);
    }
  }
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;
  ~Peer() {
    shared_.stop.store(1, std::memory_order_release);
    horus::detail::futex_wake_all(shared_.ping_word);
    int status = 0;
    ::waitpid(pid_, &status, 0);
  }

 private:
  Shared& shared_;
  pid_t pid_ = -1;
};

/// Who publishes on a measured topic: its one publisher (holding the publisher lease), that
/// publisher after a second handle shared the ring, or a single_publisher topic's publisher.
enum class Publishers { one, shared_ring, single };

template <class M>
void topic_latency(std::size_t size, bool blocking, Publishers publishers, std::size_t count,
                   const std::string& region, Shared& shared, std::vector<std::int64_t>& samples) {
  const bool single = publishers == Publishers::single;
  const horus::TopicOptions options{.capacity = kLatencyCapacity, .single_publisher = single};
  // A handle that sent first, before the measured handles open (so they never see it), makes
  // the measured publisher the second one on each topic.
  std::optional<horus::Topic<M>> first_ping;
  std::optional<horus::Topic<M>> first_pong;
  if (publishers == Publishers::shared_ring) {
    first_ping.emplace(ping_name(size, single), options);
    first_pong.emplace(pong_name(size, single), options);
    first_ping->send(M{});
    first_pong->send(M{});
  }
  horus::Topic<M> ping(ping_name(size, single), options);
  horus::Topic<M> pong(pong_name(size, single), options);
  {
    Peer peer(blocking ? (single ? "wake_single" : "wake_topic") : "echo_topic", size, region,
              shared);
    M msg{};
    const std::size_t total = kWarmup + count;
    for (std::size_t i = 0; i < total; ++i) {
      msg.seq = i;
      const std::int64_t start = now_ns();
      ping.send(msg);
      // The reply is used where try_recv() returns it: no extra copy on the measured path.
      std::int64_t end = 0;
      bool intact = false;
      for (;;) {
        if (auto back = blocking ? pong.recv(5s) : pong.try_recv()) {
          end = now_ns();
          intact = back->seq == i;
          break;
        }
        if (blocking) {
          break;
        }
      }
      if (!intact) {
        std::fprintf(stderr, "topic echo lost message %zu\n", i);
        std::exit(2);
      }
      if (i >= kWarmup) {
        samples.push_back(end - start);
      }
    }
    msg.seq = kStop;
    ping.send(msg);
  }
}

void raw_latency(std::size_t size, std::size_t count, const std::string& region, Shared& shared,
                 std::vector<std::int64_t>& samples) {
  shared.ping.seq.store(0);
  shared.pong.seq.store(0);
  std::vector<std::byte> message(size, std::byte{1});
  std::vector<std::byte> local(size);
  Peer peer("echo_raw", size, region, shared);
  const std::size_t total = kWarmup + count;
  for (std::uint64_t seq = 1; seq <= total; ++seq) {
    const std::int64_t start = now_ns();
    std::memcpy(shared.ping.payload, message.data(), size);
    shared.ping.seq.store(seq, std::memory_order_release);
    while (shared.pong.seq.load(std::memory_order_acquire) != seq) {
    }
    std::memcpy(local.data(), shared.pong.payload, size);
    const std::int64_t end = now_ns();
    if (seq > kWarmup) {
      samples.push_back(end - start);
    }
  }
  shared.ping.seq.store(kStop, std::memory_order_release);
}

#if defined(HORUS_BENCH_ICEORYX)
/// The same ping-pong through iceoryx: loan, copy in and publish; the peer polls take().
template <class M>
void iceoryx_latency(std::size_t size, std::size_t count, const std::string& region, Shared& shared,
                     std::vector<std::int64_t>& samples) {
  iceoryx_register("leader");
  iox::popo::Publisher<M> ping(iceoryx_service("ping", size));
  iox::popo::Subscriber<M> pong(iceoryx_service("pong", size));
  Peer peer("echo_iceoryx", size, region, shared);
  wait_for_iceoryx_peer(ping, pong);
  M msg{};
  for (std::size_t i = 0; i < kWarmup + count; ++i) {
    msg.seq = i;
    const std::int64_t start = now_ns();
    iceoryx_publish(ping, msg);
    std::int64_t end = 0;
    bool intact = false;
    while (end == 0) {
      pong.take().and_then([&](auto& back) {
        end = now_ns();
        intact = back->seq == i;
      });
    }
    if (!intact) {
      std::fprintf(stderr, "iceoryx echo lost message %zu\n", i);
      std::exit(2);
    }
    if (i >= kWarmup) {
      samples.push_back(end - start);
    }
  }
}
#endif

void futex_latency(std::size_t count, const std::string& region, Shared& shared,
                   std::vector<std::int64_t>& samples) {
  shared.ping_word.store(0);
  shared.pong_word.store(0);
  Peer peer("echo_futex", 0, region, shared);
  std::uint32_t seen = 0;
  for (std::size_t i = 0; i < kWarmup + count; ++i) {
    const std::int64_t start = now_ns();
    shared.ping_word.fetch_add(1, std::memory_order_release);
    horus::detail::futex_wake_all(shared.ping_word);
    std::uint32_t value = 0;
    while ((value = shared.pong_word.load(std::memory_order_acquire)) == seen) {
      horus::detail::futex_wait(shared.pong_word, seen, 5s);
    }
    seen = value;
    const std::int64_t end = now_ns();
    if (i >= kWarmup) {
      samples.push_back(end - start);
    }
  }
}

struct Throughput {
  double per_s;
  std::uint64_t lost;
  std::uint64_t misordered;
  /// Messages before which the writer found itself a whole window ahead: many when the reader
  /// sets the pace, next to none when the writer does.
  std::uint64_t writer_waits;
};

/// Lossless throughput: the writer stays within half the ring of the reader's last ack. Whether
/// it had to wait.
bool wait_for_reader(std::uint64_t sent, Shared& shared) {
  bool waited = false;
  while (sent - shared.consumed.load(std::memory_order_acquire) >= kWindow) {
    waited = true;
  }
  return waited;
}

/// Runs `write(i)` for every message with `reader` consuming in the second process, or (without
/// a reader) alone: what the writer's own code costs, without the cache-line traffic a subscriber
/// brings.
template <class Write>
Throughput stream(const char* reader, bool with_reader, const std::string& region, Shared& shared,
                  Write&& write) {
  if (!with_reader) {
    const std::int64_t begin = now_ns();
    for (std::uint64_t i = 0; i < kThroughputMessages; ++i) {
      write(i);
    }
    return {kThroughputMessages * 1e9 / static_cast<double>(now_ns() - begin), 0, 0, 0};
  }
  std::int64_t start = 0;
  std::uint64_t waits = 0;
  {
    Peer peer(reader, kRingPayload, region, shared);
    start = now_ns();
    for (std::uint64_t i = 0; i < kThroughputMessages; ++i) {
      waits += wait_for_reader(i, shared) ? 1 : 0;
      write(i);
    }
  }
  return {kThroughputMessages * 1e9 / static_cast<double>(shared.finished_ns.load() - start),
          shared.lost.load(), shared.misordered.load(), waits};
}

/// Message i, filled in by code the hand-over cannot see, as a publisher's is; inlined, the
/// compiler would hand the raw ring's copy the sequence number straight from a register. (A raw
/// ring that copies bytes nobody just wrote is not a floor: on this VM it runs 2-5x faster,
/// because a copy that reads freshly written bytes waits for the store buffer to drain, and the
/// previous message's stores there still wait for their cache lines.)
[[gnu::noinline]] void fill(topic_bench::Msg64& msg, std::uint64_t i) { msg.seq = i; }

/// The writers fill in message i the same way; only the hand-over differs.
template <Publishers Setup>
Throughput send_throughput(const std::string& region, Shared& shared, bool with_reader) {
  constexpr bool kSingle = Setup == Publishers::single;
  horus::Topic<topic_bench::Msg64> topic(kSingle ? "throughput.single" : "throughput",
                                         {.capacity = kRingSlots, .single_publisher = kSingle});
  topic_bench::Msg64 msg{};
  // Sent before the reader opens the topic, so it never sees them.
  std::optional<horus::Topic<topic_bench::Msg64>> second;
  if constexpr (Setup == Publishers::shared_ring) {
    topic.send(msg);
    second.emplace("throughput");
    second->send(msg);
  }
  return stream(kSingle ? "consume_single" : "consume_topic", with_reader, region, shared,
                [&](std::uint64_t i) {
                  fill(msg, i);
                  topic.send(msg);
                });
}

Throughput loan_throughput(const std::string& region, Shared& shared, bool with_reader) {
  horus::Topic<topic_bench::Msg64> topic("throughput.single",
                                         {.capacity = kRingSlots, .single_publisher = true});
  return stream("consume_single", with_reader, region, shared, [&](std::uint64_t i) {
    horus::Loan<topic_bench::Msg64> loan = topic.loan();
    loan->payload = {};
    fill(*loan, i);
    topic.publish(std::move(loan));
  });
}

/// What a raw ring's writer does besides odd sequence, copy, even sequence: nothing (the
/// floor), or one thing a topic's send does that a one-writer raw ring need not, so that thing's
/// cost is measured in the same rounds.
enum class RawExtra {
  none,
  /// The last-send stamp tools read.
  stamp,
  /// A multi-publisher claim: the ticket's fetch_add and the slot's compare-and-swap.
  claim,
};

template <RawExtra Extra>
Throughput raw_throughput(const std::string& region, Shared& shared, bool with_reader) {
  for (RawSlot& slot : shared.ring) {
    slot.seq.store(0);
  }
  for (std::atomic<std::uint64_t>& claim : shared.claims) {
    claim.store(0);
  }
  shared.tickets.store(0);
  topic_bench::Msg64 msg{};
  return stream("consume_raw", with_reader, region, shared, [&](std::uint64_t i) {
    fill(msg, i);
    // Read before the slot's stores, as a topic's send() does.
    const std::uint32_t sent = Extra == RawExtra::stamp ? horus::detail::send_stamp_s() : 0;
    if constexpr (Extra == RawExtra::claim) {
      // The ticket is i: this writer is alone, but pays for the read-modify-writes all the same.
      const std::uint64_t ticket = shared.tickets.fetch_add(1, std::memory_order_seq_cst);
      // The slot's claim from one lap before: released by its commit, or never claimed.
      std::uint64_t expected = ticket >= kRingSlots ? 2 * (ticket - kRingSlots) + 2 : 0;
      shared.claims[ticket % kRingSlots].compare_exchange_strong(
          expected, 2 * ticket + 1, std::memory_order_acquire, std::memory_order_relaxed);
    }
    RawSlot& slot = shared.ring[i % kRingSlots];
    slot.seq.store(2 * i + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    std::memcpy(slot.payload, &msg, sizeof msg);
    if constexpr (Extra == RawExtra::stamp) {
      slot.send_time_s.store(sent, std::memory_order_relaxed);
    }
    slot.seq.store(2 * i + 2, std::memory_order_release);
    if constexpr (Extra == RawExtra::claim) {
      shared.claims[i % kRingSlots].store(2 * i + 2, std::memory_order_release);
    }
  });
}

/// Topic, raw (and iceoryx) runs alternate in rounds, so a disturbance (other load) hits all alike.
constexpr int kRounds = 5;

/// One size's percentiles; iceoryx's stay empty unless it runs side by side.
struct LatencyRow {
  std::size_t size;
  Percentiles topic, raw;
  std::optional<Percentiles> iceoryx;
};

template <class M>
LatencyRow latency_row(std::size_t size, const std::string& region, Shared& shared) {
  std::vector<std::int64_t> topic_samples;
  std::vector<std::int64_t> raw_samples;
  std::vector<std::int64_t> iceoryx_samples;
  const std::size_t count = iterations(size) / kRounds;
  for (int round = 0; round < kRounds; ++round) {
    topic_latency<M>(size, false, Publishers::one, count, region, shared, topic_samples);
    raw_latency(size, count, region, shared, raw_samples);
#if defined(HORUS_BENCH_ICEORYX)
    if (iceoryx_enabled()) {
      iceoryx_latency<M>(size, count, region, shared, iceoryx_samples);
    }
#endif
  }
  LatencyRow row{size, percentiles(topic_samples), percentiles(raw_samples), std::nullopt};
  if (!iceoryx_samples.empty()) {
    row.iceoryx = percentiles(iceoryx_samples);
  }
  std::printf("| %6zu B | %8.0f | %8.0f | %8.0f | %8.0f | %8.0f | %8.0f | %5.2fx | %5.2fx |\n",
              size, row.topic.p50, row.topic.p99, row.topic.p999, row.raw.p50, row.raw.p99,
              row.raw.p999, row.topic.p50 / row.raw.p50, row.topic.p99 / row.raw.p99);
  std::fflush(stdout);
  return row;
}

void print_latency_table(const std::string& region, Shared& shared) {
  std::printf(
      "Latency is one-way (round trip / 2) in ns; ratio = Topic / raw.\n\n"
      "| size | topic p50 | topic p99 | topic p99.9 | raw p50 | raw p99 | raw p99.9 | p50 ratio | "
      "p99 ratio |\n");
  std::printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  std::vector<LatencyRow> rows;
  for_each_latency_message(
      [&]<class M>() { rows.push_back(latency_row<M>(sizeof(M), region, shared)); });
#if defined(HORUS_BENCH_ICEORYX)
  if (!iceoryx_enabled()) {
    return;
  }
  // HORUS_BENCH_ICEORYX is the version CMake found.
  std::printf(
      "\niceoryx %s (Debian) side by side, in the same rounds: its publisher loans a chunk, "
      "copies the message in and publishes; its subscriber polls take(). One-way in ns.\n\n"
      "| size | topic p50 | iceoryx p50 | iceoryx p99 | iceoryx p99.9 | raw p50 | iceoryx / raw "
      "p50 | topic / iceoryx p50 | topic / iceoryx p99 |\n"
      "|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
      HORUS_BENCH_ICEORYX);
  for (const LatencyRow& row : rows) {
    const Percentiles& iceoryx = *row.iceoryx;
    std::printf("| %6zu B | %8.0f | %8.0f | %8.0f | %8.0f | %8.0f | %5.2fx | %5.2fx | %5.2fx |\n",
                row.size, row.topic.p50, iceoryx.p50, iceoryx.p99, iceoryx.p999, row.raw.p50,
                iceoryx.p50 / row.raw.p50, row.topic.p50 / iceoryx.p50,
                row.topic.p99 / iceoryx.p99);
  }
#endif
}

void print_wakeup_table(const std::string& region, Shared& shared) {
  std::vector<std::int64_t> wake_samples;
  std::vector<std::int64_t> shared_samples;
  std::vector<std::int64_t> single_samples;
  std::vector<std::int64_t> futex_samples;
  for (int round = 0; round < kRounds; ++round) {
    topic_latency<topic_bench::Msg64>(64, true, Publishers::one, 1000, region, shared,
                                      wake_samples);
    topic_latency<topic_bench::Msg64>(64, true, Publishers::shared_ring, 1000, region, shared,
                                      shared_samples);
    topic_latency<topic_bench::Msg64>(64, true, Publishers::single, 1000, region, shared,
                                      single_samples);
    futex_latency(1000, region, shared, futex_samples);
  }
  const Percentiles futex = percentiles(futex_samples);
  std::printf(
      "\nBlocking wake-up, one-way in ns (Topic recv() vs raw futex ping-pong); ratio = Topic / "
      "futex:\n\n");
  std::printf("| | p50 | p99 | p99.9 | p50 ratio | p99 ratio |\n|---|---:|---:|---:|---:|---:|\n");
  const auto row = [&futex](const char* label, const Percentiles& wake) {
    std::printf("| %s | %.0f | %.0f | %.0f | %.2fx | %.2fx |\n", label, wake.p50, wake.p99,
                wake.p999, wake.p50 / futex.p50, wake.p99 / futex.p99);
  };
  row("Topic<Msg64> recv(timeout)", percentiles(wake_samples));
  row("Topic<Msg64> recv(timeout), ring shared by two publishers", percentiles(shared_samples));
  row("Topic<Msg64> recv(timeout), single_publisher", percentiles(single_samples));
  row("raw futex", futex);
}

/// Throughput rounds: every row runs once per round, so rows of one round share the machine's
/// state, and a row's ratio is the median of its per-round ratios to the floor. A writer and a
/// spinning reader settle into being paced by the writer (the reader keeps up and polls the slot
/// being written, whose lines cross cores several times) or by the reader (the writer runs a
/// window ahead, lines cross once), and on a shared VM the neighbours' load changes from second
/// to second: single rounds swing by 2-5x, pairs of rounds far less.
constexpr int kThroughputRounds = 9;

struct Rates {
  const char* label;
  Throughput (*run)(const std::string&, Shared&, bool with_reader);
  std::vector<double> per_s{};
  std::vector<double> ratios{};
  std::vector<double> writer_waits{};
  std::uint64_t lost = 0;
  std::uint64_t misordered = 0;
};

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

void print_throughput_table(const std::string& region, Shared& shared) {
  Rates rows[] = {{"raw seqlock ring (floor)", raw_throughput<RawExtra::none>},
                  {"raw seqlock ring + the topic's last-send stamp per message (reference)",
                   raw_throughput<RawExtra::stamp>},
                  {"raw seqlock ring + a multi-publisher claim per message (reference)",
                   raw_throughput<RawExtra::claim>},
                  {"Topic<Msg64> send()", send_throughput<Publishers::one>},
                  {"Topic<Msg64> send(), ring shared by two publishers",
                   send_throughput<Publishers::shared_ring>},
                  {"Topic<Msg64> send(), single_publisher", send_throughput<Publishers::single>},
                  {"Topic<Msg64> loan() + publish(), single_publisher", loan_throughput}};
  for (int round = 0; round < kThroughputRounds; ++round) {
    for (Rates& row : rows) {
      const Throughput result = row.run(region, shared, true);
      row.per_s.push_back(result.per_s);
      row.ratios.push_back(result.per_s / rows[0].per_s.back());
      row.writer_waits.push_back(static_cast<double>(result.writer_waits));
      row.lost += result.lost;
      row.misordered += result.misordered;
    }
  }
  std::printf(
      "\nThroughput, 64 B messages through 1024 slots, %llu messages per round, the writer at most "
      "%llu ahead of the reader (lossless); %d rounds, each running every row once; msg/s: "
      "median (min-max); ratio: median of the per-round ratios to the floor; writer waits: median "
      "per round of the messages before which the writer found itself a whole window ahead "
      "(thousands when the reader sets the pace, tens when the writer does):\n\n",
      static_cast<unsigned long long>(kThroughputMessages),
      static_cast<unsigned long long>(kWindow), kThroughputRounds);
  std::printf("| | msg/s | min | max | lost | misordered | ratio | writer waits |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const Rates& row : rows) {
    std::printf("| %s | %.3g | %.3g | %.3g | %llu | %llu | %.2fx | %.0f |\n", row.label,
                median(row.per_s), *std::min_element(row.per_s.begin(), row.per_s.end()),
                *std::max_element(row.per_s.begin(), row.per_s.end()),
                static_cast<unsigned long long>(row.lost),
                static_cast<unsigned long long>(row.misordered), median(row.ratios),
                median(row.writer_waits));
  }

  // The same writers with nobody reading: the difference to the table above is what the
  // subscriber's cache-line traffic costs each one.
  std::printf(
      "\nEach writer alone (nobody reading, the ring lapping), ns per message: median of %d "
      "rounds:\n\n| | ns per message |\n|---|---:|\n",
      kThroughputRounds);
  for (Rates& row : rows) {
    std::vector<double> ns;
    for (int round = 0; round < kThroughputRounds; ++round) {
      ns.push_back(1e9 / row.run(region, shared, false).per_s);
    }
    std::printf("| %s | %.1f |\n", row.label, median(ns));
  }
}

}  // namespace

/// Arguments name the tables to print (latency, wakeup, throughput); none prints all three.
int main(int argc, char** argv) {
  if (argc == 5 && std::string(argv[1]) == "--role") {
    return run_role(argv[2], std::stoul(argv[3]), argv[4]);
  }
  std::vector<std::string> tables(argv + 1, argv + argc);
  if (tables.empty()) {
    tables = {"latency", "wakeup", "throughput"};
  }
  for (const std::string& table : tables) {
    if (table != "latency" && table != "wakeup" && table != "throughput") {
      std::fprintf(stderr, "usage: %s [latency] [wakeup] [throughput]\n", argv[0]);
      return 2;
    }
  }
  const std::string ns = "bench" + std::to_string(::getpid());
  ::setenv("HORUS_NAMESPACE", ns.c_str(), 1);
  const std::string region = "/horus_topic_bench_" + std::to_string(::getpid());
  Shared& shared = *map_shared(region, true);
  pin(0);

  std::printf("Topic<T> vs raw shared memory, processes pinned to CPUs 0 and 1 (%u CPUs online).\n",
              std::thread::hardware_concurrency());
  for (const std::string& table : tables) {
    if (table == "latency") {
      print_latency_table(region, shared);
    } else if (table == "wakeup") {
      print_wakeup_table(region, shared);
    } else {
      print_throughput_table(region, shared);
    }
    std::fflush(stdout);
  }

  ::shm_unlink(region.c_str());
  horus::remove_namespace(ns);
  return 0;
}
