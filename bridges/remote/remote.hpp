// horus-remote's commands and the event loop they run on.
#pragma once

#include <kj/async-io.h>
#include <kj/async-unix.h>

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "horus/bridge/peer_policy.hpp"

namespace horus::remote {

/// The name the policy knows every peer of an --insecure server by.
inline constexpr const char* kInsecurePeer = "insecure";

/// The longest a peer may have the robot wait for one call's answer (a longer ask is cut to it).
inline constexpr std::uint32_t kLongestCallMs = 60000;

struct ServeOptions {
  std::string listen;
  std::string certs;
  std::string name;
  std::string namespace_name;
  bridge::PeerPolicy policy;
  bool insecure = false;
};

struct ConnectOptions {
  std::string address;
  std::string certs;
  std::string name;
  /// The name in the robot's certificate (default: the host of `address`).
  std::string server_name;
  std::string namespace_name;
  std::vector<std::string> imports;
  std::vector<std::string> exports;
  /// The robot's parameters ("NODE.PARAMETER" globs) mirrored here while connected.
  std::vector<std::string> params;
  /// The robot's coordinate frames set here (child-frame globs), and the frames of local
  /// processes the robot sets in its tree, while connected.
  std::vector<std::string> import_frames;
  std::vector<std::string> export_frames;
  /// Messages each stream may fall behind before the oldest are dropped.
  unsigned queue = 0;
  /// How long the robot waits for its server to answer one call a local client makes (the
  /// request frame does not carry the client's own timeout).
  std::chrono::milliseconds call_timeout{10000};
  bool insecure = false;
};

/// Kj's event loop, with SIGINT and SIGTERM turned into events (blocked in every thread).
struct EventLoop {
  EventLoop();
  kj::AsyncIoContext io;
  /// Resolves at SIGINT or SIGTERM, or when `work` ends; meanwhile the status file of this
  /// process (`role`: serve or connect) is written every second, and removed at the end.
  void run_until_stopped(kj::Promise<void> work, const std::string& namespace_name,
                         const char* role);
};

int serve(const ServeOptions& options);
int connect(const ConnectOptions& options);

}  // namespace horus::remote
