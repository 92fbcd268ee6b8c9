// The README's examples, cut out of README.md as written (tests/process/CMakeLists.txt), run as
// a reader runs them: each test in its own namespace, every wait bounded.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <thread>

#include <horus/log.hpp>
#include <horus/msg/cmd_vel.hpp>
#include <horus/presence.hpp>
#include <horus/topic.hpp>
#include <topic_test/sample.hpp>

#include "topic_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using topic_test::PrivateNamespace;

constexpr auto kLong = 30s;

/// A program of the build running with this process's environment, its stdout and stderr
/// together in an unlinked file.
class Program {
 public:
  explicit Program(const char* path) {
    char name[] = "/tmp/horus_readme_XXXXXX";
    output_ = ::mkstemp(name);
    ::unlink(name);
    posix_spawn_file_actions_t actions;
    ::posix_spawn_file_actions_init(&actions);
    ::posix_spawn_file_actions_adddup2(&actions, output_, STDOUT_FILENO);
    ::posix_spawn_file_actions_adddup2(&actions, output_, STDERR_FILENO);
    char* argv[] = {const_cast<char*>(path), nullptr};
    if (::posix_spawn(&pid_, path, &actions, nullptr, argv, environ) != 0) pid_ = -1;
    ::posix_spawn_file_actions_destroy(&actions);
  }
  Program(const Program&) = delete;
  Program& operator=(const Program&) = delete;
  ~Program() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    ::close(output_);
  }

  void signal(int number) const { ::kill(pid_, number); }

  /// The exit status (128 + the signal that ended it), or -1 when it had to be killed.
  int wait() {
    const auto deadline = std::chrono::steady_clock::now() + kLong;
    int status = 0;
    while (pid_ > 0 && ::waitpid(pid_, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, nullptr, 0);
        pid_ = -1;
        return -1;
      }
      std::this_thread::sleep_for(2ms);
    }
    if (pid_ <= 0) return -1;
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }

  /// What it wrote so far.
  std::string output() const {
    std::string text;
    char buffer[4096];
    off_t offset = 0;
    for (ssize_t got; (got = ::pread(output_, buffer, sizeof buffer, offset)) > 0; offset += got) {
      text.append(buffer, static_cast<std::size_t>(got));
    }
    return text;
  }

 private:
  pid_t pid_ = -1;
  int output_ = -1;
};

/// Waits (bounded) until `done` holds.
template <class Condition>
bool eventually(Condition done) {
  const auto deadline = std::chrono::steady_clock::now() + kLong;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(5ms);
  }
  return true;
}

/// The source of the namespace's first log line with this text ("" when there is none).
std::string logged_by(const std::string& message) {
  for (const horus::LogRecord& record : horus::read_log().records) {
    if (record.message.rfind(message, 0) == 0) return record.source;
  }
  return "";
}

TEST(ReadmeExamples, TheNodeDrivesUntilSigtermThenShutsDown) {
  PrivateNamespace ns;
  Program driver(HORUS_README_NODE);
  horus::Topic<horus::msg::CmdVel> cmd("cmd_vel");
  ASSERT_TRUE(eventually([&] {
    cmd.send(horus::msg::CmdVel{0, 0.5F, 0.1F});
    return logged_by("driving: ") == "driver";
  })) << driver.output();
  driver.signal(SIGTERM);
  EXPECT_EQ(driver.wait(), 0) << driver.output();
  EXPECT_EQ(logged_by("motors zeroed"), "driver") << driver.output();
}

TEST(ReadmeExamples, TheNodeNamesWhoHoldsATopicOfAnotherTypeAndExitsWithOne) {
  PrivateNamespace ns;
  horus::Topic<topic_test::Sample> taken("cmd_vel");  // as a process built from another schema
  Program driver(HORUS_README_NODE);
  EXPECT_EQ(driver.wait(), 1) << "an uncaught horus::Error aborts (134): " << driver.output();
  const std::string output = driver.output();
  EXPECT_EQ(output.rfind("driver: topic 'cmd_vel' (", 0), 0U) << output;
  EXPECT_NE(output.find("carries topic_test.Sample"), std::string::npos) << output;
  // This test's program, as the kernel names it (15 characters at most).
  EXPECT_NE(output.find("open in pid " + std::to_string(::getpid()) + " (readme_examples)"),
            std::string::npos)
      << output;
  EXPECT_NE(output.find("cannot open it as horus.msg.CmdVel"), std::string::npos) << output;
}

TEST(ReadmeExamples, TheServiceAnswersAndItsHandlerLogsInTheServicesName) {
  PrivateNamespace ns;
  Program services(HORUS_README_SERVICES);
  EXPECT_EQ(services.wait(), 0) << services.output();
  const std::string output = services.output();
  EXPECT_NE(output.find("2 + 3 = 5\n"), std::string::npos) << output;
  EXPECT_NE(output.find(" INFO AddTwoInts: adding 2 and 3\n"), std::string::npos) << output;
  EXPECT_EQ(logged_by("adding 2 and 3"), "AddTwoInts");
}

}  // namespace
