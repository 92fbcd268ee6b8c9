#include "signals.hpp"

#include <fcntl.h>
#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <climits>
#include <cstdio>
#include <iterator>
#include <string>

#include "scheduler_impl.hpp"

namespace horus::detail {
namespace {

std::atomic<int> g_signal{0};
std::atomic<std::atomic<std::uint32_t>*> g_wake_word{nullptr};
std::atomic<const Blackbox*> g_crash_box{nullptr};
char g_crash_path[4096];

void on_stop_signal(int signo) {
  g_signal.store(signo);
  if (auto* word = g_wake_word.load()) wake(*word);
}

constexpr int kCrashSignals[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT};
struct sigaction g_previous_crash[std::size(kCrashSignals)];

void on_crash_signal(int signo) {
  if (const Blackbox* box = g_crash_box.exchange(nullptr)) {
    const int fd = ::open(g_crash_path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd >= 0) {
      box->write_to_fd(fd);
      ::close(fd);
      static const char note[] = "[horus] crash: blackbox written\n";
      [[maybe_unused]] const auto n = ::write(STDERR_FILENO, note, sizeof(note) - 1);
    }
  }
  for (std::size_t i = 0; i < std::size(kCrashSignals); ++i) {
    if (kCrashSignals[i] == signo) sigaction(signo, &g_previous_crash[i], nullptr);
  }
  raise(signo);
}

}  // namespace

void wake(std::atomic<std::uint32_t>& word) noexcept {
  word.store(1, std::memory_order_release);
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAKE_PRIVATE, INT_MAX, nullptr,
          nullptr, 0);
}

int take_stop_signal() noexcept { return g_signal.exchange(0); }

SignalScope::SignalScope(bool stop_signals, std::atomic<std::uint32_t>& word, const Blackbox* box,
                         const std::filesystem::path& box_path)
    : stop_signals_(stop_signals), crash_(box != nullptr) {
  if (stop_signals_) {
    g_signal.store(0);
    g_wake_word.store(&word);
    struct sigaction action {};
    action.sa_handler = on_stop_signal;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &previous_int_);
    sigaction(SIGTERM, &action, &previous_term_);
  }
  if (crash_) {
    const std::string path = std::filesystem::absolute(box_path).string();
    std::snprintf(g_crash_path, sizeof(g_crash_path), "%s", path.c_str());
    g_crash_box.store(box);
    struct sigaction action {};
    action.sa_handler = on_crash_signal;
    sigemptyset(&action.sa_mask);
    for (std::size_t i = 0; i < std::size(kCrashSignals); ++i) {
      sigaction(kCrashSignals[i], &action, &g_previous_crash[i]);
    }
  }
}

SignalScope::~SignalScope() {
  if (stop_signals_) {
    sigaction(SIGINT, &previous_int_, nullptr);
    sigaction(SIGTERM, &previous_term_, nullptr);
    g_wake_word.store(nullptr);
  }
  if (crash_) {
    g_crash_box.store(nullptr);
    for (std::size_t i = 0; i < std::size(kCrashSignals); ++i) {
      sigaction(kCrashSignals[i], &g_previous_crash[i], nullptr);
    }
  }
}

void SchedulerImpl::check_signal() noexcept {
  const int signo = take_stop_signal();
  if (signo != 0) {
    char reason[48];
    std::snprintf(reason, sizeof(reason), "received %s", signo == SIGINT ? "SIGINT" : "SIGTERM");
    request_stop(reason, false);
  }
}

}  // namespace horus::detail
