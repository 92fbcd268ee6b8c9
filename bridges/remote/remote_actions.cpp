#include "remote_actions.hpp"

#include <algorithm>
#include <array>
#include <memory>
#include <mutex>
#include <utility>

#include "horus/bridge/service_relay.hpp"
#include "horus/raw_topic.hpp"
#include "link.hpp"

namespace horus::remote {

namespace {

constexpr std::array<std::string_view, 3> kServiceParts{".send_goal", ".cancel_goal",
                                                        ".get_result"};
constexpr std::array<std::string_view, 3> kTopicParts{".feedback", ".status", ".result"};
/// How many goals of one action a connection (robot) or the laptop remembers for cancelling:
/// a server keeps as many ended goals (runtime/src/action/README.md).
constexpr std::size_t kGoalsKept = 64;
/// How often the robot looks at a watched server's registration (an action client's interval).
constexpr kj::Duration kServerLookInterval = 10 * kj::MILLISECONDS;
/// How often the laptop looks for senders of goals whose process exited (an action server's
/// interval for its own clients).
constexpr kj::Duration kCallerLookInterval = 50 * kj::MILLISECONDS;
/// How long a cancel waits for the robot's server.
constexpr std::chrono::milliseconds kCancelTimeout{1000};

bool ends_with(std::string_view name, std::string_view suffix) {
  return name.size() > suffix.size() && name.substr(name.size() - suffix.size()) == suffix;
}

/// A MessagePack bin 16 at the start of a serialized message's fields: `payload` is the whole
/// message, an array (fixarray, array 16 or array 32) whose first element is the goal id.
std::optional<GoalIdBytes> goal_id_of_serialized(std::span<const std::byte> payload) {
  std::size_t at = 0;
  if (payload.empty()) return std::nullopt;
  const auto first = static_cast<std::uint8_t>(payload[0]);
  if ((first & 0xF0) == 0x90) {
    at = 1;
  } else if (first == 0xDC) {
    at = 3;
  } else if (first == 0xDD) {
    at = 5;
  } else {
    return std::nullopt;
  }
  if (payload.size() < at + 2 + 16 || static_cast<std::uint8_t>(payload[at]) != 0xC4 ||
      static_cast<std::uint8_t>(payload[at + 1]) != 16) {
    return std::nullopt;
  }
  GoalIdBytes id{};
  std::copy_n(payload.begin() + static_cast<std::ptrdiff_t>(at + 2), 16, id.begin());
  return id;
}

ServiceFrameCodec request_codec(const TopicInfo& frames) {
  return ServiceFrameCodec(service_payload_type(type_identity_of(frames), false), false);
}

std::optional<TopicInfo> existing_topic(const std::string& name,
                                        const std::string& namespace_name) {
  for (TopicInfo& info : list_topics(namespace_name)) {
    if (info.name == name && !info.type_name.empty() && info.error.empty()) return info;
  }
  return std::nullopt;
}

/// The process's worker for the robot's cancels: one frames caller per action's cancel_goal,
/// outliving the connections whose goals it cancels.
class GoalCanceller {
 public:
  static GoalCanceller& instance() {
    static GoalCanceller canceller;
    return canceller;
  }

  void cancel(const std::string& namespace_name, const std::string& action,
              const std::deque<GoalIdBytes>& goals) {
    const std::string service = action + ".cancel_goal";
    std::lock_guard lock(mutex_);
    auto& caller = callers_[{namespace_name, action}];
    if (!caller.caller) {
      const std::optional<TopicInfo> request = existing_topic(service + ".request", namespace_name);
      if (!request) return;  // no server ever ran: no goal to cancel
      try {
        caller.frames = *request;
        caller.caller = std::make_unique<bridge::LocalServiceCaller>(
            service, *request, std::nullopt, namespace_name, " on the robot",
            [namespace_name](const TopicInfo& info) {
              return RawTopic::open_recorded(info, namespace_name);
            });
      } catch (const std::exception& e) {
        say("cannot cancel the goals of %s: %s", action.c_str(), e.what());
        callers_.erase({namespace_name, action});
        return;
      }
    }
    for (const GoalIdBytes& goal : goals) {
      caller.caller->call(
          cancel_request_frame(caller.frames, goal, ServiceCaller{1, ++caller.requests, 0}),
          kCancelTimeout, [action](const bridge::LocalServiceCaller::Outcome& outcome) {
            if (!outcome.answer) {
              say("cancelling a goal of %s whose sender's connection ended: %s", action.c_str(),
                  outcome.answer.error().message().c_str());
            }
          });
    }
  }

