// Actions across the link. An action A is three services (A.send_goal, A.cancel_goal,
// A.get_result) and three topics (A.feedback, A.status, A.result) of generated messages
// (runtime/src/action/README.md), so the link carries it as it carries any service and topic. What
// it adds: a `call` rule naming A lets the peer call the three services and read the three topics;
// the laptop learns at once that the robot's server is gone (its clients' goals then end); and a
// goal does not outlive its sender: the goals of a laptop process that exits, and those of a
// connection that ends, are canceled on the robot, whose server cannot see either (every goal
// there comes from the link's own process).
#pragma once

#include <kj/async.h>
#include <kj/timer.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "horus/bridge/peer_policy.hpp"
#include "horus/raw_service.hpp"
#include "horus/topic_registry.hpp"
#include "remote.capnp.h"

namespace horus::remote {

/// The 16 bytes of a goal id (horus::GoalId's wire form).
using GoalIdBytes = std::array<std::byte, 16>;

/// The action `name` is a part of, by its name alone: A of "A.send_goal", "A.cancel_goal" or
/// "A.get_result" when `access` is Call, of "A.feedback", "A.status" or "A.result" when it is
/// Read; none otherwise.
std::optional<std::string> action_of_part(std::string_view name, bridge::Access access);

/// Whether `action` is an action among `topics` (a namespace's listing): its send_goal and
/// cancel_goal services and its feedback topic exist (the rule of `horus action list`).
bool is_action(const std::string& action, const std::vector<TopicInfo>& topics);

/// Whether `policy` lets `peer` `access` `name` as a part of an action of the namespace that a
/// `call` rule of the peer names: its services (Call) and its topics (Read). Lists the
/// namespace's topics only for the name of such a part.
bool action_allows(const bridge::PeerPolicy& policy, const std::string& peer, bridge::Access access,
                   const std::string& name, const std::string& namespace_name);

/// The goal id of a send_goal request frame (`frames`: the request topic's type): the payload's
/// first field, a POD's first 16 bytes or a serialized one's first element (MessagePack bin 16).
std::optional<GoalIdBytes> goal_id_of_request(std::span<const std::byte> frame,
                                              const TopicInfo& frames);

/// A cancel_goal request frame of `caller` asking the server to cancel `goal` (`frames`: the
/// request topic's type).
std::vector<std::byte> cancel_request_frame(const TopicInfo& frames, const GoalIdBytes& goal,
                                            const ServiceCaller& caller);

/// Resolves with why the server of `service` that serves it now is gone: withdrawn, replaced by
/// another instance, or its process exited (looked at every 10 ms, as an action client looks);
/// at once when it has none.
kj::Promise<std::string> when_server_gone(kj::Timer& timer, const std::string& service,
                                          const std::string& namespace_name);

/// The robot's end: the goals one connection sent through the link, canceled on the robot when
/// the connection ends (an ended goal's cancel is answered "already done" and changes nothing).
/// The cancels are made by a worker of the process that outlives the connection.
class RelayedGoals {
 public:
  explicit RelayedGoals(std::string namespace_name) : namespace_name_(std::move(namespace_name)) {}
  RelayedGoals(const RelayedGoals&) = delete;
  RelayedGoals& operator=(const RelayedGoals&) = delete;
  /// Cancels every goal sent and not yet forgotten.
  ~RelayedGoals();

  /// Notes the goal of a request frame of `service` (an action's send_goal, else nothing).
  void sent(const std::string& service, std::span<const std::byte> frame);

 private:
  std::string namespace_name_;
  /// Per send_goal service, the type of its request frames.
  std::map<std::string, TopicInfo> frames_;
  /// Per action, the latest goals sent (the oldest forgotten beyond kGoalsKept).
  std::map<std::string, std::deque<GoalIdBytes>> goals_;
};

/// The laptop's end: the goals local processes sent to the robot, by the process that sent
/// them; when one exits, its goals are canceled on the robot through the session.
class CallerGoals final : public kj::TaskSet::ErrorHandler {
 public:
  CallerGoals(kj::Timer& timer);

  /// Notes the goal of a request frame of `action`'s send_goal from client `client_id`.
  void sent(const std::string& action, std::uint64_t client_id, std::span<const std::byte> frame,
            const TopicInfo& frames);
  /// The robot's cancel_goal request frames of `action`, from its listing.
  void learn_cancel(const std::string& action, const TopicInfo& frames);
  /// The session the cancels go through from now on; none while the connection is down (a
  /// cancel is then the robot's to make as the connection ended).
  void connect(std::optional<wire::Session::Client> session);

  void taskFailed(kj::Exception&& exception) override;

 private:
  struct Sent {
    std::string action;
    std::uint64_t client_id;
    GoalIdBytes goal;
  };
  kj::Promise<void> watch();
  void cancel_goals_of_exited();

  kj::Timer& timer_;
  std::optional<wire::Session::Client> session_;
  std::map<std::string, TopicInfo> cancel_frames_;
  /// The latest goals sent, oldest first (the oldest forgotten beyond kGoalsKept per action).
  std::deque<Sent> sent_;
  std::uint64_t next_request_ = 1;
  bool watching_ = false;
  kj::TaskSet tasks_;
};

}  // namespace horus::remote
