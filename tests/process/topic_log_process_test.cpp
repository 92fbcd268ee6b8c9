// A C++ program's verbose topics as an operator sees them: a child process sends on verbose
// topics (a string, and a number at 1 kHz), and `horus log` (bin/horus, another process) shows
// their lines with the summaries, at most ten a second, and the count of the lines suppressed.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <stdexcept>
#include <string>
#include <thread>

#include "horus/topic.hpp"
#include "private_shm_root.hpp"

namespace {

// The child, bin/horus and this process share a private root outside /dev/shm, removed at exit.
const horus_test::PrivateShmRoot shm_root{"verbose"};

std::string horus_log() {
  std::FILE* pipe = ::popen(HORUS_CLI " log 2>&1", "r");
  if (pipe == nullptr) throw std::runtime_error("popen failed");
  std::string output;
  std::array<char, 4096> buffer{};
  while (const std::size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe)) {
    output.append(buffer.data(), n);
  }
  const int status = ::pclose(pipe);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << output;
  return output;
}

}  // namespace

TEST(VerboseTopicProcess, AChildsLinesAreInHorusLogRateLimitedWithASuppressedCount) {
  constexpr int kMessages = 1000;
  const auto started = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    {
      horus::TopicOptions options;
      options.verbose = true;
      horus::Topic<std::string> status("status", options);
      status.send("docking");
      horus::Topic<double> speed("speed", options);
      auto next = std::chrono::steady_clock::now();
      for (int i = 0; i < kMessages; ++i) {
        next += std::chrono::milliseconds(1);
        std::this_thread::sleep_until(next);
        speed.send(i + 0.5);
      }
    }  // dropping the handles reports what they still held back
    std::_Exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();

  const std::string log = horus_log();
  const std::regex sent(R"(Z INFO -: speed send: \d+\.5\n)");
  const std::regex suppressed(
      R"(Z INFO -: speed: (\d+) lines suppressed \(a verbose topic logs at most 10 lines a second\)\n)");
  const auto lines = static_cast<std::size_t>(
      std::distance(std::sregex_iterator(log.begin(), log.end(), sent), std::sregex_iterator()));
  std::size_t reports = 0;
  std::uint64_t held_back = 0;
  for (auto it = std::sregex_iterator(log.begin(), log.end(), suppressed);
       it != std::sregex_iterator(); ++it) {
    ++reports;
    held_back += std::stoull((*it)[1].str());
  }
  EXPECT_NE(log.find("Z INFO -: status send: \"docking\"\n"), std::string::npos) << log;
  EXPECT_NE(log.find("Z INFO -: speed send: 0.5\n"), std::string::npos) << log;
  EXPECT_GE(reports, 1U) << log;
  EXPECT_EQ(lines + held_back, static_cast<std::uint64_t>(kMessages)) << log;
  // Ten lines per one-second window begun, however fast the machine ran the child.
  EXPECT_LE(lines, 10U * (static_cast<std::size_t>(std::ceil(seconds)) + 1)) << seconds << " s";
}
