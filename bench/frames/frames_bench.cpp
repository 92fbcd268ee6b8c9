// Frames against tf2, one run: a lookup of a 5-deep chain (map <- f5) at a past time and at the
// latest common time, HORUS from another process than its writer, tf2::BufferCore in-process
// with its feeder thread, both fed the same 20-frame tree at 100 Hz; then the memory of 10
// processes using frames (one shared tree against 10 tf2 buffers). Every answer timed is checked
// against the stream's own formulas composed by hand; a wrong one fails the run. run.sh runs it.
//
//   frames_bench [BLOCKS LOOKUPS]       the tables, in Markdown, on stdout
//   frames_bench writer|horus-user|tf2-user|idle ...   the roles of the processes it starts
#include <sched.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <new>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "horus/clock.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/frames.hpp"
#include "tf2_side.hpp"

namespace {
/// Allocations made by this thread: the measuring thread's, not a feeder's.
thread_local long thread_allocations = 0;
}  // namespace

// Counted replacements of the global allocator (they apply to libtf2 too).
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t size) {
  ++thread_allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace {

using namespace std::chrono_literals;
using std::chrono::nanoseconds;

// ---------------------------------------------------------------------------------------------
// The stream both sides are fed: map <- f1 <- ... <- f5 (the chain looked up) and 14 side frames
// under f1..f5, f19 static. Translations move linearly and rotations turn at a constant rate
// about a fixed axis, so interpolating between two entries is exact and any time has a known
// answer; the rotations are far from the identity, so slerp does real work.

constexpr int kFrames = 20;
constexpr int kChainTip = 5;
constexpr int kStaticFrame = 19;
constexpr nanoseconds kPeriod = 10ms;  // 100 Hz
constexpr double kHistorySeconds = 10;
/// How far back the past-time lookups ask: mid-history, between two entries most of the time.
constexpr nanoseconds kPast = 5s;

std::string frame_name(int i) {
  if (i == 0) return "map";
  std::string name = "f";  // appended, not "f" + ...: GCC 12 warns falsely (-Wrestrict) on that
  name += std::to_string(i);
  return name;
}
int parent_index(int i) { return i <= kChainTip ? i - 1 : 1 + i % kChainTip; }

struct Pose {
  double t[3];
  double q[4];  // x, y, z, w
};

/// Frame i's transform to its parent at `seconds` after the stream's start.
Pose frame_pose(int i, double seconds) {
  if (i == kStaticFrame) seconds = 0;
  double axis[3] = {1, 0.3 * i, 2 - 0.1 * i};
  const double norm = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  const double half = (0.3 + 0.02 * i * seconds) / 2;
  Pose p{};
  for (int k = 0; k < 3; ++k) p.q[k] = axis[k] / norm * std::sin(half);
  p.q[3] = std::cos(half);
  p.t[0] = 0.5 + 0.01 * i * seconds;
  p.t[1] = 0.1 * i - 0.02 * seconds;
  p.t[2] = 0.05 * i;
  return p;
}

Pose compose(const Pose& a, const Pose& b) {
  const double* p = a.q;
  const double* q = b.q;
  Pose out{};
  out.q[0] = p[3] * q[0] + p[0] * q[3] + p[1] * q[2] - p[2] * q[1];
  out.q[1] = p[3] * q[1] - p[0] * q[2] + p[1] * q[3] + p[2] * q[0];
  out.q[2] = p[3] * q[2] + p[0] * q[1] - p[1] * q[0] + p[2] * q[3];
  out.q[3] = p[3] * q[3] - p[0] * q[0] - p[1] * q[1] - p[2] * q[2];
  // b's translation rotated by a: v + 2w(u x v) + 2u x (u x v), u = a's vector part.
  const double* v = b.t;
  const double c[3] = {p[1] * v[2] - p[2] * v[1], p[2] * v[0] - p[0] * v[2],
                       p[0] * v[1] - p[1] * v[0]};
  const double cc[3] = {p[1] * c[2] - p[2] * c[1], p[2] * c[0] - p[0] * c[2],
                        p[0] * c[1] - p[1] * c[0]};
  for (int k = 0; k < 3; ++k) out.t[k] = a.t[k] + v[k] + 2 * p[3] * c[k] + 2 * cc[k];
  return out;
}

/// The hand computation: map <- f5 at `stamp`, f1's transform after f2's ... after f5's.
Pose expected_chain(nanoseconds start, nanoseconds stamp) {
  const double seconds = static_cast<double>((stamp - start).count()) / 1e9;
  Pose out = frame_pose(1, seconds);
  for (int i = 2; i <= kChainTip; ++i) out = compose(out, frame_pose(i, seconds));
  return out;
}

bool matches(const Pose& expected, const double t[3], const double q[4]) {
  double dot = 0;
  for (int k = 0; k < 4; ++k) dot += expected.q[k] * q[k];
  return std::abs(expected.t[0] - t[0]) < 1e-6 && std::abs(expected.t[1] - t[1]) < 1e-6 &&
         std::abs(expected.t[2] - t[2]) < 1e-6 && std::abs(std::abs(dot) - 1) < 1e-9;
}

void check(bool ok, const std::string& what) {
  if (!ok) throw std::runtime_error("wrong answer: " + what);
}

void check_horus(const horus::Transform& got, const Pose& expected, const std::string& what) {
  const double t[3] = {got.translation.x, got.translation.y, got.translation.z};
  const double q[4] = {got.rotation.x, got.rotation.y, got.rotation.z, got.rotation.w};
  check(matches(expected, t, q), what);
}

/// A latest-common-time answer is the chain at one of the stream's stamps: the newest ones.
void check_latest_horus(const horus::Transform& got, nanoseconds start, const std::string& what) {
  const double t[3] = {got.translation.x, got.translation.y, got.translation.z};
  const double q[4] = {got.rotation.x, got.rotation.y, got.rotation.z, got.rotation.w};
  const std::int64_t newest = (horus::now() - start) / kPeriod;
  for (std::int64_t k = newest; k >= 0 && k > newest - 100; --k) {
    if (matches(expected_chain(start, start + k * kPeriod), t, q)) return;
  }
  check(false, what);
}

// ---------------------------------------------------------------------------------------------
// Feeding the stream (HORUS's writer process and tf2's feeder thread run the same loop).

using SetFrame = std::function<void(int frame, nanoseconds stamp, const Pose&, bool is_static)>;

/// Writes the static frame, then every dynamic frame at each 10 ms stamp from `start`: those
/// already past at once (the history a running robot would have), then in real time.
/// `caught_up` runs once, at the first stamp still ahead; returns when `stop` is set.
void feed(nanoseconds start, const SetFrame& set, const std::function<void()>& caught_up,
          const std::atomic<bool>& stop) {
  set(kStaticFrame, start, frame_pose(kStaticFrame, 0), true);
  bool behind = true;
  for (std::int64_t k = 0; !stop.load(std::memory_order_relaxed); ++k) {
    const nanoseconds stamp = start + k * kPeriod;
    if (stamp > horus::now()) {
      if (behind) caught_up();
      behind = false;
      std::this_thread::sleep_until(std::chrono::system_clock::time_point(
          std::chrono::duration_cast<std::chrono::system_clock::duration>(stamp)));
    }
    const double seconds = static_cast<double>((stamp - start).count()) / 1e9;
    for (int i = 1; i < kFrames; ++i) {
      if (i != kStaticFrame) set(i, stamp, frame_pose(i, seconds), false);
    }
  }
}

horus::Transform to_transform(const Pose& p) {
  return {{p.t[0], p.t[1], p.t[2]}, {p.q[0], p.q[1], p.q[2], p.q[3]}};
}

std::vector<std::string> all_names() {
  std::vector<std::string> names;
  for (int i = 0; i < kFrames; ++i) names.push_back(frame_name(i));
  return names;
}

void pin_to(int cpu) {
  if (cpu < 0) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu % static_cast<int>(std::thread::hardware_concurrency()), &set);
  ::sched_setaffinity(0, sizeof(set), &set);
}

void signal_ready(int fd) {
  if (::write(fd, "r", 1) != 1) std::_Exit(3);
  ::close(fd);
}

[[noreturn]] void wait_to_be_killed() {
  for (;;) ::pause();
}

horus::FrameTreeOptions tree_options(const std::string& namespace_name) {
  horus::FrameTreeOptions options;
  options.namespace_name = namespace_name;
  options.history =
      std::chrono::duration_cast<nanoseconds>(std::chrono::duration<double>(kHistorySeconds));
  return options;
}

// ---------------------------------------------------------------------------------------------
// The roles of the processes the benchmark starts.

/// The frames' authority: sets the 19 transforms at 100 Hz until killed.
int run_writer(const std::string& namespace_name, nanoseconds start, int ready_fd, int cpu) {
  pin_to(cpu);
  horus::FrameTree tree(tree_options(namespace_name));
  const std::vector<std::string> names = all_names();
  const std::atomic<bool> never{false};
  feed(
      start,
      [&](int i, nanoseconds stamp, const Pose& pose, bool is_static) {
        if (is_static) {
          tree.set_static_transform(names[parent_index(i)], names[i], to_transform(pose));
        } else {
          tree.set_transform(names[parent_index(i)], names[i], to_transform(pose), stamp);
        }
      },
      [&] { signal_ready(ready_fd); }, never);
  return 0;
}

/// What a node using frames does: looks up every frame in map, for `seconds`, then stays.
int run_horus_user(const std::string& namespace_name, int ready_fd) {
  horus::FrameTree tree(tree_options(namespace_name));
  const std::vector<std::string> names = all_names();
  const auto until = std::chrono::steady_clock::now() + 2s;
  while (std::chrono::steady_clock::now() < until) {
    const nanoseconds past = horus::now() - kPast;
    for (int i = 1; i < kFrames; ++i) {
      tree.lookup("map", names[i], past);
      tree.lookup("map", names[i]);
    }
    std::this_thread::sleep_for(1ms);
  }
  signal_ready(ready_fd);
  wait_to_be_killed();
}

/// A ROS node's tf2 buffer, fed by its own thread (its /tf subscription) and looked up the same.
int run_tf2_user(nanoseconds start, int ready_fd) {
  frames_bench::Tf2Buffer buffer(kHistorySeconds);
  const std::vector<std::string> names = all_names();
  std::atomic<bool> fed{false};
  std::atomic<bool> stop{false};
  std::thread feeder([&] {
    feed(
        start,
        [&](int i, nanoseconds stamp, const Pose& pose, bool is_static) {
          buffer.set(names[parent_index(i)], names[i], static_cast<std::uint64_t>(stamp.count()),
                     pose.t, pose.q, is_static);
        },
        [&] { fed.store(true); }, stop);
  });
  while (!fed.load()) std::this_thread::sleep_for(1ms);
  const auto until = std::chrono::steady_clock::now() + 2s;
  while (std::chrono::steady_clock::now() < until) {
    const auto past = static_cast<std::uint64_t>((horus::now() - kPast).count());
    for (int i = 1; i < kFrames; ++i) {
      buffer.lookup("map", names[i], past);
      buffer.lookup("map", names[i], 0);
    }
    std::this_thread::sleep_for(1ms);
  }
  signal_ready(ready_fd);
  wait_to_be_killed();
}

// ---------------------------------------------------------------------------------------------
// The orchestrating process.

/// Processes started from this binary, killed when this goes out of scope.
class Children {
 public:
  Children() = default;
  Children(const Children&) = delete;
  Children& operator=(const Children&) = delete;
  ~Children() { kill_all(); }

  /// Starts `frames_bench ROLE ARGS... READY_FD` and waits until it says it is ready.
  pid_t start(const std::string& role, std::vector<std::string> args) {
    int ends[2];
    if (::pipe(ends) != 0) throw std::runtime_error("pipe failed");
    args.insert(args.begin(), role);
    args.push_back(std::to_string(ends[1]));
    // Made before fork: a child of a process with threads must not allocate before exec.
    std::vector<char*> argv{const_cast<char*>("frames_bench")};
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const pid_t pid = ::fork();
    if (pid < 0) throw std::runtime_error("fork failed");
    if (pid == 0) {
      ::close(ends[0]);
      ::execv("/proc/self/exe", argv.data());
      std::_Exit(127);
    }
    ::close(ends[1]);
    pids_.push_back(pid);
    char byte = 0;
    const ssize_t got = ::read(ends[0], &byte, 1);
    ::close(ends[0]);
    if (got != 1) throw std::runtime_error("the " + role + " process exited before it was ready");
    return pid;
  }
  const std::vector<pid_t>& pids() const { return pids_; }
  void kill_all() {
    for (const pid_t pid : pids_) ::kill(pid, SIGTERM);
    for (const pid_t pid : pids_) ::waitpid(pid, nullptr, 0);
    pids_.clear();
  }

 private:
  std::vector<pid_t> pids_;
};

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 != 0 ? values[n / 2] : (values[n / 2 - 1] + values[n / 2]) / 2;
}

