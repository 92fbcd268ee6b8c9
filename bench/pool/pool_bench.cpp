// Tensor pool benchmark, two processes (fork) pinned to CPUs 0 and 1:
//  - latency: from send(img) to the first pixel read by the receiver, for 640x480, 1080p and 4K
//    RGB, against (a) a 16 B topic message (the descriptor's own cost) and (b) (a) plus a memcpy
//    of the frame (the least a copying transport pays). A ping-pong: the sender sends a frame,
//    the receiver polls try_recv, reads the first pixel and answers with a 16 B message holding
//    it; the 16 B floor is the same ping-pong with a 16 B ping. One-way of a frame = its round
//    trip - half the 16 B round trip (the pong's share); rounds alternate the rows so background
//    load hits all alike.
//  - throughput: 1080p frames through one publisher and two subscribers for 10 s, lossless (the
//    publisher stays at most 2 frames ahead of the slowest subscriber's acknowledgement); every
//    subscriber checks that frame i arrives i-th, with its pixels in place.
// Output is Markdown.
#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <horus/image.hpp>
#include <horus/tensor_pool.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;
using Pong = std::array<std::uint64_t, 2>;  // 16 B: sequence number, first pixel

constexpr int kRounds = 5;
constexpr int kIterations = 2000;

void pin(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu % static_cast<int>(std::max(1U, std::thread::hardware_concurrency())), &set);
  if (::sched_setaffinity(0, sizeof set, &set) != 0) {
    std::perror("sched_setaffinity");
  }
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

double percentile(std::vector<std::int64_t> samples, double q) {
  std::sort(samples.begin(), samples.end());
  return static_cast<double>(samples[static_cast<std::size_t>(q * (samples.size() - 1))]);
}

struct Size {
  const char* name;
  std::uint32_t width;
  std::uint32_t height;
};
constexpr std::array<Size, 3> kSizes{
    {{"640x480", 640, 480}, {"1920x1080", 1920, 1080}, {"3840x2160", 3840, 2160}}};

horus::TensorPool bench_pool() {
  horus::TensorPoolOptions options;
  options.block_size = std::size_t{3840} * 2160 * 3;
  options.block_count = 24;
  return horus::TensorPool::open("bench", options);
}

/// The echoing side: answers every ping (a frame, or 16 B) with a 16 B pong holding the frame's
/// first pixel. Exits after `count` pings.
template <class Ping>
void echo(const std::string& ping_name, int count) {
  pin(1);
  horus::Topic<Ping> ping(ping_name);
  horus::Topic<Pong> pong(ping_name + ".pong");
  pong.send(Pong{0, 0});  // ready
  for (int i = 0; i < count;) {
    if (std::optional<Ping> got = ping.try_recv()) {
      std::uint64_t first = 0;
      if constexpr (std::is_same_v<Ping, horus::Image>) {
        first = got->data()[0];
      } else if constexpr (std::is_same_v<Ping, horus::msg::ImageDescriptor>) {
        first = got->width;
      } else {
        first = (*got)[1];
      }
      pong.send(Pong{static_cast<std::uint64_t>(i + 1), first});
      ++i;
    }
  }
}

/// Round trips (ns) of `count` pings sent by `send(i)`.
template <class Ping, class Send>
std::vector<std::int64_t> ping_pong(const std::string& name, int count, Send&& send) {
  horus::Topic<Ping> ping(name);
  horus::Topic<Pong> pong(name + ".pong");
  std::fflush(stdout);  // or the child would print what is buffered again
  const pid_t child = ::fork();
  if (child == 0) {
    echo<Ping>(name, count);
    std::_Exit(0);
  }
  pin(0);
  while (!pong.try_recv()) {
  }
  std::vector<std::int64_t> samples;
  samples.reserve(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    const std::int64_t start = now_ns();
    send(ping, i);
    std::optional<Pong> answer;
    while (!(answer = pong.try_recv())) {
    }
    samples.push_back(now_ns() - start);
    if (answer->at(0) != static_cast<std::uint64_t>(i + 1)) {
      std::fprintf(stderr, "pong out of order\n");
      std::exit(1);
    }
  }
  ::waitpid(child, nullptr, 0);
  return samples;
}

