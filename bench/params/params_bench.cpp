// Parameters between two processes, against floors measured in the same run:
//
//   reads   a process reads an f64, an i32 and a String parameter of a node another process owns,
//           in a loop, against reading a plain word of shared memory (an mmap'd atomic) the same
//           way; also the same String's bytes copied out of shared memory without any protocol,
//           and ParamStoreReader::get(), the tools' way (a declaration copy and MessagePack).
//   writes  set_param() in this process until on_param_change() runs in the owner and until
//           set_param() returns, against a ROS-2-style parameter service built from HORUS's own
//           services (a ServiceServer whose handler checks the value, updates a map and calls a
//           callback), requests of the same size.
//
//   params_bench [writes, default 4000] [reads per block, default 200000]
//
// Prints Markdown. The reader/writer pins itself to CPU 0, the owner to CPU 1.
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <msgpack.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <horus/literals.hpp>
#include <horus/node.hpp>
#include <horus/params.hpp>
#include <horus/scheduler.hpp>
#include <horus/service.hpp>
#include <horus/topic_registry.hpp>
#include <params_bench/set_parameter.hpp>
#include <params_bench/set_parameter_handed_off.hpp>

namespace {

using namespace std::chrono_literals;
using namespace horus::literals;
using Clock = std::chrono::steady_clock;
using params_bench::SetParameter;
using params_bench::SetParameterHandedOff;
using params_bench::SetParameterHandedOffRequest;
using params_bench::SetParameterHandedOffResponse;
using params_bench::SetParameterRequest;
using params_bench::SetParameterResponse;

constexpr int kClientCore = 0;
constexpr int kOwnerCore = 1;
constexpr const char* kNode = "bench_params";
constexpr const char* kFrame = "base_link";
constexpr int kBlocks = 40;

bool pin(int core) {
  if (static_cast<int>(::sysconf(_SC_NPROCESSORS_ONLN)) <= core) return false;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(core, &set);
  return ::sched_setaffinity(0, sizeof set, &set) == 0;
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

/// Keeps a value the compiler would otherwise drop, and every load in the loop with it.
template <class T>
void keep(const T& value) {
  asm volatile("" : : "r,m"(value) : "memory");
}

/// Shared by both processes (an anonymous shared mapping made before fork).
struct Shared {
  alignas(64) std::atomic<std::uint64_t> plain_word{0};
  alignas(64) std::atomic<std::uint64_t> plain_size{0};
  char plain_bytes[64]{};
  alignas(64) std::atomic<std::int64_t> param_callback_ns{0};
  std::atomic<std::int64_t> service_callback_ns{0};
  std::atomic<std::int64_t> handoff_callback_ns{0};
  std::atomic<std::uint32_t> ready{0};
  std::atomic<std::uint32_t> stop{0};
};

std::string packed_double(double value) {
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  packer.pack_double(value);
  return {buffer.data(), buffer.size()};
}

/// The payload HORUS's own write sends: a MessagePack map {name, value, source, timeout_ns}
/// inside a Vec<u8> (runtime/src/params/README.md), used here only for its size.
std::size_t horus_request_size(const std::string& name, const std::string& value,
                               const std::string& source) {
  msgpack::sbuffer body;
  msgpack::packer<msgpack::sbuffer> packer(body);
  packer.pack_map(4);
  packer.pack(std::string("name"));
  packer.pack(name);
  packer.pack(std::string("value"));
  packer.pack_bin(static_cast<std::uint32_t>(value.size()));
  packer.pack_bin_body(value.data(), static_cast<std::uint32_t>(value.size()));
  packer.pack(std::string("source"));
  packer.pack(source);
  packer.pack(std::string("timeout_ns"));
  packer.pack_uint64(5'000'000'000ULL);
  const std::vector<std::uint8_t> bytes(body.data(), body.data() + body.size());
  return horus::encode(bytes).size();
}

// ---- The owner: a node with three parameters, and the ROS-2-style service beside it ----------

class BenchNode : public horus::Node {
 public:
  explicit BenchNode(Shared& shared) : shared_(shared) {}
  std::string_view name() const override { return kNode; }
  void tick() override {}
  horus::ParamVerdict on_param_change(const horus::ParamChange&) override {
    shared_.param_callback_ns.store(now_ns(), std::memory_order_release);
    return horus::ParamVerdict::accept();
  }

 private:
  Shared& shared_;
  horus::Param<double> max_speed_ =
      declare_param<double>("max_speed", 1.0, {.min = 0.0, .max = 2.0, .unit = "m/s"});
  horus::Param<std::int32_t> retries_ = declare_param<std::int32_t>("retries", 3);
  horus::Param<std::string> frame_id_ = declare_param<std::string>("frame_id", kFrame);
};

/// What a ROS 2 node's parameter service does with one SetParameters request: find the
/// parameter, check the value against its descriptor, store it, call the user's callback.
class ServiceParameters {
 public:
  explicit ServiceParameters(std::function<void(const std::string&)> on_change)
      : on_change_(std::move(on_change)) {
    values_["max_speed"] = {packed_double(1.0), 1};
  }
  SetParameterResponse set(const SetParameterRequest& request) {
    std::lock_guard lock(mutex_);
    const auto found = values_.find(request.name);
    if (found == values_.end()) return {false, "no parameter " + request.name, 0};
    const msgpack::object_handle handle =
        msgpack::unpack(reinterpret_cast<const char*>(request.value.data()), request.value.size());
    const double value = handle.get().as<double>();
    if (value < 0.0 || value > 2.0) return {false, "out of range", found->second.version};
    found->second.value.assign(request.value.begin(), request.value.end());
    on_change_(request.name);
    return {true, "", ++found->second.version};
  }

 private:
  struct Value {
    std::string value;
    std::uint64_t version;
  };
  std::function<void(const std::string&)> on_change_;
  std::mutex mutex_;
  std::map<std::string, Value> values_;
};

[[noreturn]] void own(Shared& shared) {
  pin(kOwnerCore);
  auto node = std::make_shared<BenchNode>(shared);
  horus::Scheduler scheduler(horus::SchedulerConfig{}.tick_rate(100_hz).handle_signals(false));
  scheduler.add(node).rate(100_hz).build();
  std::thread ticking([&] { scheduler.run(); });
  ServiceParameters parameters([&](const std::string&) {
    shared.service_callback_ns.store(now_ns(), std::memory_order_release);
  });
  auto server =
      horus::ServiceServerBuilder<SetParameter>()
          .on_request([&](const SetParameterRequest& request) { return parameters.set(request); })
          .build();
  // The same, with each change applied on a thread of its own (a mutex, a condition variable
  // and a queue), the server waiting for its verdict.
  ServiceParameters handed_parameters([&](const std::string&) {
    shared.handoff_callback_ns.store(now_ns(), std::memory_order_release);
  });
  std::mutex handoff_mutex;
  std::condition_variable handoff_changed;
  std::optional<SetParameterRequest> handed;
  std::optional<SetParameterResponse> verdict;
  bool stopping = false;
  std::thread applying([&] {
    std::unique_lock lock(handoff_mutex);
    for (;;) {
      handoff_changed.wait(lock, [&] { return handed.has_value() || stopping; });
      if (stopping) return;
      verdict = handed_parameters.set(*handed);
      handed.reset();
      handoff_changed.notify_all();
    }
  });
  auto handing_server =
      horus::ServiceServerBuilder<SetParameterHandedOff>()
          .on_request([&](const SetParameterHandedOffRequest& request) {
            std::unique_lock lock(handoff_mutex);
            handed = SetParameterRequest{request.name, request.value, request.source,
                                         request.timeout_ns};
            handoff_changed.notify_all();
            handoff_changed.wait(lock, [&] { return verdict.has_value(); });
            const SetParameterResponse answer = *verdict;
            verdict.reset();
            return SetParameterHandedOffResponse{answer.accepted, answer.reason, answer.version};
          })
          .build();
  shared.ready.store(1, std::memory_order_release);
  while (shared.stop.load(std::memory_order_acquire) == 0) std::this_thread::sleep_for(10ms);
  handing_server.stop();
  {
    std::lock_guard lock(handoff_mutex);
    stopping = true;
  }
  handoff_changed.notify_all();
  applying.join();
  server.stop();
  scheduler.stop();
  ticking.join();
  ::_exit(0);
}

// ---- Reads -----------------------------------------------------------------------------------

struct ReadContender {
  const char* label;
  std::function<int(int)> read;  // reads about n times; how many it read
  std::vector<double> ns_per_read;
};

/// Each contender reads `per_block` times per block, in interleaved blocks; ns per read of each
/// block.
void measure_reads(std::vector<ReadContender>& contenders, int per_block) {
  for (int block = 0; block < kBlocks; ++block) {
    for (ReadContender& contender : contenders) {
      contender.read(per_block / 10 + 1);
      const auto start = Clock::now();
      const int done = contender.read(per_block);
      contender.ns_per_read.push_back(
          std::chrono::duration<double, std::nano>(Clock::now() - start).count() / done);
    }
  }
}

// ---- Writes ----------------------------------------------------------------------------------

struct WriteContender {
  const char* label;
  std::function<bool(int)> write;
  const std::atomic<std::int64_t>* callback_ns;
  std::vector<double> to_callback_us;
  std::vector<double> to_return_us;
};

void measure_writes(std::vector<WriteContender>& contenders, int writes) {
  const int per_block = std::max(1, writes / kBlocks);
  int sequence = 0;
  for (int block = 0; block < kBlocks; ++block) {
    for (WriteContender& contender : contenders) {
      for (int i = 0; i < per_block / 10 + 1; ++i) {
        if (!contender.write(++sequence)) {
          std::fprintf(stderr, "%s: warm-up write refused\n", contender.label);
          std::exit(1);
        }
      }
      for (int i = 0; i < per_block; ++i) {
        const std::int64_t before = contender.callback_ns->load(std::memory_order_acquire);
        const std::int64_t start = now_ns();
        if (!contender.write(++sequence)) {
          std::fprintf(stderr, "%s: write refused\n", contender.label);
          std::exit(1);
        }
        const std::int64_t end = now_ns();
        const std::int64_t called = contender.callback_ns->load(std::memory_order_acquire);
        if (called == before) {
          std::fprintf(stderr, "%s: the callback did not run before the write returned\n",
                       contender.label);
          std::exit(1);
        }
        contender.to_callback_us.push_back(static_cast<double>(called - start) / 1000.0);
        contender.to_return_us.push_back(static_cast<double>(end - start) / 1000.0);
      }
    }
  }
}

double quantile(std::vector<double> samples, double q) {
  std::sort(samples.begin(), samples.end());
  return samples[std::min(samples.size() - 1,
                          static_cast<std::size_t>(q * static_cast<double>(samples.size())))];
}

}  // namespace

int main(int argc, char** argv) {
  const int writes = argc > 1 ? std::atoi(argv[1]) : 4000;
  const int reads_per_block = argc > 2 ? std::atoi(argv[2]) : 200000;
  const std::string ns = "bench_params_" + std::to_string(::getpid());
  ::setenv("HORUS_NAMESPACE", ns.c_str(), 1);
  horus::remove_namespace(ns);

  void* memory =
      ::mmap(nullptr, sizeof(Shared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  auto* shared = new (memory) Shared{};
  shared->plain_word.store(std::bit_cast<std::uint64_t>(1.0));
  shared->plain_size.store(std::strlen(kFrame));
  std::memcpy(shared->plain_bytes, kFrame, std::strlen(kFrame));
  // The owner is forked before this process makes any thread.
  const pid_t owner = ::fork();
  if (owner == 0) own(*shared);
  const bool pinned = pin(kClientCore);
  const auto give_up = [&](const char* why) {
    std::fprintf(stderr, "%s\n", why);
    ::kill(owner, SIGKILL);
    ::waitpid(owner, nullptr, 0);
    horus::remove_namespace(ns);
    std::exit(1);
  };
  std::vector<ReadContender> reads;
  std::vector<WriteContender> contenders;
  std::size_t horus_size = 0;
  std::size_t service_size = 0;
  // Every HORUS handle of this process ends with this block, before the namespace is removed.
  {
    const auto deadline = Clock::now() + 20s;
    while (shared->ready.load(std::memory_order_acquire) == 0) {
      if (Clock::now() > deadline) give_up("the owner process never started");
      std::this_thread::sleep_for(10ms);
    }
    std::optional<horus::ParamStoreReader> reader;
    while (!reader || !reader->owner_alive()) {
      if (Clock::now() > deadline) give_up("the owner never opened its parameter store");
      try {
        reader.emplace(kNode);
      } catch (const horus::Error&) {
        std::this_thread::sleep_for(10ms);
      }
    }
    horus::ServiceClient<SetParameter> client;
    horus::ServiceClient<SetParameterHandedOff> handing_client;
    if (!client.wait_for_server(10s) || !handing_client.wait_for_server(10s)) {
      give_up("the ROS-2-style parameter services never registered");
    }

    // Reads.
    const horus::Param<double> max_speed = reader->param<double>("max_speed");
    const horus::Param<std::int32_t> retries = reader->param<std::int32_t>("retries");
    const horus::Param<std::string> frame_id = reader->param<std::string>("frame_id");
    if (max_speed.get() != 1.0 || retries.get() != 3 || frame_id.get() != kFrame) {
      give_up("the reader does not see the owner's values");
    }
    const std::atomic<std::uint64_t>& word = shared->plain_word;
    reads.push_back({"plain shared-memory word (floor): atomic load",
                     [&](int n) {
                       for (int i = 0; i < n; ++i) keep(word.load(std::memory_order_acquire));
                       return n;
                     },
                     {}});
    reads.push_back({"f64 parameter: `Param<double>::get()`",
                     [&](int n) {
                       for (int i = 0; i < n; ++i) keep(max_speed.get());
                       return n;
                     },
                     {}});
    reads.push_back({"i32 parameter: `Param<std::int32_t>::get()`",
                     [&](int n) {
                       for (int i = 0; i < n; ++i) keep(retries.get());
                       return n;
                     },
                     {}});
    reads.push_back({"plain shared-memory bytes into a `std::string` (9 bytes, no protocol)",
                     [&](int n) {
                       for (int i = 0; i < n; ++i) {
                         const std::string text(shared->plain_bytes,
                                                shared->plain_size.load(std::memory_order_acquire));
                         keep(text.data());
                       }
                       return n;
                     },
                     {}});
    reads.push_back({"String parameter: `Param<std::string>::get()` (9 bytes)",
                     [&](int n) {
                       for (int i = 0; i < n; ++i) {
                         const std::string text = frame_id.get();
                         keep(text.data());
                       }
                       return n;
                     },
                     {}});
    reads.push_back(
        {"f64 parameter: `ParamStoreReader::get()` + MessagePack decode (tools' way)",
         [&](int n) {
           // Far slower: a hundredth as many reads.
           const int count = n / 100 + 1;
           for (int i = 0; i < count; ++i) {
             const horus::ParamInfo info = reader->get("max_speed");
             keep(msgpack::unpack(info.value.data(), info.value.size()).get().as<double>());
           }
           return count;
         },
         {}});
    measure_reads(reads, reads_per_block);

    // Writes: the same value size (an f64) and the same request size.
    const std::string program = "params_bench";
    horus_size = horus_request_size("max_speed", packed_double(1.5), program);
    SetParameterRequest service_request{"max_speed", {}, program, 5'000'000'000LL};
    {
      const std::string value = packed_double(1.5);
      service_request.value.assign(value.begin(), value.end());
      while (horus::encode(service_request).size() < horus_size) {
        service_request.source.push_back('.');
      }
      service_size = horus::encode(service_request).size();
    }
    const auto speed_of = [](int sequence) { return 0.5 + 0.001 * (sequence % 1000); };
    horus::ParamSetOptions options;
    options.source = program;
    contenders.push_back({"ROS-2-style parameter service (a ServiceServer, a map, a callback)",
                          [&](int sequence) {
                            const std::string value = packed_double(speed_of(sequence));
                            service_request.value.assign(value.begin(), value.end());
                            const auto answer = client.call(service_request, 5s);
                            return answer.has_value() && answer->accepted;
                          },
                          &shared->service_callback_ns,
                          {},
                          {}});
    SetParameterHandedOffRequest handing_request{service_request.name, service_request.value,
                                                 service_request.source,
                                                 service_request.timeout_ns};
    contenders.push_back(
        {"the same service, applying on another thread (the hop to a node's thread)",
         [&](int sequence) {
           const std::string value = packed_double(speed_of(sequence));
           handing_request.value.assign(value.begin(), value.end());
           const auto answer = handing_client.call(handing_request, 5s);
           return answer.has_value() && answer->accepted;
         },
         &shared->handoff_callback_ns,
         {},
         {}});
    contenders.push_back({"`set_param()` to the owner's `on_param_change()`",
                          [&](int sequence) {
                            return horus::set_param(kNode, "max_speed",
                                                    packed_double(speed_of(sequence)), options)
                                .accepted;
                          },
                          &shared->param_callback_ns,
                          {},
                          {}});
    measure_writes(contenders, writes);
  }

  shared->stop.store(1, std::memory_order_release);
  ::waitpid(owner, nullptr, 0);
  horus::remove_namespace(ns);

  std::printf(
      "Reader/writer and owner %s. Reads: %d blocks of %d reads per row, interleaved; "
      "writes: %d per row in %d interleaved blocks.\n\n",
      pinned ? "pinned to CPUs 0 and 1" : "not pinned (fewer than 2 CPUs)", kBlocks,
      reads_per_block, writes, kBlocks);
  std::printf("### Reading a parameter another process owns\n\n");
  std::printf("| read | ns/read (median block) | best block | / plain word |\n");
  std::printf("|---|---:|---:|---:|\n");
  const double floor = quantile(reads.front().ns_per_read, 0.5);
  for (const ReadContender& contender : reads) {
    const double median = quantile(contender.ns_per_read, 0.5);
    std::printf("| %s | %.2f | %.2f | %.2fx |\n", contender.label, median,
                quantile(contender.ns_per_read, 0.0), median / floor);
  }
  std::printf(
      "\n### A write until the owner's callback runs, and until the writer has the "
      "answer\n\n");
  std::printf("Requests: %zu bytes (HORUS's write), %zu bytes (the service's).\n\n", horus_size,
              service_size);
  std::printf(
      "| write | to callback p50 (us) | p99 (us) | to return p50 (us) | p99 (us) | "
      "p50 / service | p99 / service |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|\n");
  const double service_p50 = quantile(contenders.front().to_callback_us, 0.5);
  const double service_p99 = quantile(contenders.front().to_callback_us, 0.99);
  for (const WriteContender& contender : contenders) {
    const double p50 = quantile(contender.to_callback_us, 0.5);
    const double p99 = quantile(contender.to_callback_us, 0.99);
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f | %.2fx | %.2fx |\n", contender.label, p50, p99,
                quantile(contender.to_return_us, 0.5), quantile(contender.to_return_us, 0.99),
                p50 / service_p50, p99 / service_p99);
  }
  return 0;
}