struct Row {
  explicit Row(std::string row_name) : name(std::move(row_name)) {}
  std::string name;
  std::vector<double> ns_per_lookup;  // one per block
  long allocations = 0;
  long lookups = 0;
};

template <typename Body>
void time_block(Row& row, int lookups, Body&& body) {
  const long allocated_before = thread_allocations;
  const auto begin = std::chrono::steady_clock::now();
  for (int n = 0; n < lookups; ++n) body();
  const auto end = std::chrono::steady_clock::now();
  row.allocations += thread_allocations - allocated_before;
  row.lookups += lookups;
  row.ns_per_lookup.push_back(static_cast<double>((end - begin).count()) / lookups);
}

void print_lookups(int blocks, int lookups) {
  const bool two_cpus = std::thread::hardware_concurrency() >= 2;
  const std::string namespace_name = "frames_bench_" + std::to_string(::getpid());
  horus::remove_frame_tree(namespace_name);
  const nanoseconds start = horus::now() - 10s;
  pin_to(0);
  Children children;
  children.start("writer", {namespace_name, std::to_string(start.count()), two_cpus ? "1" : "0"});

  frames_bench::Tf2Buffer tf2(kHistorySeconds);
  std::atomic<bool> tf2_fed{false};
  std::atomic<bool> stop{false};
  const std::vector<std::string> names = all_names();
  std::thread feeder([&] {
    pin_to(two_cpus ? 1 : 0);
    feed(
        start,
        [&](int i, nanoseconds stamp, const Pose& pose, bool is_static) {
          tf2.set(names[parent_index(i)], names[i], static_cast<std::uint64_t>(stamp.count()),
                  pose.t, pose.q, is_static);
        },
        [&] { tf2_fed.store(true); }, stop);
  });
  while (!tf2_fed.load()) std::this_thread::sleep_for(1ms);

  const horus::FrameTree tree(tree_options(namespace_name));
  const std::string target = "map";
  const std::string source = frame_name(kChainTip);
  Row horus_past{"HORUS `FrameTree::lookup(\"map\", \"f5\", past)`, another process writes"};
  Row tf2_past{"tf2 `BufferCore::lookupTransform(\"map\", \"f5\", past)`, feeder thread writes"};
  Row horus_latest{"HORUS `FrameTree::lookup(\"map\", \"f5\")`, latest common time"};
  Row tf2_latest{"tf2 `lookupTransform(\"map\", \"f5\", ros::Time(0))`, latest common time"};
  horus::Transform horus_answer;
  frames_bench::Tf2Answer tf2_answer{};
  const std::vector<std::function<void(nanoseconds)>> rows = {
      [&](nanoseconds past) {
        time_block(horus_past, lookups, [&] { horus_answer = tree.lookup(target, source, past); });
        check_horus(horus_answer, expected_chain(start, past), "HORUS at a past time");
      },
      [&](nanoseconds past) {
        const auto stamp = static_cast<std::uint64_t>(past.count());
        time_block(tf2_past, lookups, [&] { tf2_answer = tf2.lookup(target, source, stamp); });
        check(matches(expected_chain(start, past), tf2_answer.translation, tf2_answer.rotation),
              "tf2 at a past time");
      },
      [&](nanoseconds) {
        time_block(horus_latest, lookups, [&] { horus_answer = tree.lookup(target, source); });
        check_latest_horus(horus_answer, start, "HORUS at the latest common time");
      },
      [&](nanoseconds) {
        time_block(tf2_latest, lookups, [&] { tf2_answer = tf2.lookup(target, source, 0); });
        const nanoseconds stamp(static_cast<std::int64_t>(tf2_answer.stamp_ns));
        check(stamp > horus::now() - 1s && matches(expected_chain(start, stamp),
                                                   tf2_answer.translation, tf2_answer.rotation),
              "tf2 at the latest common time");
      }};
  // Warm both (caches, tf2's frame-name map), then interleave: each block runs every row once,
  // starting from a different row each time.
  for (int warm = 0; warm < 2; ++warm) {
    for (const auto& row : rows) row(horus::now() - kPast);
  }
  for (Row* row : {&horus_past, &tf2_past, &horus_latest, &tf2_latest}) *row = Row{row->name};
  for (int block = 0; block < blocks; ++block) {
    const nanoseconds past = horus::now() - kPast;
    for (std::size_t r = 0; r < rows.size(); ++r) rows[(r + block) % rows.size()](past);
  }
  stop.store(true);
  feeder.join();
  children.kill_all();
  horus::remove_frame_tree(namespace_name);

  std::printf(
      "Lookups of map <- f5 (5 links): %d blocks of %d per row, interleaved; reader on CPU "
      "0, writer (HORUS's process, tf2's thread) on CPU %d.\n\n",
      blocks, lookups, two_cpus ? 1 : 0);
  std::printf(
      "| lookup | ns/lookup (median block) | best block | / tf2 (median) | allocations "
      "per lookup |\n|---|---:|---:|---:|---:|\n");
  const auto print_row = [](const Row& row, double tf2_median) {
    const double m = median(row.ns_per_lookup);
    std::printf("| %s | %.1f | %.1f | %.2fx | %.2f |\n", row.name.c_str(), m,
                *std::min_element(row.ns_per_lookup.begin(), row.ns_per_lookup.end()),
                m / tf2_median, static_cast<double>(row.allocations) / row.lookups);
  };
  const double tf2_past_median = median(tf2_past.ns_per_lookup);
  const double tf2_latest_median = median(tf2_latest.ns_per_lookup);
  print_row(tf2_past, tf2_past_median);
  print_row(horus_past, tf2_past_median);
  print_row(tf2_latest, tf2_latest_median);
  print_row(horus_latest, tf2_latest_median);
  std::vector<double> ratios;
  for (int b = 0; b < blocks; ++b) {
    ratios.push_back(horus_past.ns_per_lookup[b] / tf2_past.ns_per_lookup[b]);
  }
  std::printf(
      "\nPer-block ratio HORUS / tf2 at a past time: median %.2fx, best %.2fx, worst "
      "%.2fx (goal <= 0.5x).\n\n",
      median(ratios), *std::min_element(ratios.begin(), ratios.end()),
      *std::max_element(ratios.begin(), ratios.end()));
}

