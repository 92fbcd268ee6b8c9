// What the C++ action tests share: the Navigate server (navigate_server.hpp) and a namespace of
// its own per test case.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

#include <horus/topic_registry.hpp>

#include "navigate_server.hpp"

namespace action_test {

/// The running test case's own namespace, made current (HORUS_NAMESPACE) and removed at both
/// ends.
class ActionTest : public ::testing::Test {
 protected:
  ActionTest() {
    name_ = "act" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name();
    ::setenv("HORUS_NAMESPACE", name_.c_str(), 1);
    horus::remove_namespace(name_);
  }
  ~ActionTest() override {
    horus::remove_namespace(name_);
    ::unsetenv("HORUS_NAMESPACE");
  }

  std::string name_;
};

}  // namespace action_test
