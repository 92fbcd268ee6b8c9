// Records 10 topics at 1 kHz (64 B each) and a 30 Hz stream of 1080p RGB frames (6,220,800 B)
// for a given time, with the recorder in a child process of its own (so its CPU time is its
// own), then writes the same number of bytes with plain sequential write() calls: the floor of
// the write rate. Twice: the frames as a POD plain value [u8; 6220800] written in place with
// loan(), then as pool-backed horus::Image (the ring carries a descriptor, the recorder copies
// the pixels from the pool block).
//
//   horus_recording_bench [seconds, default 10] [folder, default .]
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "horus/error.hpp"
#include "horus/image.hpp"
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
int run_recorder(const std::filesystem::path& file, const std::string& tag, int ready_fd,
                 int stop_fd, int out_fd) {
  horus::RecorderOptions options;
  options.path = file;
  for (std::size_t i = 0; i < kSmallTopics; ++i)
    options.topics.push_back(tag + "_small" + std::to_string(i));
  options.topics.push_back(tag + "_camera");
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

/// One recording session's numbers.
struct Session {
  std::uint64_t sent_small = 0, sent_frames = 0;
  double publish_s = 0, cpu_s = 0, write_s = 0;
  RecorderResult recorded;
};

/// Publishes 10 small topics <tag>_small<i> and the camera <tag>_camera for `duration` s while
/// a child process records them, then writes the floor. `send_frame(i)` publishes camera frame
/// i (true: sent).
template <class SendFrame>
std::optional<Session> record_session(double duration, const std::filesystem::path& folder,
                                      const std::string& tag, SendFrame&& send_frame) {
  const std::string id = tag + "_" + std::to_string(::getpid());
  std::vector<std::unique_ptr<horus::Topic<Small>>> small;
  for (std::size_t i = 0; i < kSmallTopics; ++i) {
    small.push_back(std::make_unique<horus::Topic<Small>>(
        tag + "_small" + std::to_string(i), horus::TopicOptions{.capacity = kSmallCapacity}));
  }
  const std::filesystem::path file = folder / ("recording_bench_" + id + ".mcap");
  const std::filesystem::path plain = folder / ("write_floor_" + id + ".bin");
  Session session;
  int ready[2], stop[2], out[2];
  if (::pipe(ready) != 0 || ::pipe(stop) != 0 || ::pipe(out) != 0) return std::nullopt;
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(stop[1]);
    std::_Exit(run_recorder(file, tag, ready[1], stop[0], out[1]));
  }
  ::close(stop[0]);
  char go = 0;
  if (::read(ready[0], &go, 1) != 1) return std::nullopt;

  // Publishers: the 1 kHz topics and the 30 Hz camera on a release grid of their own each.
  const auto start = std::chrono::steady_clock::now();
  const auto end = start + std::chrono::duration<double>(duration);
  std::thread camera_thread([&] {
    auto next = start;
    for (std::uint64_t i = 0; next < end; ++i) {
      if (send_frame(i)) ++session.sent_frames;
      next += std::chrono::microseconds(33'333);
      std::this_thread::sleep_until(next);
    }
  });
  auto next = start;
  for (std::uint64_t i = 0; next < end; ++i) {
    for (auto& topic : small) {
      Small value{};
      value.fill(i);
      if (topic->send(value)) ++session.sent_small;
    }
    next += std::chrono::microseconds(1000);
    std::this_thread::sleep_until(next);
  }
  camera_thread.join();
  session.publish_s = seconds_since(start);
  ::close(stop[1]);
  const bool reported =
      ::read(out[0], &session.recorded, sizeof session.recorded) == sizeof session.recorded;
  int status = 0;
  rusage usage{};
  ::wait4(child, &status, 0, &usage);
  for (const int fd : {ready[0], ready[1], out[0], out[1]}) ::close(fd);
  session.cpu_s = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                  static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) * 1e-6;
  if (!reported || status != 0) {
    std::fprintf(stderr, "recorder child failed (status %d)\n", status);
    return std::nullopt;
  }

  // The floor: the same number of bytes, written in 1 MiB write() calls and fsync'd (as the
  // recorder's finish() does), from a buffer already in memory.
  const std::size_t block = std::size_t{1} << 20;
  std::vector<std::uint8_t> buffer(block);
  for (std::size_t i = 0; i < block; ++i) buffer[i] = static_cast<std::uint8_t>(i * 131);
  const auto write_start = std::chrono::steady_clock::now();
  const int fd = ::open(plain.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  for (std::uint64_t left = session.recorded.bytes; left > 0;) {
    const std::size_t n = left < block ? static_cast<std::size_t>(left) : block;
    if (::write(fd, buffer.data(), n) != static_cast<ssize_t>(n)) return std::nullopt;
    left -= n;
  }
  ::fsync(fd);
  ::close(fd);
  session.write_s = seconds_since(write_start);
  std::filesystem::remove(file);
  std::filesystem::remove(plain);
  return session;
}

/// One row of the table: `measure`, then the value of each session.
template <class Value>
void row(const char* measure, const std::vector<Session>& sessions, Value&& value) {
  std::printf("| %s |", measure);
  for (const Session& s : sessions) std::printf(" %s |", value(s).c_str());
  std::printf("\n");
}

template <class... Args>
std::string text(const char* format, Args... args) {
  char out[160];
  std::snprintf(out, sizeof out, format, args...);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  const double duration = argc > 1 ? std::atof(argv[1]) : 10.0;
  const std::filesystem::path folder = argc > 2 ? argv[2] : ".";
  const std::string ns = "bench_rec_" + std::to_string(::getpid());
  ::setenv("HORUS_NAMESPACE", ns.c_str(), 1);

  std::vector<std::unique_ptr<Frame>> frames;
  for (std::uint64_t i = 0; i < 4; ++i) {
    frames.push_back(std::make_unique<Frame>());
    paint(*frames.back(), i);
  }
  std::vector<Session> sessions;

  // The frames as a plain value [u8; 6220800]: the POD ring carries each whole.
  {
    horus::Topic<Frame> camera("pod_camera", {.capacity = kFrameCapacity});
    const auto session = record_session(duration, folder, "pod", [&](std::uint64_t i) {
      auto loan = camera.loan();
      std::memcpy(loan->data(), frames[i % frames.size()]->data(), kFrameBytes);
      return camera.publish(std::move(loan));
    });
    if (!session) return 1;
    sessions.push_back(*session);
  }
  // The frames as horus::Image: pixels in a block of the shared-memory pool, the ring carrying
  // the descriptor; the recorder copies the pixels from the block. The pool holds the ring's
  // capacity of frames that the sender keeps alive, the recorder's one and the one being made.
  {
    horus::TensorPoolOptions geometry;
    geometry.block_size = std::size_t{8} << 20;
    geometry.block_count = 2 * kFrameCapacity;
    const horus::TensorPool pool = horus::TensorPool::open("default", geometry);
    horus::Topic<horus::Image> camera("image_camera", {.capacity = kFrameCapacity});
    const auto session = record_session(duration, folder, "image", [&](std::uint64_t i) {
      try {
        horus::Image image = horus::Image::make(1080, 1920, horus::ImageEncoding::Rgb8, pool);
        image.copy_from(*frames[i % frames.size()]);
        return camera.send(image);
      } catch (const horus::Error& e) {  // the pool exhausted: a frame not sent, counted so
        std::fprintf(stderr, "frame %llu not sent: %s\n", static_cast<unsigned long long>(i),
                     e.what());
        return false;
      }
    });
    if (!session) return 1;
    sessions.push_back(*session);
  }

  std::printf("| measure | POD `[u8; 6220800]` frames | pool `horus::Image` frames |\n");
  std::printf("|---|---:|---:|\n");
  const auto payload_mb = [](const Session& s) {
    return (static_cast<double>(s.sent_small) * sizeof(Small) +
            static_cast<double>(s.sent_frames) * kFrameBytes) /
           1e6;
  };
  const auto file_mb = [](const Session& s) { return static_cast<double>(s.recorded.bytes) / 1e6; };
  row("published: 1 kHz messages (10 topics x 64 B)", sessions,
      [](const Session& s) { return text("%llu", static_cast<unsigned long long>(s.sent_small)); });
  row("published: 1080p RGB frames (6,220,800 B)", sessions, [](const Session& s) {
    return text("%llu", static_cast<unsigned long long>(s.sent_frames));
  });
  row("payload published", sessions, [&](const Session& s) {
    return text("%.1f MB in %.2f s (%.1f MB/s)", payload_mb(s), s.publish_s,
                payload_mb(s) / s.publish_s);
  });
  row("recorded messages", sessions, [](const Session& s) {
    return text("%llu of %llu", static_cast<unsigned long long>(s.recorded.messages),
                static_cast<unsigned long long>(s.sent_small + s.sent_frames));
  });
  row("**lost** (counted by the recorder)", sessions, [](const Session& s) {
    return text("**%llu**", static_cast<unsigned long long>(s.recorded.lost));
  });
  row("file size (zstd level 1 chunks)", sessions, [&](const Session& s) {
    return text("%.1f MB (%.2fx of the payload)", file_mb(s), file_mb(s) / payload_mb(s));
  });
  row("**recorder CPU** (user + system, whole child process)", sessions, [](const Session& s) {
    return text("**%.2f s = %.0f %% of one CPU**", s.cpu_s, 100.0 * s.cpu_s / s.publish_s);
  });
  row("recorder write rate while recording (file bytes / recording time)", sessions,
      [&](const Session& s) { return text("%.1f MB/s", file_mb(s) / s.publish_s); });
  row("floor: plain write() of the same bytes, 1 MiB blocks + fsync", sessions,
      [&](const Session& s) {
        return text("%.1f MB/s (%.3f s)", file_mb(s) / s.write_s, s.write_s);
      });
  row("**write rate while recording / floor**", sessions, [&](const Session& s) {
    return text("**%.2fx**", (file_mb(s) / s.publish_s) / (file_mb(s) / s.write_s));
  });
  row("recorder capacity (file bytes / recorder CPU time)", sessions,
      [&](const Session& s) { return text("%.1f MB/s", file_mb(s) / s.cpu_s); });
  row("capacity / floor", sessions,
      [](const Session& s) { return text("%.2fx", s.write_s / s.cpu_s); });
  horus::remove_namespace(ns);
  const bool lost = std::any_of(sessions.begin(), sessions.end(),
                                [](const Session& s) { return s.recorded.lost > 0; });
  return lost ? 3 : 0;
}
