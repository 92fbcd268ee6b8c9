// The child process behind SchedulerConfig::network(): `horus bridge` with the Network's options,
// in the scheduler's namespace, from the scheduler's construction until its run ends
// (runtime/src/network/README.md).
#pragma once

#include <signal.h>
#include <sys/types.h>

#include <chrono>
#include <condition_variable>
#include <functional>
#include <future>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "horus/network.hpp"

namespace horus::detail {

/// Throws horus::Error naming the first field of `network` that `horus bridge` would refuse.
void validate_network(const Network& network);

/// The command line after the program: `bridge --namespace=NS --domain=N ... --export=PATTERN`.
std::vector<std::string> bridge_arguments(const Network& network,
                                          const std::string& namespace_name);

/// The `horus` command that runs the bridge: $HORUS_BRIDGE_PROGRAM, else the installed one
/// (<prefix>/bin/horus), else `horus` on PATH, else the build tree's. Throws horus::Error naming
/// every place it looked.
std::string bridge_program();

class BridgeProcess {
 public:
  /// Called on the watching thread when the bridge ends on its own with a failure status or by a
  /// signal it was not sent by end(); says which.
  using OnFailure = std::function<void(const std::string& reason)>;

  /// Validates `network`, finds the program and starts it. Throws horus::Error when the network
  /// is invalid or the program cannot be found or started.
  BridgeProcess(const Network& network, const std::string& namespace_name, OnFailure on_failure);
  /// end()
  ~BridgeProcess();
  BridgeProcess(const BridgeProcess&) = delete;
  BridgeProcess& operator=(const BridgeProcess&) = delete;

  /// SIGTERM, then waits until the bridge has ended (SIGKILL after kTermGrace). Idempotent.
  void end() noexcept;

  /// How long the bridge may take to leave DDS after SIGTERM (it needs half a second).
  static constexpr std::chrono::seconds kTermGrace{5};

 private:
  /// The watching thread: forks the child (which dies with this thread: PR_SET_PDEATHSIG), says
  /// through `started` whether its exec succeeded (0) or the errno, then waits for its end.
  void watch(std::vector<std::string> argv, std::promise<int> started);

  OnFailure on_failure_;
  std::mutex mutex_;
  std::condition_variable reaped_changed_;
  pid_t pid_ = 0;
  bool ending_ = false;  // end() sent SIGTERM: the end that follows is no failure
  bool exited_ = false;  // the child has ended (not yet reaped: pid_ still names it until reaped_)
  bool reaped_ = false;
  std::thread watcher_;
};

}  // namespace horus::detail
