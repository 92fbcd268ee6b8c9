// Real child processes: SIGTERM / SIGINT make a running scheduler shut its nodes down in reverse
// order and exit 0; a crash writes the blackbox before the process dies. Every wait is bounded.
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "horus/blackbox.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;

namespace {

constexpr auto kLimit = std::chrono::seconds(10);

// Writes "<event> <node>" lines to the parent through a pipe (write(2): safe in a forked child).
class Reporter : public horus::Node {
 public:
  Reporter(std::string name, int fd, bool announce)
      : name_(std::move(name)), fd_(fd), announce_(announce) {}
  std::string_view name() const override { return name_; }
  void init() override { say("init " + name_); }
  void tick() override {
    if (announce_ && !announced_) {
      announced_ = true;
      say("ready");
    }
  }
  void shutdown() override { say("shutdown " + name_); }

 private:
  void say(const std::string& line) const {
    const std::string text = line + "\n";
    [[maybe_unused]] const auto n = ::write(fd_, text.data(), text.size());
  }
  std::string name_;
  int fd_;
  bool announce_;
  bool announced_ = false;
};

[[noreturn]] void child_run_scheduler(int fd) {
  int rc = 2;
  try {
    horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(100_hz).name("child")};
    sched.add(std::make_unique<Reporter>("sensor", fd, false)).order(0).build();
    sched.add(std::make_unique<Reporter>("planner", fd, false))
        .order(10)
        .rate(50_hz)
        .compute()
        .build();
    sched.add(std::make_unique<Reporter>("motor", fd, true)).order(20).rate(200_hz).build();
    sched.add(std::make_unique<Reporter>("logger", fd, false)).order(30).build();
    rc = sched.run();
  } catch (...) {
    rc = 3;
  }
  ::close(fd);
  std::_Exit(rc);
}

// Reads lines until `stop_at` is seen (or EOF when empty); false on timeout.
bool read_lines(int fd, std::vector<std::string>& lines, const std::string& stop_at) {
  std::string pending;
  const auto give_up = std::chrono::steady_clock::now() + kLimit;
  while (std::chrono::steady_clock::now() < give_up) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 100) <= 0) continue;
    char buf[256];
    const ssize_t n = ::read(fd, buf, sizeof(buf));
    if (n <= 0) return stop_at.empty();
    pending.append(buf, static_cast<std::size_t>(n));
    for (std::size_t nl; (nl = pending.find('\n')) != std::string::npos;) {
      lines.push_back(pending.substr(0, nl));
      pending.erase(0, nl + 1);
      if (!stop_at.empty() && lines.back() == stop_at) return true;
    }
  }
  return false;
}

// Waits for the child to end; kills it (and returns -1) if it does not within the limit.
int wait_child(pid_t pid) {
  const auto give_up = std::chrono::steady_clock::now() + kLimit;
  int status = 0;
  while (std::chrono::steady_clock::now() < give_up) {
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) return status;
    ::usleep(2000);
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, &status, 0);
  return -1;
}

std::vector<std::string> starting_with(const std::vector<std::string>& lines,
                                       const std::string& prefix) {
  std::vector<std::string> out;
  for (const auto& l : lines) {
    if (l.rfind(prefix, 0) == 0) out.push_back(l);
  }
  return out;
}

class SchedulerSignal : public ::testing::TestWithParam<int> {};

}  // namespace

TEST_P(SchedulerSignal, StopsAndShutsDownInReverseOrder) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::close(fds[0]);
    child_run_scheduler(fds[1]);
  }
  ::close(fds[1]);
  std::vector<std::string> lines;
  const bool ready = read_lines(fds[0], lines, "ready");
  if (!ready) {
    ::kill(pid, SIGKILL);
    wait_child(pid);
    ::close(fds[0]);
    FAIL() << "the child never started ticking";
  }
  ASSERT_EQ(::kill(pid, GetParam()), 0);
  EXPECT_TRUE(read_lines(fds[0], lines, "")) << "the child did not close its pipe";
  ::close(fds[0]);
  const int status = wait_child(pid);
  ASSERT_NE(status, -1) << "the child did not exit after the signal";
  ASSERT_TRUE(WIFEXITED(status)) << "the child died from signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_EQ(starting_with(lines, "init"),
            (std::vector<std::string>{"init sensor", "init planner", "init motor", "init logger"}));
  EXPECT_EQ(starting_with(lines, "shutdown"),
            (std::vector<std::string>{"shutdown logger", "shutdown motor", "shutdown planner",
                                      "shutdown sensor"}));
}

INSTANTIATE_TEST_SUITE_P(Signals, SchedulerSignal, ::testing::Values(SIGTERM, SIGINT),
                         [](const auto& info) {
                           return info.param == SIGTERM ? "SIGTERM" : "SIGINT";
                         });

TEST(SchedulerCrash, AbortWritesTheBlackboxBeforeDying) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("horus_crash_" + std::to_string(::getpid()) + ".blackbox");
  std::filesystem::remove(path);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    class Doomed : public horus::Node {
     public:
      std::string_view name() const override { return "doomed"; }
      void tick() override {
        if (++n_ == 3) std::abort();
      }
      int n_ = 0;
    };
    horus::Scheduler sched{
        horus::SchedulerConfig{}.tick_rate(200_hz).blackbox_mb(1).blackbox_path(path)};
    sched.add(std::make_unique<Doomed>()).build();
    sched.run();
    std::_Exit(0);
  }
  const int status = wait_child(pid);
  ASSERT_NE(status, -1);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the child should have died";
  EXPECT_EQ(WTERMSIG(status), SIGABRT);
  ASSERT_TRUE(std::filesystem::exists(path)) << "no blackbox was written on the crash";
  const auto events = horus::read_blackbox(path);
  std::filesystem::remove(path);
  ASSERT_GE(events.size(), 2U);
  EXPECT_EQ(events[0].kind, horus::BlackboxEventKind::SchedulerStart);
  EXPECT_EQ(events[1].kind, horus::BlackboxEventKind::NodeInit);
  EXPECT_EQ(events[1].node_name(), "doomed");
}
