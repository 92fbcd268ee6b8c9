// SchedulerConfig::network()'s bridge process: validation, the command line, finding `horus`,
// and a child that lives no longer than the scheduler (README.md).
#include "horus/detail/bridge_process.hpp"

#include <fcntl.h>
#include <linux/close_range.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string_view>
#include <utility>

#include "horus/detail/errno_text.hpp"
#include "horus/error.hpp"

namespace horus::detail {
namespace {

// Compiled in by CMakeLists.txt: where `cmake --install` puts the command, and the build tree's.
constexpr std::string_view kInstalledCommand = HORUS_INSTALLED_CLI;
constexpr std::string_view kBuildTreeCommand = HORUS_BUILD_TREE_CLI;

bool is_program(const std::string& path) {
  struct stat info {};
  return ::stat(path.c_str(), &info) == 0 && S_ISREG(info.st_mode) &&
         ::access(path.c_str(), X_OK) == 0;
}

/// `name` itself when it has a slash, else the first executable `name` in a PATH folder.
std::optional<std::string> find_program(const std::string& name) {
  if (name.find('/') != std::string::npos) {
    if (is_program(name)) return name;
    return std::nullopt;
  }
  const char* path = std::getenv("PATH");  // NOLINT(concurrency-mt-unsafe): set-up only
  std::string_view folders = path != nullptr ? path : "";
  while (!folders.empty()) {
    const std::size_t colon = folders.find(':');
    const std::string_view folder = folders.substr(0, colon);
    std::string candidate = std::string(folder.empty() ? "." : folder) + "/" + name;
    if (is_program(candidate)) return candidate;
    folders = colon == std::string_view::npos ? std::string_view{} : folders.substr(colon + 1);
  }
  return std::nullopt;
}

/// Seconds as `horus bridge` reads them, to the nanosecond and without trailing zeros.
std::string seconds_text(std::chrono::duration<double> seconds) {
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", seconds.count());
  return text;
}

void check_patterns(const std::vector<std::string>& patterns, std::string_view field) {
  for (const std::string& pattern : patterns) {
    if (pattern.empty()) {
      throw Error(std::string(field) + " has an empty pattern, which names nothing");
    }
  }
}

// Only async-signal-safe calls: the child of a threaded process until exec.
[[noreturn]] void become_bridge(char* const* argv, pid_t parent, int report) noexcept {
  sigset_t none;
  ::sigemptyset(&none);
  // The scheduler's threads may block SIGTERM; the child has one thread.
  ::sigprocmask(SIG_SETMASK, &none, nullptr);  // NOLINT(concurrency-mt-unsafe)
  struct sigaction by_default {};
  by_default.sa_handler = SIG_DFL;
  ::sigaction(SIGTERM, &by_default, nullptr);  // an ignored signal would stay ignored after exec
  ::sigaction(SIGINT, &by_default, nullptr);
  // A group of its own: Ctrl+C reaches the scheduler alone, which ends the bridge after its
  // nodes' shutdown; the bridge dies with the thread that forked it (the scheduler's process).
  ::setpgid(0, 0);
  if (::prctl(PR_SET_PDEATHSIG, SIGTERM) != 0 || ::getppid() != parent) ::_exit(127);
  ::close_range(3, ~0U, CLOSE_RANGE_CLOEXEC);  // no descriptor of the scheduler's leaks into it
  ::execv(argv[0], argv);
  const int error = errno;
  [[maybe_unused]] const ssize_t written = ::write(report, &error, sizeof error);
  ::_exit(127);
}

/// What ended the bridge, when it is a failure ("" when it exited with status 0).
std::string failure_of(pid_t pid, const siginfo_t* end) {
  const std::string who = "network: the bridge process (pid " + std::to_string(pid) + ") ";
  if (end == nullptr) return who + "ended with an unknown status";
  if (end->si_code == CLD_EXITED) {
    if (end->si_status == 0) return "";
    return who + "exited with status " + std::to_string(end->si_status) +
           " (its line on stderr says why)";
  }
  const char* name = ::sigabbrev_np(end->si_status);
  return who + "was killed by signal " + std::to_string(end->si_status) +
         (name != nullptr ? " (SIG" + std::string(name) + ")" : std::string{});
}

}  // namespace

void validate_network(const Network& network) {
  if (network.export_.empty() && network.import_.empty() && network.export_services.empty() &&
      network.import_services.empty()) {
    throw Error(
        "a Network carries nothing: give export_ and/or import_ patterns (or export_services, "
        "import_services)");
  }
  check_patterns(network.export_, "export_");
  check_patterns(network.import_, "import_");
  check_patterns(network.transient_local, "transient_local");
  check_patterns(network.export_services, "export_services");
  check_patterns(network.import_services, "import_services");
  check_patterns(network.ros2_types, "ros2_types");
  if (network.domain < 0 || network.domain > 232) {
    throw Error("domain must be a DDS domain id (0..232), got " + std::to_string(network.domain));
  }
  if (network.depth < 1) {
    throw Error("depth must be at least 1, got " + std::to_string(network.depth));
  }
  if (!(network.service_timeout.count() > 0.0) || std::isinf(network.service_timeout.count())) {
    throw Error("service_timeout must be a finite number of seconds above 0, got " +
                seconds_text(network.service_timeout) + " s");
  }
  for (const auto& [pattern, period] : network.deadlines) {
    if (pattern.empty()) throw Error("deadlines has an empty pattern, which names nothing");
    if (period.count() < 1) {
      throw Error("the deadline of '" + pattern + "' must be at least 1 ms, got " +
                  std::to_string(period.count()) + " ms");
    }
  }
}

std::vector<std::string> bridge_arguments(const Network& network,
                                          const std::string& namespace_name) {
  // --option=VALUE throughout: a pattern that starts with '-' stays a value.
  std::vector<std::string> arguments{"bridge", "--namespace=" + namespace_name,
                                     "--domain=" + std::to_string(network.domain),
                                     "--depth=" + std::to_string(network.depth)};
  if (!network.reliable) arguments.emplace_back("--best-effort");
  const auto each = [&](std::string_view option, const std::vector<std::string>& patterns) {
    for (const std::string& pattern : patterns) {
      arguments.push_back(std::string(option) + "=" + pattern);
    }
  };
  each("--export", network.export_);
  each("--import", network.import_);
  each("--transient-local", network.transient_local);
  each("--export-service", network.export_services);
  each("--import-service", network.import_services);
  for (const auto& [pattern, period] : network.deadlines) {
    arguments.push_back("--deadline=" + pattern + "=" + std::to_string(period.count()));
  }
  arguments.push_back("--service-timeout=" + seconds_text(network.service_timeout));
  each("--ros2-types", network.ros2_types);
  if (network.accept_untyped_writers) arguments.emplace_back("--accept-untyped-writers");
  return arguments;
}

std::string bridge_program() {
  const char* given = std::getenv("HORUS_BRIDGE_PROGRAM");  // NOLINT(concurrency-mt-unsafe)
  if (given != nullptr && *given != 0) {
    if (auto found = find_program(given)) return *std::move(found);
    throw Error("HORUS_BRIDGE_PROGRAM is '" + std::string(given) + "', which is no executable" +
                (std::string_view(given).find('/') == std::string_view::npos ? " on PATH" : ""));
  }
  for (const std::string_view candidate :
       {kInstalledCommand, std::string_view("horus"), kBuildTreeCommand}) {
    if (auto found = find_program(std::string(candidate))) return *std::move(found);
  }
  throw Error(
      "no `horus` command to run the bridge: HORUS_BRIDGE_PROGRAM is unset, and there is "
      "none at " +
      std::string(kInstalledCommand) + ", on PATH or at " + std::string(kBuildTreeCommand));
}

BridgeProcess::BridgeProcess(const Network& network, const std::string& namespace_name,
                             OnFailure on_failure)
    : on_failure_(std::move(on_failure)) {
  validate_network(network);
  std::string program = bridge_program();
  std::vector<std::string> argv = bridge_arguments(network, namespace_name);
  argv.insert(argv.begin(), program);
  std::promise<int> started;
  std::future<int> exec_error = started.get_future();
  watcher_ = std::thread(&BridgeProcess::watch, this, std::move(argv), std::move(started));
  if (const int error = exec_error.get(); error != 0) {
    watcher_.join();
    throw Error("cannot run " + program + ": " + errno_text(error));
  }
}

BridgeProcess::~BridgeProcess() { end(); }

void BridgeProcess::watch(std::vector<std::string> argv, std::promise<int> started) {
  std::vector<char*> pointers;
  for (std::string& argument : argv) pointers.push_back(argument.data());
  pointers.push_back(nullptr);
  int report[2];
  if (::pipe2(report, O_CLOEXEC) != 0) {
    started.set_value(errno);
    return;
  }
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) become_bridge(pointers.data(), parent, report[1]);
  int error = pid < 0 ? errno : 0;
  ::close(report[1]);
  // The report pipe closes unread on a successful exec, or carries exec's errno.
  while (pid > 0 && ::read(report[0], &error, sizeof error) < 0 && errno == EINTR) {
  }
  ::close(report[0]);
  if (error != 0) {
    if (pid > 0) ::waitpid(pid, nullptr, 0);
    started.set_value(error);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    pid_ = pid;
  }
  started.set_value(0);
  // Waited for without reaping, so that end() never signals a pid the kernel gave to another.
  siginfo_t ended{};
  int waited = 0;
  while ((waited = ::waitid(P_PID, static_cast<id_t>(pid), &ended, WEXITED | WNOWAIT)) != 0 &&
         errno == EINTR) {
  }
  bool requested = false;
  {
    std::lock_guard lock(mutex_);
    exited_ = true;
    requested = ending_;
  }
  ::waitpid(pid, nullptr, 0);
  {
    std::lock_guard lock(mutex_);
    reaped_ = true;
  }
  reaped_changed_.notify_all();
  if (!requested) {
    if (std::string failure = failure_of(pid, waited == 0 ? &ended : nullptr); !failure.empty()) {
      on_failure_(failure);
    }
  }
}

void BridgeProcess::end() noexcept {
  if (!watcher_.joinable()) return;
  {
    std::unique_lock lock(mutex_);
    ending_ = true;
    if (!exited_) ::kill(pid_, SIGTERM);
    if (!reaped_changed_.wait_for(lock, kTermGrace, [this] { return reaped_; })) {
      if (!exited_) {
        std::fprintf(stderr,
                     "horus: the network's bridge (pid %d) did not end within %lld s of SIGTERM; "
                     "killing it\n",
                     static_cast<int>(pid_), static_cast<long long>(kTermGrace.count()));
        ::kill(pid_, SIGKILL);
      }
      reaped_changed_.wait(lock, [this] { return reaped_; });
    }
  }
  watcher_.join();
}

}  // namespace horus::detail
