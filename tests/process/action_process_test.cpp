// Actions across real processes: tests/process/action_peer.cpp serves or sends Navigate goals
// in a process of its own, which a test SIGKILLs mid-goal. Each test has its own namespace.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <horus/action.hpp>
#include <horus_test/action/navigate.hpp>

#include "topic_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using horus::GoalState;
using horus_test::action::Navigate;

constexpr auto kLong = 5s;

/// action_peer with its stdout read line by line.
class Peer {
 public:
  explicit Peer(const std::vector<std::string>& args) {
    int out[2];
    if (::pipe2(out, O_CLOEXEC) != 0) return;
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    std::vector<std::string> argv_text{HORUS_ACTION_PEER};
    argv_text.insert(argv_text.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& text : argv_text) argv.push_back(text.data());
    argv.push_back(nullptr);
    if (::posix_spawn(&pid_, HORUS_ACTION_PEER, &actions, nullptr, argv.data(), environ) != 0) {
      pid_ = -1;
    }
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    out_ = out[0];
  }
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;
  ~Peer() {
    kill(SIGKILL);
    if (out_ >= 0) ::close(out_);
  }

  pid_t pid() const { return pid_; }

  /// The next line, waiting up to `timeout`; none at the end of the output or on timeout.
  std::optional<std::string> line(std::chrono::milliseconds timeout = kLong) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const std::size_t end = buffer_.find('\n');
      if (end != std::string::npos) {
        std::string text = buffer_.substr(0, end);
        buffer_.erase(0, end + 1);
        return text;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return std::nullopt;
      pollfd ready{out_, POLLIN, 0};
      if (::poll(&ready, 1, static_cast<int>(left.count())) <= 0) continue;
      char chunk[512];
      const ssize_t got = ::read(out_, chunk, sizeof chunk);
      if (got <= 0) return std::nullopt;
      buffer_.append(chunk, static_cast<std::size_t>(got));
    }
  }

  /// Lines until one starting with `prefix` (which it returns); none if it never came.
  std::optional<std::string> until(std::string_view prefix,
                                   std::chrono::milliseconds timeout = kLong) {
    while (std::optional<std::string> text = line(timeout)) {
      if (text->rfind(prefix, 0) == 0) return text;
    }
    return std::nullopt;
  }

  void kill(int signal) {
    if (pid_ > 0) {
      ::kill(pid_, signal);
      ::waitpid(pid_, nullptr, 0);
      pid_ = -1;
    }
  }

  int wait() {
    int status = 0;
    if (pid_ <= 0 || ::waitpid(pid_, &status, 0) != pid_) return -1;
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  std::string buffer_;
};

void drive(horus::ServerGoal<Navigate>& goal) {
  const std::uint32_t count = goal.goal().feedback_count;
  for (std::uint32_t step = 1; step <= count; ++step) {
    std::this_thread::sleep_for(std::chrono::microseconds(goal.goal().period_us));
    if (goal.is_cancel_requested()) {
      goal.cancel({false, 0.0, 0.0, step - 1});
      return;
    }
    goal.publish_feedback({step, static_cast<double>(count - step)});
  }
  goal.succeed({true, goal.goal().x, goal.goal().y, count});
}

class ActionProcessTest : public ::testing::Test {
 protected:
  topic_test::PrivateNamespace namespace_;
};

TEST_F(ActionProcessTest, NavigateGoalWithTwentyFeedbacks) {
  Peer server({"serve"});
  ASSERT_EQ(server.line(), "ready");
  Peer client({"send", "3", "4"});
  ASSERT_EQ(client.line()->rfind("accepted ", 0), 0u);
  for (int step = 1; step <= 20; ++step) {
    EXPECT_EQ(client.line(), "feedback " + std::to_string(step));
  }
  EXPECT_EQ(client.line(), "succeeded ");
  EXPECT_EQ(client.wait(), 0);
}

TEST_F(ActionProcessTest, CancelMidGoal) {
  Peer server({"serve"});
  ASSERT_EQ(server.line(), "ready");
  Peer client({"send", "1", "0", "--count", "1000", "--cancel-after", "3"});
  EXPECT_EQ(client.until("canceled"), "canceled canceled by a client");
  EXPECT_EQ(client.wait(), 1);
}

TEST_F(ActionProcessTest, AbortedWithTheServersReason) {
  Peer server({"serve"});
  ASSERT_EQ(server.line(), "ready");
  Peer client({"send", "1", "0", "--abort-with", "no path"});
  EXPECT_EQ(client.until("aborted"), "aborted no path");
  EXPECT_EQ(client.wait(), 1);
}

