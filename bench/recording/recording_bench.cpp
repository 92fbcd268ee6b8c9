// Records 10 topics at 1 kHz (64 B each) and a 30 Hz stream of 1080p RGB frames (6,220,800 B,
// a POD plain value [u8; 6220800] written in place with loan()) for a given time, with the
// recorder in a child process of its own (so its CPU time is its own), then writes the same
// number of bytes with plain sequential write() calls: the floor of the write rate.
//
//   horus_recording_bench [seconds, default 10] [folder, default .]
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "horus/recording.hpp"
#include "horus/topic.hpp"
#include "horus/topic_registry.hpp"

namespace {

constexpr std::size_t kSmallTopics = 10;
constexpr std::size_t kFrameBytes = 1920 * 1080 * 3;
/// Ring sizes: about one second of each stream, the pause a recorder thread may see on a loaded
/// machine (a 64-slot ring at 1 kHz covers 64 ms).
constexpr std::size_t kSmallCapacity = 1024;
constexpr std::size_t kFrameCapacity = 32;
using Small = std::array<std::uint64_t, 8>;
using Frame = std::array<std::uint8_t, kFrameBytes>;

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// A camera-like frame: smooth gradients with sensor noise in the low bits (compresses about
/// as poorly as real video frames do with a fast codec).
void paint(Frame& frame, std::uint64_t index) {
  std::uint64_t noise = 0x9e3779b97f4a7c15ULL * (index + 1);
  for (std::size_t y = 0; y < 1080; ++y) {
    for (std::size_t x = 0; x < 1920; ++x) {
      noise ^= noise << 13;
      noise ^= noise >> 7;
      noise ^= noise << 17;
      std::uint8_t* pixel = frame.data() + (y * 1920 + x) * 3;
      pixel[0] = static_cast<std::uint8_t>((x / 8 + index) ^ (noise & 7));
      pixel[1] = static_cast<std::uint8_t>((y / 4 + index * 3) ^ ((noise >> 8) & 7));
      pixel[2] = static_cast<std::uint8_t>(((x + y) / 16) ^ ((noise >> 16) & 7));
    }
  }
}

struct RecorderResult {
  std::uint64_t messages = 0, bytes = 0, lost = 0;
};

/// The child: records every topic until the parent closes `stop_fd`, then reports on `out_fd`.
int run_recorder(const std::filesystem::path& file, int ready_fd, int stop_fd, int out_fd) {
  horus::RecorderOptions options;
  options.path = file;
  for (std::size_t i = 0; i < kSmallTopics; ++i)
    options.topics.push_back("small" + std::to_string(i));
  options.topics.emplace_back("camera");
  horus::Recorder recorder(options);
  const char go = 1;
  if (::write(ready_fd, &go, 1) != 1) return 1;
  char byte = 0;
  while (::read(stop_fd, &byte, 1) > 0) {
  }
  const horus::RecordingSummary summary = recorder.stop();
  const RecorderResult result{summary.messages, summary.bytes, summary.lost_total};
  return ::write(out_fd, &result, sizeof result) == sizeof result ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const double duration = argc > 1 ? std::atof(argv[1]) : 10.0;
  const std::filesystem::path folder = argc > 2 ? argv[2] : ".";
  const std::string ns = "bench_rec_" + std::to_string(::getpid());
  ::setenv("HORUS_NAMESPACE", ns.c_str(), 1);
  const std::filesystem::path file =
      folder / ("recording_bench_" + std::to_string(::getpid()) + ".mcap");
  const std::filesystem::path plain =
      folder / ("write_floor_" + std::to_string(::getpid()) + ".bin");

  std::vector<std::unique_ptr<horus::Topic<Small>>> small;
  for (std::size_t i = 0; i < kSmallTopics; ++i) {
    small.push_back(std::make_unique<horus::Topic<Small>>(
        "small" + std::to_string(i), horus::TopicOptions{.capacity = kSmallCapacity}));
  }
  horus::Topic<Frame> camera("camera", {.capacity = kFrameCapacity});
  std::vector<std::unique_ptr<Frame>> frames;
  for (std::uint64_t i = 0; i < 4; ++i) {
    frames.push_back(std::make_unique<Frame>());
    paint(*frames.back(), i);
  }

  int ready[2], stop[2], out[2];
  if (::pipe(ready) != 0 || ::pipe(stop) != 0 || ::pipe(out) != 0) return 1;
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(stop[1]);
    std::_Exit(run_recorder(file, ready[1], stop[0], out[1]));
  }
  ::close(stop[0]);
  char go = 0;
  if (::read(ready[0], &go, 1) != 1) return 1;

