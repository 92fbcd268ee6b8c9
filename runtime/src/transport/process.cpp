// Who this process is (its pid for the hot path, its identity for shared tables), cached and
// forgotten in every forked child; and whether the process an entry names still runs.
#include "horus/detail/process.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>

namespace horus::detail {

namespace {

std::atomic<std::uint64_t> cached_identity{0};

/// What /proc/<pid>/stat says of a process: its state letter and its start time in clock ticks
/// since boot.
struct ProcessStat {
  char state = '?';
  std::uint64_t start_ticks = 0;
};

bool read_process_stat(std::uint32_t pid, ProcessStat& stat) noexcept {
  char path[32];
  std::snprintf(path, sizeof path, "/proc/%u/stat", pid);
  std::FILE* file = std::fopen(path, "re");
  if (file == nullptr) {
    return false;
  }
  char text[1024];
  const std::size_t length = std::fread(text, 1, sizeof text - 1, file);
  std::fclose(file);
  text[length] = '\0';
  // The command name (field 2) may hold spaces and parentheses: fields 3 on follow its last ')'.
  // Field 3 is the state; the start time is field 22, past the 18 fields in between.
  const char* fields = std::strrchr(text, ')');
  if (fields == nullptr) {
    return false;
  }
  unsigned long long start = 0;
  const int read =
      std::sscanf(fields + 1,
                  " %c %*s %*s %*s %*s %*s %*s %*s %*s %*s %*s %*s %*s %*s %*s %*s %*s "
                  "%*s %*s %llu",
                  &stat.state, &start);
  stat.start_ticks = start;
  return read == 2;
}

}  // namespace

bool process_alive(std::uint32_t pid) noexcept {
  if (pid == 0) {
    return false;
  }
  return ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM;
}

std::uint32_t refresh_pid() noexcept {
  [[maybe_unused]] static const int forgotten_on_fork = ::pthread_atfork(nullptr, nullptr, [] {
    cached_pid.store(0, std::memory_order_relaxed);
    cached_identity.store(0, std::memory_order_relaxed);
  });
  const auto pid = static_cast<std::uint32_t>(::getpid());
  cached_pid.store(pid, std::memory_order_relaxed);
  return pid;
}

std::uint64_t this_process_identity() noexcept {
  const std::uint32_t pid = this_pid();
  if (const std::uint64_t identity = cached_identity.load(std::memory_order_relaxed);
      identity_pid(identity) == pid) {
    return identity;
  }
  ProcessStat stat;
  const std::uint64_t start = read_process_stat(pid, stat) ? stat.start_ticks & 0xffffffffU : 0;
  const std::uint64_t identity = start << 32 | pid;
  cached_identity.store(identity, std::memory_order_relaxed);
  return identity;
}

bool identity_alive(std::uint64_t identity) noexcept {
  const std::uint32_t pid = identity_pid(identity);
  if (!process_alive(pid)) {
    return false;
  }
  ProcessStat stat;
  if (!read_process_stat(pid, stat)) {
    // No /proc to ask (or not allowed to): the pid is all there is to go by.
    return true;
  }
  const std::uint64_t start = identity >> 32;
  const bool exited = stat.state == 'Z' || stat.state == 'X';
  return !exited && (start == 0 || (stat.start_ticks & 0xffffffffU) == start);
}

std::int64_t identity_start_wall_ns(std::uint64_t identity) noexcept {
  const std::uint64_t start = identity >> 32;
  const long ticks_per_second = ::sysconf(_SC_CLK_TCK);
  timespec boot{};
  timespec wall{};
  if (start == 0 || ticks_per_second <= 0 || ::clock_gettime(CLOCK_BOOTTIME, &boot) != 0 ||
      ::clock_gettime(CLOCK_REALTIME, &wall) != 0) {
    return 0;
  }
  const std::int64_t tick_ns = 1'000'000'000 / ticks_per_second;
  const std::int64_t since_boot_ns = boot.tv_sec * 1'000'000'000LL + boot.tv_nsec;
  const auto now_ticks = static_cast<std::uint64_t>(since_boot_ns / tick_ns);
  // The identity keeps the start's low 32 bits (497 days at 100 ticks/s): the start is the
  // latest tick count up to now with those bits, so a machine up longer still gets it right.
  const std::uint64_t start_ticks = now_ticks - ((now_ticks - start) & 0xffffffffU);
  // Boot time from two continuous clocks, not from the tick count: the same start reads the
  // same (to the microsecond) each time it is asked.
  const std::int64_t booted_wall_ns = wall.tv_sec * 1'000'000'000LL + wall.tv_nsec - since_boot_ns;
  return booted_wall_ns + static_cast<std::int64_t>(start_ticks) * tick_ns;
}

std::string process_name(std::uint32_t pid) {
  char path[32];
  std::snprintf(path, sizeof path, "/proc/%u/comm", pid);
  char name[64] = {};
  const int fd = ::open(path, O_RDONLY | O_CLOEXEC);
  ssize_t got = fd >= 0 ? ::read(fd, name, sizeof name - 1) : -1;
  if (fd >= 0) ::close(fd);
  while (got > 0 && (name[got - 1] == '\n' || name[got - 1] == '\0')) --got;
  return got > 0 ? std::string(name, static_cast<std::size_t>(got)) : std::string();
}

}  // namespace horus::detail