TEST_F(ActionProcessTest, RejectPolicyWithTwoClients) {
  Peer server({"serve", "--policy", "reject"});
  ASSERT_EQ(server.line(), "ready");
  Peer first({"send", "1", "0", "--count", "100000"});
  const std::optional<std::string> accepted = first.line();
  ASSERT_TRUE(accepted && accepted->rfind("accepted ", 0) == 0);
  Peer second({"send", "2", "0"});
  EXPECT_EQ(second.line(), "rejected busy: goal " + accepted->substr(9) + " is executing");
  EXPECT_EQ(second.wait(), 1);
  // The first goal still runs; the peer's end (SIGKILL) ends it.
}

TEST_F(ActionProcessTest, PreemptPolicyWithTwoClients) {
  Peer server({"serve", "--policy", "preempt"});
  ASSERT_EQ(server.line(), "ready");
  Peer first({"send", "1", "0", "--count", "1000"});
  ASSERT_TRUE(first.until("feedback"));
  Peer second({"send", "2", "0", "--count", "3"});
  const std::optional<std::string> accepted = second.line();
  ASSERT_TRUE(accepted && accepted->rfind("accepted ", 0) == 0);
  EXPECT_EQ(first.until("canceled"), "canceled preempted by goal " + accepted->substr(9));
  EXPECT_EQ(second.until("succeeded"), "succeeded ");
}

TEST_F(ActionProcessTest, QueuePolicyWithTwoClients) {
  Peer server({"serve", "--policy", "queue", "--capacity", "1"});
  ASSERT_EQ(server.line(), "ready");
  Peer first({"send", "1", "0", "--count", "20"});
  ASSERT_TRUE(first.until("feedback"));
  Peer second({"send", "2", "0", "--count", "3"});
  ASSERT_EQ(second.line()->rfind("accepted ", 0), 0u);
  EXPECT_EQ(first.until("succeeded"), "succeeded ");
  EXPECT_EQ(second.until("succeeded"), "succeeded ");
  EXPECT_EQ(first.wait(), 0);
  EXPECT_EQ(second.wait(), 0);
}

TEST_F(ActionProcessTest, ServerKilledMidGoalAbortsTheGoalWithinASecond) {
  Peer server({"serve"});
  ASSERT_EQ(server.line(), "ready");
  horus::ActionClient<Navigate> client;
  Navigate::Goal goal{};
  goal.x = 1.0;
  goal.feedback_count = 100000;
  goal.period_us = 5000;
  auto handle = client.send_goal(goal, kLong);
  ASSERT_TRUE(handle) << handle.error().to_string();
  ASSERT_TRUE(handle->next_feedback(kLong));
  const pid_t pid = server.pid();
  const auto killed = std::chrono::steady_clock::now();
  server.kill(SIGKILL);
  auto outcome = handle->result(kLong);
  ASSERT_TRUE(outcome);
  EXPECT_LT(std::chrono::steady_clock::now() - killed, 1s);
  EXPECT_EQ(outcome->state, GoalState::Aborted);
  EXPECT_EQ(outcome->reason, "the action server (pid " + std::to_string(pid) + ") exited mid-goal");
}

TEST_F(ActionProcessTest, ClientKilledMidGoalEndsItsGoalAndTheNextClientIsServed) {
  std::mutex ended_mutex;
  std::optional<std::string> ended_reason;
  auto server = horus::ActionServerBuilder<Navigate>()
                    .on_execute([&](horus::ServerGoal<Navigate>& goal) {
                      drive(goal);
                      std::lock_guard lock(ended_mutex);
                      if (!ended_reason) ended_reason = goal.cancel_reason();
                    })
                    .build();
  Peer first({"send", "1", "0", "--count", "100000"});
  ASSERT_TRUE(first.until("feedback"));
  const pid_t pid = first.pid();
  first.kill(SIGKILL);
  for (auto until = std::chrono::steady_clock::now() + 1s; server.stats().canceled == 0;) {
    ASSERT_LT(std::chrono::steady_clock::now(), until) << "the dead client's goal still runs";
    std::this_thread::sleep_for(5ms);
  }
  {
    std::lock_guard lock(ended_mutex);
    EXPECT_EQ(ended_reason, "the client (pid " + std::to_string(pid) + ") exited");
  }
  Peer second({"send", "2", "0", "--count", "3"});
  EXPECT_EQ(second.until("succeeded"), "succeeded ");
  EXPECT_EQ(second.wait(), 0);
}

TEST_F(ActionProcessTest, GoalWithoutServerIsRefusedAtOnce) {
  const auto start = std::chrono::steady_clock::now();
  Peer client({"send", "1", "0"});
  const std::optional<std::string> text = client.line();
  ASSERT_TRUE(text);
  EXPECT_EQ(text->rfind("error NoServer", 0), 0u) << *text;
  EXPECT_EQ(client.wait(), 1);
  EXPECT_LT(std::chrono::steady_clock::now() - start, 2s);  // a process start, not a timeout
}

}  // namespace
