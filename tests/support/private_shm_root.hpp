// A test process's own shared-memory root, outside /dev/shm.
#pragma once

#include <stdlib.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace horus_test {

/// Points HORUS_SHM_DIR at a new folder under /tmp and HORUS_NAMESPACE at `namespace_name`, with
/// the default log level, and removes the folder when it is destroyed. Made as a global, before
/// anything opens a topic or the log ring: gtest_discover_tests runs each test in a process of its
/// own, and child processes (a re-executed test, bin/horus) inherit the same root.
class PrivateShmRoot {
 public:
  explicit PrivateShmRoot(const char* namespace_name) {
    std::string pattern = "/tmp/horus_" + std::string(namespace_name) + "_XXXXXX";
    root_ = ::mkdtemp(pattern.data());
    ::setenv("HORUS_SHM_DIR", root_.c_str(), 1);
    ::setenv("HORUS_NAMESPACE", namespace_name, 1);
    ::unsetenv("HORUS_LOG_LEVEL");
  }
  ~PrivateShmRoot() {
    std::error_code ignored;
    std::filesystem::remove_all(root_, ignored);
  }
  PrivateShmRoot(const PrivateShmRoot&) = delete;
  PrivateShmRoot& operator=(const PrivateShmRoot&) = delete;

  const std::string& root() const { return root_; }

 private:
  std::string root_;
};

}  // namespace horus_test