 private:
  struct Caller {
    TopicInfo frames;
    std::uint64_t requests = 0;
    std::unique_ptr<bridge::LocalServiceCaller> caller;
  };
  std::mutex mutex_;
  std::map<std::pair<std::string, std::string>, Caller> callers_;
};

}  // namespace

std::optional<std::string> action_of_part(std::string_view name, bridge::Access access) {
  const auto* parts = access == bridge::Access::Call   ? &kServiceParts
                      : access == bridge::Access::Read ? &kTopicParts
                                                       : nullptr;
  if (parts == nullptr) return std::nullopt;
  for (const std::string_view part : *parts) {
    if (ends_with(name, part)) return std::string(name.substr(0, name.size() - part.size()));
  }
  return std::nullopt;
}

bool is_action(const std::string& action, const std::vector<TopicInfo>& topics) {
  const auto has = [&topics](const std::string& name) {
    return std::any_of(topics.begin(), topics.end(), [&name](const TopicInfo& info) {
      return info.name == name && !info.type_name.empty();
    });
  };
  return has(action + ".send_goal.request") && has(action + ".cancel_goal.request") &&
         has(action + ".feedback");
}

bool action_allows(const bridge::PeerPolicy& policy, const std::string& peer, bridge::Access access,
                   const std::string& name, const std::string& namespace_name) {
  const std::optional<std::string> action = action_of_part(name, access);
  if (!action || !policy.allows(peer, bridge::Access::Call, *action)) return false;
  return is_action(*action, list_topics(namespace_name));
}

std::optional<GoalIdBytes> goal_id_of_request(std::span<const std::byte> frame,
                                              const TopicInfo& frames) {
  const std::optional<RawRequestFrame> request = request_codec(frames).read_request(frame);
  if (!request) return std::nullopt;
  if (!frames.is_pod) return goal_id_of_serialized(request->payload);
  if (request->payload.size() < 16) return std::nullopt;
  GoalIdBytes id{};
  std::copy_n(request->payload.begin(), 16, id.begin());
  return id;
}

std::vector<std::byte> cancel_request_frame(const TopicInfo& frames, const GoalIdBytes& goal,
                                            const ServiceCaller& caller) {
  // A cancel request is POD: the goal id alone.
  return request_codec(frames).request(caller, goal);
}

kj::Promise<std::string> when_server_gone(kj::Timer& timer, const std::string& service,
                                          const std::string& namespace_name) {
  TopicOptions options;
  options.namespace_name = namespace_name;
  auto registration = std::make_shared<ServiceRegistrationTopic>(service, options);
  const std::optional<ServiceRegistration> serving = registration->latest();
  if (!serving || serving->server_pid == 0) {
    return kj::Promise<std::string>(std::string("it has no server"));
  }
  struct Look {
    static kj::Promise<std::string> again(kj::Timer& timer,
                                          std::shared_ptr<ServiceRegistrationTopic> registration,
                                          ServiceRegistration serving) {
      return timer.afterDelay(kServerLookInterval)
          .then([&timer, registration, serving]() mutable -> kj::Promise<std::string> {
            const std::optional<ServiceRegistration> now = registration->latest();
            if (!now || now->server_pid == 0) return std::string("its server stopped");
            if (now->server_instance != serving.server_instance) {
              return std::string("its server restarted");
            }
            if (service_server_gone(serving.server_pid)) {
              return "its server (pid " + std::to_string(serving.server_pid) + ") exited";
            }
            return again(timer, std::move(registration), serving);
          });
    }
  };
  return Look::again(timer, std::move(registration), *serving);
}

RelayedGoals::~RelayedGoals() {
  for (const auto& [action, goals] : goals_) {
    GoalCanceller::instance().cancel(namespace_name_, action, goals);
  }
}

void RelayedGoals::sent(const std::string& service, std::span<const std::byte> frame) {
  const std::optional<std::string> action = action_of_part(service, bridge::Access::Call);
  if (!action || !ends_with(service, kServiceParts[0])) return;
  auto frames = frames_.find(service);
  if (frames == frames_.end()) {
    std::optional<TopicInfo> request = existing_topic(service + ".request", namespace_name_);
    if (!request) return;
    frames = frames_.emplace(service, std::move(*request)).first;
  }
  const std::optional<GoalIdBytes> goal = goal_id_of_request(frame, frames->second);
  if (!goal) return;
  std::deque<GoalIdBytes>& goals = goals_[*action];
  goals.push_back(*goal);
  if (goals.size() > kGoalsKept) goals.pop_front();
}

CallerGoals::CallerGoals(kj::Timer& timer) : timer_(timer), tasks_(*this) {}

void CallerGoals::sent(const std::string& action, std::uint64_t client_id,
                       std::span<const std::byte> frame, const TopicInfo& frames) {
  const std::optional<GoalIdBytes> goal = goal_id_of_request(frame, frames);
  if (!goal) return;
  sent_.push_back(Sent{action, client_id, *goal});
  if (std::count_if(sent_.begin(), sent_.end(), [&action](const Sent& each) {
        return each.action == action;
      }) > static_cast<std::ptrdiff_t>(kGoalsKept)) {
    sent_.erase(std::find_if(sent_.begin(), sent_.end(),
                             [&action](const Sent& each) { return each.action == action; }));
  }
  if (!watching_) {
    watching_ = true;
    tasks_.add(watch());
  }
}

void CallerGoals::learn_cancel(const std::string& action, const TopicInfo& frames) {
  cancel_frames_.insert_or_assign(action, frames);
}

void CallerGoals::connect(std::optional<wire::Session::Client> session) {
  session_ = std::move(session);
  // Goals sent before the connection ended were the robot's to cancel as it ended.
  if (!session_) sent_.clear();
}

void CallerGoals::taskFailed(kj::Exception&& exception) {
  say("cancelling the goals of an exited process: %s", exception.getDescription().cStr());
}

kj::Promise<void> CallerGoals::watch() {
  return timer_.afterDelay(kCallerLookInterval).then([this]() -> kj::Promise<void> {
    cancel_goals_of_exited();
    if (sent_.empty()) {
      watching_ = false;
      return kj::READY_NOW;
    }
    return watch();
  });
}

void CallerGoals::cancel_goals_of_exited() {
  std::map<std::uint64_t, bool> exited;
  for (auto it = sent_.begin(); it != sent_.end();) {
    auto [known, fresh] = exited.try_emplace(it->client_id, false);
    if (fresh) known->second = service_server_gone(it->client_id >> 32);
    if (!known->second) {
      ++it;
      continue;
    }
    const auto frames = cancel_frames_.find(it->action);
    if (session_ && frames != cancel_frames_.end()) {
      auto request = session_->callRequest();
      request.setService(it->action + std::string(kServiceParts[1]));
      const std::vector<std::byte> frame = cancel_request_frame(
          frames->second, it->goal, ServiceCaller{it->client_id, next_request_++, 0});
      request.setRequest(
          kj::arrayPtr(reinterpret_cast<const capnp::byte*>(frame.data()), frame.size()));
      request.setTimeoutMs(static_cast<std::uint32_t>(kCancelTimeout.count()));
      tasks_.add(request.send().ignoreResult());
    }
    it = sent_.erase(it);
  }
}

}  // namespace horus::remote
