// Helpers shared by the transport tests: checksummed payloads, a private namespace per test,
// and child processes that re-execute the test binary in a role.
#pragma once

#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <horus/detail/shm_segment.hpp>
#include <horus/topic_registry.hpp>

extern char** environ;

namespace topic_test {

/// Fills every byte from `seq` and `salt` and seals it: any mix of two messages fails valid().
template <class Msg>
void seal(Msg& msg, std::uint64_t seq, std::uint64_t salt = 0) {
  msg.seq = seq;
  std::uint64_t state = seq * 0x9e3779b97f4a7c15ULL + salt + 1;
  for (auto& byte : msg.payload) {
    state ^= state << 13;
    state ^= state >> 7;
    state ^= state << 17;
    byte = static_cast<std::uint8_t>(state);
  }
  std::uint64_t sum = 0xcbf29ce484222325ULL ^ seq;
  for (const auto byte : msg.payload) {
    sum = (sum ^ byte) * 0x100000001b3ULL;
  }
  msg.checksum = sum;
}

template <class Msg>
bool valid(const Msg& msg) {
  std::uint64_t sum = 0xcbf29ce484222325ULL ^ msg.seq;
  for (const auto byte : msg.payload) {
    sum = (sum ^ byte) * 0x100000001b3ULL;
  }
  return sum == msg.checksum;
}

template <class Msg>
Msg sealed(std::uint64_t seq, std::uint64_t salt = 0) {
  Msg msg{};
  seal(msg, seq, salt);
  return msg;
}

/// Gives each test its own namespace (inherited by its children) and removes it afterwards.
class PrivateNamespace {
 public:
  PrivateNamespace() {
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    name_ = "t" + std::to_string(::getpid()) + "_" + (test != nullptr ? test->name() : "x");
    for (char& c : name_) {
      if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9'))) {
        c = '_';
      }
    }
    ::setenv("HORUS_NAMESPACE", name_.c_str(), 1);
    horus::remove_namespace(name_);
  }
  PrivateNamespace(const PrivateNamespace&) = delete;
  PrivateNamespace& operator=(const PrivateNamespace&) = delete;
  ~PrivateNamespace() {
    horus::remove_namespace(name_);
    ::unsetenv("HORUS_NAMESPACE");
    // Nothing of the namespace may outlive the test (no /dev/shm growth).
    std::error_code ignored;
    if (std::filesystem::exists(horus::detail::namespace_directory(name_), ignored)) {
      ADD_FAILURE() << "namespace folder " << horus::detail::namespace_directory(name_) << " left";
    }
    for (const horus::NamespaceObjectInfo& object : horus::list_namespace_objects(name_)) {
      ADD_FAILURE() << object.path << " left";
    }
  }
  const std::string& name() const { return name_; }

 private:
  std::string name_;
};

// ---- Child processes -------------------------------------------------------------------------
// A child is this test binary re-executed with HORUS_TEST_ROLE set: a static initializer in the
// test file runs the role's function before GoogleTest starts, and exits with its result.

using Role = std::function<int(const std::vector<std::string>& args)>;

inline std::map<std::string, Role>& roles() {
  static std::map<std::string, Role> table;
  return table;
}

/// Runs the role named by HORUS_TEST_ROLE, if any, and exits with its status.
inline int dispatch_role() {
  const char* role = std::getenv("HORUS_TEST_ROLE");
  if (role == nullptr) {
    return 0;
  }
  std::vector<std::string> args;
  for (int i = 0;; ++i) {
    const char* arg = std::getenv(("HORUS_TEST_ARG" + std::to_string(i)).c_str());
    if (arg == nullptr) {
      break;
    }
    args.emplace_back(arg);
  }
  const auto found = roles().find(role);
  if (found == roles().end()) {
    std::fprintf(stderr, "unknown test role %s\n", role);
    std::exit(90);
  }
  int status = 91;
  try {
    status = found->second(args);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "role %s threw: %s\n", role, e.what());
  }
  std::exit(status);
}

class Child {
 public:
  Child(const std::string& role, const std::vector<std::string>& args) {
    std::vector<std::string> env_text;
    for (char** entry = environ; *entry != nullptr; ++entry) {
      const std::string text = *entry;
      if (text.rfind("HORUS_TEST_", 0) != 0) {
        env_text.push_back(text);
      }
    }
    env_text.push_back("HORUS_TEST_ROLE=" + role);
    for (std::size_t i = 0; i < args.size(); ++i) {
      env_text.push_back("HORUS_TEST_ARG" + std::to_string(i) + "=" + args[i]);
    }
    std::vector<char*> env;
    for (std::string& text : env_text) {
      env.push_back(text.data());
    }
    env.push_back(nullptr);
    std::string exe = "/proc/self/exe";
    char* argv[] = {exe.data(), nullptr};
    if (::posix_spawn(&pid_, "/proc/self/exe", nullptr, nullptr, argv, env.data()) != 0) {
      pid_ = -1;
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  ~Child() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }

  pid_t pid() const { return pid_; }

  /// The exit status, or -1 when the child had to be killed after `timeout`.
  int wait(std::chrono::milliseconds timeout = std::chrono::seconds(60)) {
    if (pid_ <= 0) {
      return -2;
    }
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    int status = 0;
    while (::waitpid(pid_, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, nullptr, 0);
        pid_ = -1;
        return -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }

  /// kill -9, then reap.
  void kill() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
      pid_ = -1;
    }
  }

 private:
  pid_t pid_ = -1;
};

}  // namespace topic_test
