// horus-record: records topics of a namespace into an MCAP session file until Ctrl+C, SIGTERM
// or --duration, then finishes the file (summary, footer) and says what it recorded and lost.
//
//   horus-record [-a | TOPICS...] [--frames] [-o FILE] [--duration S] [--namespace NS]
#include <signal.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <string>
#include <string_view>

#include "horus/pool_frames.hpp"
#include "horus/recording.hpp"

namespace {

int usage(std::FILE* out, int status) {
  std::fprintf(out,
               "usage: horus-record [-a | TOPICS...] [--frames] [-o FILE] [--duration S] "
               "[--namespace NS]\n"
               "Records topics into an MCAP file until Ctrl+C, SIGTERM or --duration.\n"
               "  -a, --all         every topic of the namespace, also those that appear later,\n"
               "                    the parameter changes of its nodes (/horus/params) and its\n"
               "                    frame tree (/horus/frames, /horus/frames_static)\n"
               "  --frames          the namespace's frame tree beside the TOPICS named\n"
               "  -o, --output FILE the file (default: a new session_YYYY_MM_DD_HHMMSS.mcap in\n"
               "                    $HORUS_RECORDINGS, else ~/.local/share/horus/recordings)\n"
               "  --duration S      stop after S seconds\n"
               "  --namespace NS    the namespace (default: $HORUS_NAMESPACE, else 'default')\n");
  return status;
}

/// Waits for SIGINT or SIGTERM (blocked in every thread), at most `seconds` when positive.
void wait_for_end(const sigset_t& signals, double seconds) {
  if (seconds <= 0) {
    int received = 0;
    while (sigwait(&signals, &received) != 0) {
    }
    return;
  }
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  const double end =
      static_cast<double>(now.tv_sec) + static_cast<double>(now.tv_nsec) * 1e-9 + seconds;
  for (;;) {
    clock_gettime(CLOCK_MONOTONIC, &now);
    const double left =
        end - (static_cast<double>(now.tv_sec) + static_cast<double>(now.tv_nsec) * 1e-9);
    if (left <= 0) return;
    timespec timeout{static_cast<time_t>(left), static_cast<long>((left - std::floor(left)) * 1e9)};
    if (sigtimedwait(&signals, nullptr, &timeout) >= 0) return;
    if (errno != EINTR && errno != EAGAIN) return;
  }
}

}  // namespace

int main(int argc, char** argv) {
  // Images, depth images, point clouds and tensors of other processes are kept with their data.
  horus::enable_pool_frames();
  horus::RecorderOptions options;
  double duration = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    const auto value = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "horus-record: %s needs a value\n", argv[i]);
        std::exit(usage(stderr, 2));
      }
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help") return usage(stdout, 0);
    if (arg == "-a" || arg == "--all") {
      options.all_topics = true;
    } else if (arg == "--frames") {
      options.frames = true;
    } else if (arg == "-o" || arg == "--output") {
      options.path = value();
    } else if (arg == "--namespace" || arg == "-n") {
      options.namespace_name = value();
    } else if (arg == "--duration") {
      const char* text = value();
      char* end = nullptr;
      duration = std::strtod(text, &end);
      if (end == text || *end != '\0' || !(duration > 0) || !std::isfinite(duration)) {
        std::fprintf(stderr,
                     "horus-record: --duration needs a positive number of seconds, not '%s'\n",
                     text);
        return 2;
      }
    } else if (!arg.empty() && arg[0] == '-') {
      std::fprintf(stderr, "horus-record: unknown option %s\n", argv[i]);
      return usage(stderr, 2);
    } else {
      options.topics.emplace_back(arg);
    }
  }
  if (options.topics.empty() && !options.all_topics && !options.frames) {
    std::fprintf(stderr,
                 "horus-record: name topics to record, --frames for the frame tree, or -a for "
                 "all of them\n");
    return usage(stderr, 2);
  }
  // Blocked before the recording thread starts, so that only sigwait here receives them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  try {
    horus::Recorder recorder(options);
    std::fprintf(stderr, "horus-record: recording to %s (Ctrl+C to stop)\n",
                 recorder.path().c_str());
    wait_for_end(signals, duration);
    const horus::RecordingSummary summary = recorder.stop();
    std::printf("%s: %llu messages, %llu bytes, %llu lost\n", summary.path.c_str(),
                static_cast<unsigned long long>(summary.messages),
                static_cast<unsigned long long>(summary.bytes),
                static_cast<unsigned long long>(summary.lost_total));
    for (const auto& [topic, lost] : summary.lost) {
      std::printf("  lost on %s: %llu\n", topic.c_str(), static_cast<unsigned long long>(lost));
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "horus-record: %s\n", e.what());
    return 1;
  }
}