// ---------------------------------------------------------------------------------------------
// Memory of 10 processes using frames.

struct Memory {
  long pss_kb = 0;
  long pss_anon_kb = 0;
  long pss_file_kb = 0;
  long pss_shmem_kb = 0;
};

Memory memory_of(pid_t pid) {
  std::ifstream file("/proc/" + std::to_string(pid) + "/smaps_rollup");
  if (!file) throw std::runtime_error("cannot read /proc/" + std::to_string(pid) + "/smaps_rollup");
  Memory m;
  std::string line;  // "Pss:  1234 kB"; the first line names the rollup's address range
  while (std::getline(file, line)) {
    const std::size_t colon = line.find(':');
    if (colon == std::string::npos || line.find(" kB") == std::string::npos) continue;
    const std::string key = line.substr(0, colon);
    const long value = std::stol(line.substr(colon + 1));
    if (key == "Pss") m.pss_kb = value;
    if (key == "Pss_Anon") m.pss_anon_kb = value;
    if (key == "Pss_File") m.pss_file_kb = value;
    if (key == "Pss_Shmem") m.pss_shmem_kb = value;
  }
  return m;
}

Memory total_memory(const std::vector<pid_t>& pids) {
  Memory sum;
  for (const pid_t pid : pids) {
    const Memory m = memory_of(pid);
    sum.pss_kb += m.pss_kb;
    sum.pss_anon_kb += m.pss_anon_kb;
    sum.pss_file_kb += m.pss_file_kb;
    sum.pss_shmem_kb += m.pss_shmem_kb;
  }
  return sum;
}