void latency_table() {
  horus::TensorPool pool = bench_pool();
  std::printf("## Latency: send(img) to the first pixel read, one way (ns)\n\n");
  std::printf(
      "| frame | bytes | 16 B topic (a) p50 | frame p50 | frame / (a) | (a) + memcpy p50 (b) | "
      "frame / (b) | frame p99 | memcpy p50 | descriptor alone p50 |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Size& size : kSizes) {
    // Eight frames in turn, each painted once (a camera writes every frame anyway).
    std::vector<horus::Image> frames;
    for (int i = 0; i < 8; ++i) {
      frames.push_back(
          horus::Image::make(size.height, size.width, horus::ImageEncoding::Rgb8, pool));
      frames.back().fill(static_cast<std::uint8_t>(i + 1));
    }
    const std::size_t bytes = frames[0].size();
    std::vector<std::uint8_t> copy(bytes);
    std::vector<double> ratio_a;
    std::vector<double> ratio_b;
    std::vector<double> floor_a;
    std::vector<double> frame_p50;
    std::vector<double> frame_p99;
    std::vector<double> memcpy_p50;
    std::vector<double> descriptor_p50;
    for (int round = 0; round < kRounds; ++round) {
      const std::string tag = std::string(size.name) + "." + std::to_string(round);
      const std::vector<std::int64_t> small =
          ping_pong<Pong>("small." + tag, kIterations, [](horus::Topic<Pong>& ping, int i) {
            ping.send(Pong{static_cast<std::uint64_t>(i), 1});
          });
      const std::vector<std::int64_t> frame = ping_pong<horus::Image>(
          "frame." + tag, kIterations,
          [&](horus::Topic<horus::Image>& ping, int i) { ping.send(frames[i % frames.size()]); });
      const std::vector<std::int64_t> descriptor = ping_pong<horus::msg::ImageDescriptor>(
          "descriptor." + tag, kIterations,
          [&](horus::Topic<horus::msg::ImageDescriptor>& ping, int i) {
            ping.send(frames[i % frames.size()].descriptor());
          });
      std::vector<std::int64_t> copies;
      for (int i = 0; i < 50; ++i) {
        const std::int64_t start = now_ns();
        std::memcpy(copy.data(), frames[i % frames.size()].data().data(), bytes);
        copies.push_back(now_ns() - start);
      }
      const double a = percentile(small, 0.5) / 2;
      const double one_way = percentile(frame, 0.5) - a;
      const double one_way_p99 = percentile(frame, 0.99) - a;
      const double b = a + percentile(copies, 0.5);
      floor_a.push_back(a);
      frame_p50.push_back(one_way);
      frame_p99.push_back(one_way_p99);
      memcpy_p50.push_back(percentile(copies, 0.5));
      descriptor_p50.push_back(percentile(descriptor, 0.5) - a);
      ratio_a.push_back(one_way / a);
      ratio_b.push_back(one_way / b);
    }
    std::printf("| %s RGB | %zu | %.0f | %.0f | %.2fx | %.0f | %.4fx | %.0f | %.0f | %.0f |\n",
                size.name, bytes, median(floor_a), median(frame_p50), median(ratio_a),
                median(floor_a) + median(memcpy_p50), median(ratio_b), median(frame_p99),
                median(memcpy_p50), median(descriptor_p50));
    std::fflush(stdout);
  }
  std::printf(
      "\n(ratios: median over %d rounds of each round's ratio; %d pings per row and round)\n\n",
      kRounds, kIterations);
}

/// A subscriber of the throughput run: checks order and pixels, acknowledges each frame.
int subscriber(int index, std::uint64_t* received_out) {
  pin(1);
  horus::Topic<horus::Image> frames("fps");
  horus::Topic<std::uint64_t> ack("fps.ack" + std::to_string(index));
  ack.send(0);  // ready
  std::uint64_t expected = 1;
  for (;;) {
    std::optional<horus::Image> frame = frames.recv(2s);
    if (!frame) {
      break;
    }
    std::uint64_t seq = 0;
    std::memcpy(&seq, frame->data().data(), sizeof seq);
    if (seq == 0) {
      break;  // the end
    }
    if (seq != expected || frame->data()[frame->size() - 1] != static_cast<std::uint8_t>(seq)) {
      std::fprintf(stderr, "subscriber %d: frame %llu where %llu was due\n", index,
                   static_cast<unsigned long long>(seq), static_cast<unsigned long long>(expected));
      return 1;
    }
    ++expected;
    ack.send(seq);
  }
  *received_out = expected - 1;
  return frames.lost() == 0 && frames.refused() == 0 ? 0 : 2;
}

