// The C++ end of the Python runtime's latency benchmark (bench_runtime.py): echoes every message
// of `ping` onto `pong` as soon as it arrives (busy-polling, as the Python ends do), COUNT times.
//   horus_py_bench_echo typed|dict COUNT
#include <sched.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <string_view>

#include <horus/msg.hpp>
#include <horus/topic.hpp>

namespace {

void pin(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  sched_setaffinity(0, sizeof(set), &set);
}

template <class T>
int echo(long count) {
  horus::Topic<T> ping("ping");
  horus::Topic<T> pong("pong");
  std::printf("ready\n");
  std::fflush(stdout);
  for (long i = 0; i < count; ++i) {
    for (;;) {
      if (auto msg = ping.try_recv()) {
        pong.send(*msg);
        break;
      }
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s typed|dict COUNT\n", argv[0]);
    return 2;
  }
  pin(1);
  const std::string_view kind = argv[1];
  const long count = std::atol(argv[2]);
  if (kind == "typed") return echo<horus::msg::CmdVel>(count);
  if (kind == "dict") return echo<horus::msg::GenericMessage>(count);
  return 2;
}