/// The same binary doing nothing, as many processes at once (the libraries' pages are shared
/// among as many): the baseline subtracted from each measure.
Memory idle_memory(int processes) {
  Children idle;
  for (int i = 0; i < processes; ++i) idle.start("idle", {});
  return total_memory(idle.pids());
}

void print_memory(int users) {
  const std::string namespace_name = "frames_bench_memory_" + std::to_string(::getpid());
  horus::remove_frame_tree(namespace_name);
  Memory horus_memory;
  long tree_file_kb = 0;
  {
    Children children;
    children.start("writer", {namespace_name, std::to_string((horus::now() - 10s).count()), "-1"});
    for (int i = 0; i < users; ++i) children.start("horus-user", {namespace_name});
    horus_memory = total_memory(children.pids());
    struct stat file {};
    const std::string path = horus::detail::shm_root() + "/@frames/" + namespace_name;
    if (::stat(path.c_str(), &file) != 0) throw std::runtime_error("cannot stat " + path);
    tree_file_kb = static_cast<long>(file.st_blocks) * 512 / 1024;
  }
  horus::remove_frame_tree(namespace_name);
  const Memory horus_idle = idle_memory(users + 1);
  Memory tf2_memory;
  {
    Children children;
    for (int i = 0; i < users; ++i) {
      children.start("tf2-user", {std::to_string((horus::now() - 10s).count())});
    }
    tf2_memory = total_memory(children.pids());
  }
  const Memory tf2_idle = idle_memory(users);

  // The tree's pages are counted once, as the file's blocks (they stay while nobody maps
  // them); the processes' share of its mapping (Pss_Shmem) is left out so as not to count
  // them twice.
  const long horus_total = horus_memory.pss_kb - horus_memory.pss_shmem_kb -
                           (horus_idle.pss_kb - horus_idle.pss_shmem_kb) + tree_file_kb;
  const long tf2_total = tf2_memory.pss_kb - tf2_idle.pss_kb;
  std::printf(
      "Memory of %d processes using frames (sums over the processes of Pss from "
      "/proc/PID/smaps_rollup, kB).\n\n",
      users);
  std::printf(
      "| processes | sum of Pss | of which Pss_Anon / Pss_Shmem | idle baseline (same "
      "binary, as many processes) | tree file on tmpfs | frames memory | / tf2 |\n"
      "|---|---:|---:|---:|---:|---:|---:|\n");
  std::printf(
      "| tf2: %d processes, each its own `BufferCore` (19 frames, 10 s at 100 Hz) and "
      "feeder thread | %ld | %ld / %ld | %ld | - | **%ld** | 1.00x |\n",
      users, tf2_memory.pss_kb, tf2_memory.pss_anon_kb, tf2_memory.pss_shmem_kb, tf2_idle.pss_kb,
      tf2_total);
  std::printf(
      "| HORUS: %d processes reading one shared tree + its writer process | %ld | %ld / "
      "%ld | %ld | %ld | **%ld** | %.2fx |\n\n",
      users, horus_memory.pss_kb, horus_memory.pss_anon_kb, horus_memory.pss_shmem_kb,
      horus_idle.pss_kb, tree_file_kb, horus_total,
      static_cast<double>(horus_total) / static_cast<double>(tf2_total));
  std::printf(
      "Frames memory: sum of Pss less the idle baseline; for HORUS less the processes' "
      "share of the tree's mapping (Pss_Shmem) and plus the tree file's allocated blocks "
      "instead (%ld kB: the 20 frames' slots the writer touched), so the tree counts once "
      "and stays counted when nobody maps it.\n",
      tree_file_kb);
}

int run_bench(int blocks, int lookups) {
  print_lookups(blocks, lookups);
  print_memory(10);
  return 0;
}

int to_int(const char* text) { return std::stoi(text); }

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string role = argc > 1 ? argv[1] : "";
    if (role == "writer" && argc == 6) {
      return run_writer(argv[2], nanoseconds(std::stoll(argv[3])), to_int(argv[5]),
                        to_int(argv[4]));
    }
    if (role == "horus-user" && argc == 4) return run_horus_user(argv[2], to_int(argv[3]));
    if (role == "tf2-user" && argc == 4) {
      return run_tf2_user(nanoseconds(std::stoll(argv[2])), to_int(argv[3]));
    }
    if (role == "idle" && argc == 3) {
      signal_ready(to_int(argv[2]));
      wait_to_be_killed();
    }
    if (argc == 1) return run_bench(40, 20000);
    if (argc == 3) return run_bench(to_int(argv[1]), to_int(argv[2]));
    std::fprintf(stderr, "usage: frames_bench [BLOCKS LOOKUPS]\n");
    return 2;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "frames_bench: %s\n", error.what());
    return 1;
  }
}
