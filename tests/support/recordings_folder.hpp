// A private recordings folder for one GoogleTest test.
#pragma once

#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace horus_test {

/// Points $HORUS_RECORDINGS at a folder of the running test's own, removed afterwards.
class RecordingsFolder {
 public:
  RecordingsFolder()
      : path_(std::filesystem::temp_directory_path() /
              ("horus_recordings_" + std::to_string(::getpid()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
    std::filesystem::remove_all(path_);
    ::setenv("HORUS_RECORDINGS", path_.c_str(), 1);
  }
  ~RecordingsFolder() {
    ::unsetenv("HORUS_RECORDINGS");
    std::filesystem::remove_all(path_);
  }
  RecordingsFolder(const RecordingsFolder&) = delete;
  RecordingsFolder& operator=(const RecordingsFolder&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace horus_test
