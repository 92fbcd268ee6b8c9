// Parameters across the link (`PEER param NODE.PARAMETER` rules): what a peer may see of the
// robot's parameter stores, and the laptop's mirrors of them, local stores whose writes go to
// the robot's owners.
#pragma once

#include <kj/async.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "horus/params.hpp"
#include "horus/scheduler.hpp"
#include "remote.capnp.h"

namespace horus::remote {

/// The robot's parameters as one peer may see them: the running nodes with a parameter its rules
/// name ("NODE.PARAMETER"), each with only those parameters. Read from the stores, lock-free.
class ParamView {
 public:
  ParamView(std::function<bool(const std::string&)> allows, std::string namespace_name);

  /// Looks at the stores again (nodes that started or ended, values that changed); a digest of
  /// what the peer sees, which changes whenever that does.
  std::uint64_t refresh();
  /// What refresh() saw, for the wire.
  void fill(capnp::List<wire::ParamNode>::Builder nodes) const;
  std::size_t node_count() const;

 private:
  struct Store {
    std::unique_ptr<ParamStoreReader> reader;
    /// The declarations the peer may see (an encoded type description), and their names.
    std::string description;
    std::vector<std::string> names;
    /// Which opening of the node's store this is (a restarted node may have a new one).
    std::uint64_t opening = 0;
    std::chrono::steady_clock::time_point opened;
    /// Whether refresh() found it shown to the peer (fill() keeps to what refresh() saw).
    bool shown = false;
  };

  std::function<bool(const std::string&)> allows_;
  std::string namespace_name_;
  std::map<std::string, Store> stores_;
  std::uint64_t openings_ = 0;
};

/// The laptop's mirrors of the robot's parameters, for one connection: per robot node, a local
/// node of the same name run by a scheduler of this process, whose store holds the robot's
/// declarations (the peer's share of them) and follows the robot's values; a write of it (from
/// `horus param set` here) is offered to the robot's owner over the link and stored here only
/// when the robot took it. Ended with the connection: the stores stay, shown as not running.
class ParamMirrors final : private kj::TaskSet::ErrorHandler {
 public:
  /// `session`: the connection's; the writes go through it, from the event loop of the thread
  /// that makes this. `patterns`: which of what the robot shows ("NODE.PARAMETER" globs).
  ParamMirrors(wire::Session::Client session, std::vector<std::string> patterns,
               std::string namespace_name);
  ~ParamMirrors();
  ParamMirrors(const ParamMirrors&) = delete;
  ParamMirrors& operator=(const ParamMirrors&) = delete;

  /// Follows the robot's parameters until the connection ends (asking again whenever the robot
  /// answered, the answer waiting for a change).
  kj::Promise<void> run();

 private:
  struct Mirror;
  struct Forward;
  /// Asks the robot for its parameters, again as soon as it answered.
  kj::Promise<void> poll();
  /// Makes, keeps or ends the mirrors as the robot's answer says, and queues its values.
  void follow(capnp::List<wire::ParamNode>::Reader nodes);
  /// On a mirror's thread: the robot's verdict on a write made here.
  ParamSetResult forward(const std::string& node, const std::string& name,
                         const std::string& value);
  /// The event loop's side of forward(): sends what the mirrors' threads queued.
  kj::Promise<void> send_forwards();
  /// The thread that writes the robot's values into the mirrors (a write waits for the mirror's
  /// thread, which the event loop must never do).
  void sync_loop();

  void taskFailed(kj::Exception&& exception) override;

  wire::Session::Client session_;
  std::vector<std::string> patterns_;
  std::string namespace_name_;
  /// The source of the writes that bring the robot's values here: only those a mirror takes
  /// without asking the robot.
  std::string sync_source_;
  std::map<std::string, std::unique_ptr<Mirror>> mirrors_;
  /// Nodes whose declarations (as the robot sent them) cannot be mirrored here.
  std::map<std::string, std::string> unmirrorable_;
  std::uint64_t generation_ = 0;

  std::mutex mutex_;
  std::condition_variable wake_;
  bool closing_ = false;
  /// Values of the robot for sync_loop(): node, parameter, value.
  std::deque<std::tuple<std::string, std::string, std::string>> updates_;
  /// Writes made here for the event loop to send, and every write still waiting for its answer.
  std::deque<std::shared_ptr<Forward>> forwards_;
  std::vector<std::shared_ptr<Forward>> unanswered_;
  kj::Own<kj::CrossThreadPromiseFulfiller<void>> forwards_waiting_;
  std::thread sync_thread_;
  /// The writes on their way to the robot.
  kj::TaskSet sending_{*this};
};

}  // namespace horus::remote
