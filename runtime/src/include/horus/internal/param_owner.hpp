// The owner's side of a node's parameters (runtime/src/params/): the store the scheduler opens
// when it starts a node that declared parameters, and the write service it answers: itself while
// the node's thread sleeps, through the node's thread while that thread holds the node.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>

#include "horus/node.hpp"

namespace horus::detail {

/// A scheduler's parameter file, checked: per node, per parameter, MessagePack VALUE bytes.
using ParamFileValues = std::map<std::string, std::map<std::string, std::string>>;

/// Reads the file and checks it against the nodes' declarations (by node name); throws
/// ParamError with every problem as FILE:LINE: reason (a node of the file with no parameters
/// here is one).
ParamFileValues read_scheduler_param_file(
    const std::filesystem::path& path,
    const std::map<std::string, const std::vector<ParamDeclaration>*>& declarations);

class ParamOwner {
 public:
  /// Opens the store of `node` (named `name`) in the current namespace, or takes over a dead
  /// owner's, holding its flock; writes the declarations and defaults, then `file_values` (the
  /// parameter file's, already checked), then the values persisted for this start, then
  /// `replay_values` (what a replayed recording's node started with) where they fit the
  /// declarations. Throws ParamError: another live owner (naming its pid and program), a bad
  /// persisted value.
  ParamOwner(Node& node, std::string name, const std::map<std::string, std::string>* file_values,
             const std::map<std::string, std::string>* replay_values = nullptr);
  /// Stops serving (waiting writes are refused), marks the store as not running, unlocks it.
  ~ParamOwner();
  ParamOwner(const ParamOwner&) = delete;
  ParamOwner& operator=(const ParamOwner&) = delete;

  /// Answers writes on a thread of its own from now on. While the node's thread has lent the
  /// node (idle(), as it sleeps) that thread calls on_param_change() itself; otherwise it queues
  /// the change, and `wake` asks the node's thread to call deliver() soon.
  void serve(std::function<void()> wake);
  /// Whether changes wait for deliver(): the one relaxed load a tick pays.
  bool pending() const noexcept { return pending_.load(std::memory_order_relaxed); }
  /// On the thread that runs the node, holding it, between two ticks: offers each waiting change
  /// to on_param_change(), stores the accepted ones and answers their writers.
  void deliver() noexcept;
  /// The thread that runs the node is about to sleep: until hold(), the service thread may call
  /// on_param_change() itself. Delivers what is already waiting first (a seq_cst store and then
  /// a load of the pending flag, against the service's store of the flag and load of the state,
  /// so a change queued meanwhile is seen by one side or the other).
  void idle() noexcept;
  /// The thread that runs the node takes it back (one CAS), waiting for an on_param_change()
  /// the service thread is in; its writes happen before what the node does next. A node never
  /// lent is held already.
  void hold() noexcept;
  /// While lent (between idle() and hold()): delivers changes that were queued as the node's
  /// thread lent it.
  void deliver_while_idle() noexcept;
  /// On the node's thread, between two ticks: the path a write takes, for a change that does
  /// not come through the service (a replay's): checked against the declaration (read-only
  /// refused), offered to on_param_change() with `source`, stored when accepted.
  ParamSetResult apply(std::string_view name, const std::string& value,
                       const std::string& source) noexcept;

  /// What is told of each change the node accepted, once stored, by the thread that offered it
  /// (see idle()): its declaration, value (MessagePack VALUE bytes), new version and source.
  using AcceptedChange = std::function<void(const ParamDeclaration&, const std::string& value,
                                            std::uint64_t version, const std::string& source)>;
  /// Tells `listener` of every change accepted from now on (a session recording). Set before
  /// the node's thread first lends the node (the scheduler sets it before the node first runs).
  void on_accepted(AcceptedChange listener);

 private:
  struct State;
  /// Who may call the node: its thread (kHeldByNode), nobody (kIdle: the thread sleeps), or the
  /// service thread (kHeldByService, with kNodeWaits when the node's thread waits to hold it).
  static constexpr std::uint32_t kIdle = 0;
  static constexpr std::uint32_t kHeldByNode = 1;
  static constexpr std::uint32_t kHeldByService = 2;
  static constexpr std::uint32_t kNodeWaits = 4;
  /// The service thread's side: takes an idle node (kIdle -> kHeldByService), or false.
  bool take_idle_node() noexcept;
  /// Gives the node back to idle, waking its thread if it waits.
  void give_back() noexcept;

  std::unique_ptr<State> state_;
  std::atomic<bool> pending_{false};
  std::atomic<std::uint32_t> holder_{kHeldByNode};
};

}  // namespace horus::detail