void throughput_table() {
  horus::TensorPool pool = bench_pool();
  horus::Topic<horus::Image> frames("fps");
  std::array<horus::Topic<std::uint64_t>, 2> acks{horus::Topic<std::uint64_t>("fps.ack0"),
                                                  horus::Topic<std::uint64_t>("fps.ack1")};
  std::array<pid_t, 2> children{};
  std::fflush(stdout);  // or the children would print what is buffered again
  for (int i = 0; i < 2; ++i) {
    children[i] = ::fork();
    if (children[i] == 0) {
      std::uint64_t received = 0;
      const int status = subscriber(i, &received);
      std::printf("| subscriber %d | %llu frames received, in order, none lost |\n", i,
                  static_cast<unsigned long long>(received));
      std::fflush(stdout);
      std::_Exit(status);
    }
  }
  pin(0);
  std::array<std::uint64_t, 2> acked{};
  std::array<bool, 2> ready{};
  while (!ready[0] || !ready[1]) {
    for (int i = 0; i < 2; ++i) {
      ready[i] = ready[i] || acks[i].try_recv().has_value();
    }
  }
  std::vector<horus::Image> images;
  for (int i = 0; i < 8; ++i) {
    images.push_back(horus::Image::make(1080, 1920, horus::ImageEncoding::Rgb8, pool));
  }
  std::printf("## Throughput: 1080p RGB, one publisher, two subscribers, 10 s, lossless\n\n");
  std::printf("| who | result |\n|---|---|\n");
  std::fflush(stdout);
  const auto start = Clock::now();
  std::uint64_t seq = 0;
  while (Clock::now() - start < 10s) {
    ++seq;
    // At most two frames ahead of the slower subscriber (the ring holds four).
    while (seq > std::min(acked[0], acked[1]) + 2) {
      for (int i = 0; i < 2; ++i) {
        while (std::optional<std::uint64_t> a = acks[i].try_recv()) {
          acked[i] = std::max(acked[i], *a);
        }
      }
    }
    horus::Image& image = images[seq % images.size()];
    std::span<std::uint8_t> bytes = image.data_mut();
    std::memcpy(bytes.data(), &seq, sizeof seq);
    bytes[bytes.size() - 1] = static_cast<std::uint8_t>(seq);
    if (!frames.send(image)) {
      std::fprintf(stderr, "send failed\n");
      std::exit(1);
    }
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  // The end: frame 0 (after the subscribers caught up).
  while (std::min(acked[0], acked[1]) < seq) {
    for (int i = 0; i < 2; ++i) {
      while (std::optional<std::uint64_t> a = acks[i].try_recv()) {
        acked[i] = std::max(acked[i], *a);
      }
    }
  }
  horus::Image& last = images[(seq + 1) % images.size()];
  std::memset(last.data_mut().data(), 0, sizeof(std::uint64_t));
  frames.send(last);
  int failures = 0;
  for (const pid_t child : children) {
    int status = 0;
    ::waitpid(child, &status, 0);
    failures += WIFEXITED(status) && WEXITSTATUS(status) == 0 ? 0 : 1;
  }
  std::printf("| publisher | %llu frames in %.2f s = %.0f fps (%.2f GB/s per subscriber) |\n",
              static_cast<unsigned long long>(seq), seconds, static_cast<double>(seq) / seconds,
              static_cast<double>(seq) * 1920 * 1080 * 3 / seconds / 1e9);
  std::printf("| subscribers failing the order/loss check | %d |\n\n", failures);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string space = "poolbench" + std::to_string(::getpid());
  ::setenv("HORUS_NAMESPACE", space.c_str(), 1);
  const std::string only = argc > 1 ? argv[1] : "";
  if (only.empty() || only == "latency") {
    latency_table();
  }
  if (only.empty() || only == "throughput") {
    throughput_table();
  }
  horus::remove_namespace(space);
  horus::remove_pools(space);
  return 0;
}