  // Publishers: the 1 kHz topics and the 30 Hz camera on a release grid of their own each.
  const auto start = std::chrono::steady_clock::now();
  const auto end = start + std::chrono::duration<double>(duration);
  std::uint64_t sent_small = 0, sent_frames = 0;
  std::thread camera_thread([&] {
    auto next = start;
    for (std::uint64_t i = 0; next < end; ++i) {
      auto loan = camera.loan();
      std::memcpy(loan->data(), frames[i % frames.size()]->data(), kFrameBytes);
      if (camera.publish(std::move(loan))) ++sent_frames;
      next += std::chrono::microseconds(33'333);
      std::this_thread::sleep_until(next);
    }
  });
  auto next = start;
  for (std::uint64_t i = 0; next < end; ++i) {
    for (auto& topic : small) {
      Small value{};
      value.fill(i);
      if (topic->send(value)) ++sent_small;
    }
    next += std::chrono::microseconds(1000);
    std::this_thread::sleep_until(next);
  }
  camera_thread.join();
  const double publish_s = seconds_since(start);
  ::close(stop[1]);
  RecorderResult result;
  const bool reported = ::read(out[0], &result, sizeof result) == sizeof result;
  int status = 0;
  rusage usage{};
  ::wait4(child, &status, 0, &usage);
  const double cpu_s = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                       static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) * 1e-6;
  if (!reported || status != 0) {
    std::fprintf(stderr, "recorder child failed (status %d)\n", status);
    return 1;
  }

  // The floor: the same number of bytes, written in 1 MiB write() calls and fsync'd (as the
  // recorder's finish() does), from a buffer already in memory.
  const std::size_t block = std::size_t{1} << 20;
  std::vector<std::uint8_t> buffer(block);
  for (std::size_t i = 0; i < block; ++i) buffer[i] = static_cast<std::uint8_t>(i * 131);
  const auto write_start = std::chrono::steady_clock::now();
  const int fd = ::open(plain.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  for (std::uint64_t left = result.bytes; left > 0;) {
    const std::size_t n = left < block ? static_cast<std::size_t>(left) : block;
    if (::write(fd, buffer.data(), n) != static_cast<ssize_t>(n)) return 1;
    left -= n;
  }
  ::fsync(fd);
  ::close(fd);
  const double write_s = seconds_since(write_start);

  const std::uint64_t expected = sent_small + sent_frames;
  const double payload_mb = (static_cast<double>(sent_small) * sizeof(Small) +
                             static_cast<double>(sent_frames) * kFrameBytes) /
                            1e6;
  const double file_mb = static_cast<double>(result.bytes) / 1e6;
  std::printf("| measure | value |\n|---|---:|\n");
  std::printf("| published: 1 kHz messages (10 topics x 64 B) | %llu |\n",
              static_cast<unsigned long long>(sent_small));
  std::printf("| published: 1080p RGB frames (6,220,800 B) | %llu |\n",
              static_cast<unsigned long long>(sent_frames));
  std::printf("| payload published | %.1f MB in %.2f s (%.1f MB/s) |\n", payload_mb, publish_s,
              payload_mb / publish_s);
  std::printf("| recorded messages | %llu of %llu |\n",
              static_cast<unsigned long long>(result.messages),
              static_cast<unsigned long long>(expected));
  std::printf("| **lost** (counted by the recorder) | **%llu** |\n",
              static_cast<unsigned long long>(result.lost));
  std::printf("| file size (zstd level 1 chunks) | %.1f MB (%.2fx of the payload) |\n", file_mb,
              file_mb / payload_mb);
  std::printf(
      "| **recorder CPU** (user + system, whole child process) | **%.2f s = %.0f %% of one CPU** "
      "|\n",
      cpu_s, 100.0 * cpu_s / publish_s);
  std::printf("| recorder write rate while recording (file bytes / recording time) | %.1f MB/s |\n",
              file_mb / publish_s);
  std::printf("| recorder capacity (file bytes / recorder CPU time) | %.1f MB/s |\n",
              file_mb / cpu_s);
  std::printf(
      "| floor: plain write() of the same bytes, 1 MiB blocks + fsync | %.1f MB/s (%.3f s) |\n",
      file_mb / write_s, write_s);
  std::printf("| **capacity / floor** | **%.2fx** |\n", write_s / cpu_s);
  std::printf("| payload capacity (payload bytes / recorder CPU time) / floor | %.2fx |\n",
              (payload_mb / cpu_s) / (file_mb / write_s));
  std::filesystem::remove(file);
  std::filesystem::remove(plain);
  horus::remove_namespace(ns);
  return result.lost == 0 ? 0 : 3;
}
