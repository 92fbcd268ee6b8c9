// horus::ActionServerBuilder<A> and ActionServer<A>: serving an action's goals, one executing at
// a time, with feedback, cancels and results. The wire: runtime/src/action/README.md.
//
//   auto server = horus::ActionServerBuilder<Navigate>()
//                     .on_execute([](horus::ServerGoal<Navigate>& goal) {
//                       while (!goal.is_cancel_requested()) { ...; goal.publish_feedback(fb); }
//                       goal.cancel();
//                     })
//                     .build();
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <system_error>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "horus/action_type.hpp"
#include "horus/codec.hpp"
#include "horus/detail/action_wire.hpp"
#include "horus/error.hpp"
#include "horus/raw_service.hpp"
#include "horus/topic.hpp"

namespace horus {

/// on_goal's answer: accept the goal, or refuse it with a reason the client reads.
struct GoalDecision {
  static GoalDecision accept() { return {}; }
  static GoalDecision reject(std::string reason) { return {false, std::move(reason)}; }

  bool accepted = true;
  std::string reason;
};

/// Counters of a running server: nothing fails silently.
struct ActionServerStats {
  /// Goals received (accepted or rejected).
  std::uint64_t goals = 0;
  std::uint64_t accepted = 0;
  std::uint64_t rejected = 0;
  std::uint64_t succeeded = 0;
  std::uint64_t aborted = 0;
  std::uint64_t canceled = 0;
  std::uint64_t feedback_sent = 0;
  /// Feedback the topic refused (too large for a slot).
  std::uint64_t feedback_refused = 0;
};

template <Action A>
class ActionServer;
template <Action A>
class ActionServerBuilder;
template <Action A>
class ServerGoal;

namespace detail {

/// A goal the server knows, live or ended. Its fields are under the server's mutex, except
/// `cancel_requested`, which the executing code polls.
template <Action A>
struct ServerGoalRecord {
  GoalId id;
  typename A::Goal goal;
  /// The send_goal caller's client id: a relay's for goals that came over a link, so a goal
  /// is judged by the process that holds its call.
  std::uint64_t caller = 0;
  GoalState state = GoalState::Accepted;
  std::string cancel_reason;
  std::atomic<bool> cancel_requested{false};
  /// Set when the goal ends: what get_result answers from then on.
  std::optional<typename A::ResultMessage> outcome;
};

/// The server's goal table and its three services' threads, shared with the ServerGoals it
/// hands out (which may outlive the ActionServer in tick mode: they then find it stopped).
template <Action A>
class ActionServerCore : public std::enable_shared_from_this<ActionServerCore<A>> {
 public:
  using Goal = typename A::Goal;
  using Result = typename A::Result;
  using Record = ServerGoalRecord<A>;
  using RecordPtr = std::shared_ptr<Record>;

  struct Config {
    std::function<GoalDecision(const Goal&)> on_goal;
    std::function<bool(const ServerGoal<A>&)> on_cancel;
    std::function<void(ServerGoal<A>&)> on_execute;
    ActionPolicy policy = ActionPolicy::Reject;
    std::size_t queue_capacity = 8;
    TopicOptions options;
  };

  explicit ActionServerCore(Config config)
      : config_(std::move(config)),
        feedback_(A::feedback_topic(), config_.options),
        status_(A::status_topic(), config_.options),
        results_(A::result_topic(), config_.options),
        get_result_server_(raw_service_type<typename A::GetResult>(), config_.options),
        cancel_server_(raw_service_type<typename A::CancelGoal>(), config_.options),
        send_goal_server_(raw_service_type<typename A::SendGoal>(), config_.options) {}

  void start() {
    try {
      if (config_.on_execute) {
        executor_ = std::thread([this] { execute_goals(); });
      }
      send_goal_thread_ = std::thread([this] { serve_send_goal(); });
      cancel_thread_ = std::thread([this] { serve_cancel(); });
      get_result_thread_ = std::thread([this] { serve_get_result(); });
    } catch (const std::system_error& e) {
      stop();
      throw Error("action " + std::string(A::name()) + ": cannot start its threads: " + e.what());
    }
  }

  /// Aborts the live goals, ends the threads (waiting for on_execute to return: it is asked
  /// to cancel) and withdraws the registrations. Idempotent.
  void stop() noexcept {
    {
      std::lock_guard lock(mutex_);
      if (stopped_) return;
      stopped_ = true;
      std::vector<RecordPtr> live;
      for (const auto& [id, record] : live_) live.push_back(record);
      for (const RecordPtr& record : live) {
        record->cancel_reason = std::string(kServerStoppedReason);
        record->cancel_requested.store(true, std::memory_order_release);
        finish_locked(*record, GoalState::Aborted, kServerStoppedReason, Result{});
      }
    }
    changed_.notify_all();
    send_goal_server_.stop();
    cancel_server_.stop();
    get_result_server_.stop();
    for (std::thread* thread :
         {&send_goal_thread_, &cancel_thread_, &get_result_thread_, &executor_}) {
      if (thread->joinable()) thread->join();
    }
    send_goal_server_.withdraw();
    cancel_server_.withdraw();
    get_result_server_.withdraw();
  }

  bool is_running() const noexcept {
    std::lock_guard lock(mutex_);
    return !stopped_;
  }

  ActionServerStats stats() const noexcept {
    std::lock_guard lock(mutex_);
    ActionServerStats stats = stats_;
    stats.feedback_sent = feedback_sent_.load(std::memory_order_relaxed);
    stats.feedback_refused = feedback_refused_.load(std::memory_order_relaxed);
    return stats;
  }

  /// Tick mode: the next waiting goal, now Executing, when none executes.
  std::optional<ServerGoal<A>> next_goal();

  GoalState state_of(const Record& record) const {
    std::lock_guard lock(mutex_);
    return record.state;
  }

  std::string cancel_reason_of(const Record& record) const {
    std::lock_guard lock(mutex_);
    return record.cancel_reason;
  }

  bool publish_feedback(const Record& record, const typename A::Feedback& feedback) {
    if (is_terminal(state_of(record))) return false;
    typename A::FeedbackMessage message{};
    set_goal_id(message, record.id);
    message.feedback = feedback;
    std::lock_guard lock(feedback_mutex_);
    if (!feedback_.send(message)) {
      feedback_refused_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    feedback_sent_.fetch_add(1, std::memory_order_relaxed);
    return true;
  }

  /// Ends a goal unless it has ended already (an outcome after stop() or a second one is
  /// ignored: the first counts).
  void finish(Record& record, GoalState state, std::string_view reason, Result result) {
    {
      std::lock_guard lock(mutex_);
      finish_locked(record, state, reason, std::move(result));
    }
    changed_.notify_all();
  }

 private:
  void serve_send_goal() noexcept {
    auto next_client_check = std::chrono::steady_clock::now() + kClientCheckInterval;
    while (!send_goal_server_.stopped()) {
      std::optional<RawServiceServer::Request> request = send_goal_server_.next(kServeSlice);
      if (request) {
        try {
          receive_goal(*request);
        } catch (...) {
          // Out of memory for the goal: the caller learns it failed rather than waiting.
          static_cast<void>(send_goal_server_.fail(
              request->caller,
              ServiceError::service_failed("the action server ran out of memory")));
        }
      }
      if (std::chrono::steady_clock::now() >= next_client_check) {
        cancel_goals_of_exited_clients();
        next_client_check = std::chrono::steady_clock::now() + kClientCheckInterval;
      }
    }
  }

  void receive_goal(RawServiceServer::Request& request) {
    using Request = typename A::SendGoal::Request;
    std::optional<Request> decoded = try_decode<Request>(std::span(
        reinterpret_cast<const std::uint8_t*>(request.payload.data()), request.payload.size()));
    if (!decoded) return;  // not a request of this type: it passes by, as on a typed topic
    const GoalId id = goal_id_of(*decoded);
    std::optional<std::string> refusal = policy_refusal(id);
    if (!refusal) {
      GoalDecision decision = decide(decoded->goal);
      if (!decision.accepted) refusal = std::move(decision.reason);
    }
    typename A::SendGoal::Response response{};
    response.stamp_ns = action_stamp_ns();
    {
      std::lock_guard lock(mutex_);
      ++stats_.goals;
      if (!refusal && stopped_) refusal = std::string(kServerStoppedReason);
      if (refusal) {
        ++stats_.rejected;
      } else {
        admit_locked(id, std::move(decoded->goal), request.caller.client_id);
      }
    }
    // The goal is in the executor's queue before the answer leaves (a cancel or get_result
    // right after the answer finds it); the executor is woken once the answer is out, so the
    // answer does not wait for the executor's start on a busy core. Its first feedback still
    // races the answer, and the client keeps it.
    response.accepted = !refusal;
    if (refusal) set_text(response.reason, *refusal);
    const std::vector<std::uint8_t> bytes = encode(response);
    send_goal_server_.answer(request.caller, std::as_bytes(std::span(bytes)));
    changed_.notify_all();
    // Last: the executor may have published Executing already; clients let states only move
    // forward.
    std::lock_guard lock(mutex_);
    publish_status_locked(id, refusal ? GoalState::Rejected : GoalState::Accepted,
                          refusal ? std::string_view(*refusal) : std::string_view());
  }

  /// Why the policy refuses goal `id` now, if it does.
  std::optional<std::string> policy_refusal(const GoalId& id) {
    std::lock_guard lock(mutex_);
    if (live_.contains(id)) return "goal " + id.to_string() + " already exists";
    switch (config_.policy) {
      case ActionPolicy::Reject:
        if (executing_) return busy_reason(executing_->id);
        if (!waiting_.empty()) return busy_reason(waiting_.front()->id);
        break;
      case ActionPolicy::Queue:
        if (waiting_.size() >= config_.queue_capacity) return queue_full_reason(waiting_.size());
        break;
      case ActionPolicy::Preempt:
        break;
    }
    return std::nullopt;
  }

  GoalDecision decide(const Goal& goal) noexcept {
    if (!config_.on_goal) return GoalDecision::accept();
    try {
      return config_.on_goal(goal);
    } catch (const std::exception& e) {
      return GoalDecision::reject(std::string("on_goal threw: ") + e.what());
    } catch (...) {
      return GoalDecision::reject("on_goal threw an exception that is not a std::exception");
    }
  }

  void admit_locked(const GoalId& id, Goal goal, std::uint64_t caller) {
    auto record = std::make_shared<Record>();
    record->id = id;
    record->goal = std::move(goal);
    record->caller = caller;
    if (config_.policy == ActionPolicy::Preempt) {
      const std::string reason = preempted_reason(id);
      while (!waiting_.empty()) {
        RecordPtr waiting = waiting_.front();
        record_cancel_locked(*waiting, reason);
      }
      if (executing_) record_cancel_locked(*executing_, reason);
    }
    live_.emplace(id, record);
    waiting_.push_back(record);
    ++stats_.accepted;
  }

  /// Cancels a waiting goal at once, asks an executing one to cancel.
  void record_cancel_locked(Record& record, std::string_view reason) {
    if (record.state == GoalState::Accepted) {
      finish_locked(record, GoalState::Canceled, reason, Result{});
    } else if (record.state == GoalState::Executing) {
      record.state = GoalState::Canceling;
      record.cancel_reason = std::string(reason);
      record.cancel_requested.store(true, std::memory_order_release);
      publish_status_locked(record.id, GoalState::Canceling, reason);
    }
  }

  void finish_locked(Record& record, GoalState state, std::string_view reason, Result result) {
    if (is_terminal(record.state)) return;
    record.state = state;
    typename A::ResultMessage message{};
    set_goal_id(message, record.id);
    message.state = static_cast<std::uint8_t>(state);
    message.stamp_ns = action_stamp_ns();
    set_text(message.reason, reason);
    message.result = std::move(result);
    {
      std::lock_guard publish(publish_mutex_);
      results_.send(message);
    }
    publish_status_locked(record.id, state, reason);
    record.outcome = std::move(message);
    switch (state) {
      case GoalState::Succeeded:
        ++stats_.succeeded;
        break;
      case GoalState::Canceled:
        ++stats_.canceled;
        break;
      default:
        ++stats_.aborted;
        break;
    }
    for (auto it = waiting_.begin(); it != waiting_.end(); ++it) {
      if (it->get() == &record) {
        waiting_.erase(it);
        break;
      }
    }
    if (executing_.get() == &record) executing_.reset();
    const auto found = live_.find(record.id);
    if (found != live_.end()) {
      ended_.push_back(found->second);
      live_.erase(found);
      if (ended_.size() > kEndedGoalsKept) ended_.pop_front();
    }
  }

  void publish_status_locked(const GoalId& id, GoalState state, std::string_view reason) {
    typename A::Status status{};
    set_goal_id(status, id);
    status.state = static_cast<std::uint8_t>(state);
    status.stamp_ns = action_stamp_ns();
    set_text(status.reason, reason);
    std::lock_guard publish(publish_mutex_);
    status_.send(status);
  }

  /// The next waiting goal made the executing one; none while one executes.
  RecordPtr start_next_locked() {
    if (executing_ || waiting_.empty() || stopped_) return nullptr;
    RecordPtr record = waiting_.front();
    waiting_.pop_front();
    executing_ = record;
    record->state = GoalState::Executing;
    publish_status_locked(record->id, GoalState::Executing, {});
    return record;
  }

  void execute_goals() noexcept;

  void cancel_goals_of_exited_clients() noexcept {
    std::vector<std::uint64_t> pids;
    {
      std::lock_guard lock(mutex_);
      for (const auto& [id, record] : live_) {
        const std::uint64_t pid = record->caller >> 32;
        if (std::find(pids.begin(), pids.end(), pid) == pids.end()) pids.push_back(pid);
      }
    }
    for (const std::uint64_t pid : pids) {
      if (!service_server_gone(pid)) continue;
      std::vector<RecordPtr> orphans;
      {
        std::lock_guard lock(mutex_);
        for (const auto& [id, record] : live_) {
          if (record->caller >> 32 == pid && record->state != GoalState::Canceling) {
            orphans.push_back(record);
          }
        }
        for (const RecordPtr& record : orphans) {
          record_cancel_locked(*record, client_exited_reason(pid));
        }
      }
      changed_.notify_all();
    }
  }

  void serve_cancel() noexcept {
    using Request = typename A::CancelGoal::Request;
    while (!cancel_server_.stopped()) {
      std::optional<RawServiceServer::Request> request = cancel_server_.next(kServeSlice);
      if (!request) continue;
      std::optional<Request> decoded = try_decode<Request>(std::span(
          reinterpret_cast<const std::uint8_t*>(request->payload.data()), request->payload.size()));
      if (!decoded) continue;
      try {
        const typename A::CancelGoal::Response response = cancel(goal_id_of(*decoded));
        const std::vector<std::uint8_t> bytes = encode(response);
        cancel_server_.answer(request->caller, std::as_bytes(std::span(bytes)));
      } catch (...) {
        static_cast<void>(cancel_server_.fail(
            request->caller, ServiceError::service_failed("the action server ran out of memory")));
      }
    }
  }

  typename A::CancelGoal::Response cancel(const GoalId& id);

  void serve_get_result() noexcept {
    using Request = typename A::GetResult::Request;
    while (!get_result_server_.stopped()) {
      std::optional<RawServiceServer::Request> request = get_result_server_.next(kServeSlice);
      if (!request) continue;
      std::optional<Request> decoded = try_decode<Request>(std::span(
          reinterpret_cast<const std::uint8_t*>(request->payload.data()), request->payload.size()));
      if (!decoded) continue;
      try {
        const typename A::ResultMessage answer = result_of(goal_id_of(*decoded));
        const std::vector<std::uint8_t> bytes = encode(answer);
        get_result_server_.answer(request->caller, std::as_bytes(std::span(bytes)));
      } catch (...) {
        static_cast<void>(get_result_server_.fail(
            request->caller, ServiceError::service_failed("the action server ran out of memory")));
      }
    }
  }

  /// The goal's outcome once ended, else its state now (Unknown for a goal never seen or
  /// ended too long ago).
  typename A::ResultMessage result_of(const GoalId& id) {
    std::lock_guard lock(mutex_);
    for (const RecordPtr& record : ended_) {
      if (record->id == id) return *record->outcome;
    }
    typename A::ResultMessage message{};
    set_goal_id(message, id);
    message.stamp_ns = action_stamp_ns();
    const auto found = live_.find(id);
    if (found == live_.end()) {
      message.state = static_cast<std::uint8_t>(GoalState::Unknown);
      set_text(message.reason, kUnknownGoalReason);
    } else {
      message.state = static_cast<std::uint8_t>(found->second->state);
    }
    return message;
  }

  Config config_;
  Topic<typename A::FeedbackMessage> feedback_;  // under feedback_mutex_
  Topic<typename A::Status> status_;             // under publish_mutex_
  Topic<typename A::ResultMessage> results_;     // under publish_mutex_
  RawServiceServer get_result_server_;
  RawServiceServer cancel_server_;
  // Registered last: clients judge the server by this registration.
  RawServiceServer send_goal_server_;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool stopped_ = false;
  std::unordered_map<GoalId, RecordPtr> live_;
  std::deque<RecordPtr> waiting_;
  RecordPtr executing_;
  std::deque<RecordPtr> ended_;
  ActionServerStats stats_;

  std::mutex feedback_mutex_;
  std::mutex publish_mutex_;
  std::atomic<std::uint64_t> feedback_sent_{0};
  std::atomic<std::uint64_t> feedback_refused_{0};

  std::thread send_goal_thread_;
  std::thread cancel_thread_;
  std::thread get_result_thread_;
  std::thread executor_;
};

}  // namespace detail

/// A goal being executed: its goal message, feedback, the cancel request and its outcome.
/// Move-only; dropped without an outcome, the goal is Aborted ("the goal was dropped without
/// an outcome"). After the outcome (or once the server stopped), further outcomes and feedback
/// are ignored.
template <Action A>
class ServerGoal {
 public:
  ServerGoal(ServerGoal&& other) noexcept
      : core_(std::move(other.core_)), record_(std::move(other.record_)), owning_(other.owning_) {}
  ServerGoal& operator=(ServerGoal&& other) noexcept {
    if (this != &other) {
      drop();
      core_ = std::move(other.core_);
      record_ = std::move(other.record_);
      owning_ = other.owning_;
    }
    return *this;
  }
  ServerGoal(const ServerGoal&) = delete;
  ServerGoal& operator=(const ServerGoal&) = delete;
  ~ServerGoal() { drop(); }

  GoalId id() const { return record_->id; }
  const typename A::Goal& goal() const { return record_->goal; }
  GoalState state() const { return core_->state_of(*record_); }
  bool is_done() const { return is_terminal(state()); }

  /// Publishes feedback on `A.feedback`; false once the goal ended or when the topic refused it.
  bool publish_feedback(const typename A::Feedback& feedback) {
    return core_->publish_feedback(*record_, feedback);
  }

  /// Whether a client, a preempting goal, a client's exit or stop() asked this goal to cancel.
  bool is_cancel_requested() const noexcept {
    return record_->cancel_requested.load(std::memory_order_acquire);
  }
  /// Why: "canceled by a client", "preempted by goal <id>", "the client (pid N) exited", ...
  std::string cancel_reason() const { return core_->cancel_reason_of(*record_); }

  void succeed(typename A::Result result) {
    core_->finish(*record_, GoalState::Succeeded, {}, std::move(result));
  }
  void abort(std::string reason, typename A::Result result = {}) {
    core_->finish(*record_, GoalState::Aborted, reason, std::move(result));
  }
  /// Ends the goal Canceled, with the cancel's reason.
  void cancel(typename A::Result result = {}) {
    core_->finish(*record_, GoalState::Canceled, cancel_reason(), std::move(result));
  }

 private:
  friend class detail::ActionServerCore<A>;

  ServerGoal(std::shared_ptr<detail::ActionServerCore<A>> core,
             std::shared_ptr<detail::ServerGoalRecord<A>> record, bool owning)
      : core_(std::move(core)), record_(std::move(record)), owning_(owning) {}

  void drop() noexcept {
    if (owning_ && core_ && record_) {
      try {
        core_->finish(*record_, GoalState::Aborted, detail::kGoalDroppedReason, {});
      } catch (...) {
        // Out of memory for the result message: the client's get_result still finds the goal.
      }
    }
    core_.reset();
    record_.reset();
  }

  std::shared_ptr<detail::ActionServerCore<A>> core_;
  std::shared_ptr<detail::ServerGoalRecord<A>> record_;
  bool owning_ = true;
};

namespace detail {

template <Action A>
std::optional<ServerGoal<A>> ActionServerCore<A>::next_goal() {
  RecordPtr record;
  {
    std::lock_guard lock(mutex_);
    record = start_next_locked();
  }
  if (!record) return std::nullopt;
  return ServerGoal<A>(this->shared_from_this(), std::move(record), true);
}

template <Action A>
void ActionServerCore<A>::execute_goals() noexcept {
  for (;;) {
    RecordPtr record;
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [this] { return stopped_ || (!executing_ && !waiting_.empty()); });
      if (stopped_) return;
      record = start_next_locked();
    }
    if (!record) continue;
    ServerGoal<A> goal(this->shared_from_this(), record, false);
    try {
      config_.on_execute(goal);
      finish(*record, GoalState::Aborted, kExecuteReturnedReason, Result{});
    } catch (const std::exception& e) {
      finish(*record, GoalState::Aborted, std::string("on_execute threw: ") + e.what(), Result{});
    } catch (...) {
      finish(*record, GoalState::Aborted,
             "on_execute threw an exception that is not a std::exception", Result{});
    }
  }
}

template <Action A>
typename A::CancelGoal::Response ActionServerCore<A>::cancel(const GoalId& id) {
  typename A::CancelGoal::Response response{};
  std::vector<RecordPtr> targets;
  {
    std::lock_guard lock(mutex_);
    if (id.is_all()) {
      for (const auto& [live_id, record] : live_) targets.push_back(record);
    } else if (const auto found = live_.find(id); found != live_.end()) {
      targets.push_back(found->second);
    } else {
      const bool ended = std::any_of(ended_.begin(), ended_.end(),
                                     [&](const RecordPtr& record) { return record->id == id; });
      response.return_code =
          static_cast<std::uint8_t>(ended ? CancelCode::AlreadyDone : CancelCode::UnknownGoal);
      return response;
    }
  }
  std::vector<RecordPtr> agreed;
  for (const RecordPtr& record : targets) {
    bool agrees = true;
    if (config_.on_cancel) {
      try {
        agrees = config_.on_cancel(ServerGoal<A>(this->shared_from_this(), record, false));
      } catch (...) {
        agrees = false;
      }
    }
    if (agrees) agreed.push_back(record);
  }
  std::uint32_t canceling = 0;
  {
    std::lock_guard lock(mutex_);
    for (const RecordPtr& record : agreed) {
      if (is_terminal(record->state)) continue;
      if (record->state != GoalState::Canceling) {
        record_cancel_locked(*record, kCanceledByClientReason);
      }
      ++canceling;
    }
  }
  changed_.notify_all();
  response.goals_canceling = canceling;
  if (!id.is_all() && canceling == 0) {
    response.return_code =
        static_cast<std::uint8_t>(agreed.empty() ? CancelCode::Rejected : CancelCode::AlreadyDone);
  }
  return response;
}

}  // namespace detail

/// A running action server (move-only; destruction stops it). Goals run one at a time, on the
/// server's executor thread with on_execute, or (tick mode, without on_execute) handed out by
/// next_goal(). Three threads answer send_goal, cancel_goal and get_result.
template <Action A>
class ActionServer {
 public:
  ActionServer(ActionServer&&) noexcept = default;
  ActionServer& operator=(ActionServer&& other) noexcept {
    if (this != &other) {
      stop();
      core_ = std::move(other.core_);
    }
    return *this;
  }
  ActionServer(const ActionServer&) = delete;
  ActionServer& operator=(const ActionServer&) = delete;
  ~ActionServer() { stop(); }

  /// Tick mode: the next goal to run, now Executing; none while one executes or none waits.
  /// Never blocks.
  std::optional<ServerGoal<A>> next_goal() {
    if (!core_) return std::nullopt;
    return core_->next_goal();
  }

  /// Aborts the live goals ("the action server stopped"), asks the executing one to cancel and
  /// waits for on_execute to return, then withdraws. Idempotent; not from on_execute.
  void stop() noexcept {
    if (core_) core_->stop();
  }
  bool is_running() const noexcept { return core_ && core_->is_running(); }
  ActionServerStats stats() const noexcept { return core_ ? core_->stats() : ActionServerStats{}; }

 private:
  friend class ActionServerBuilder<A>;
  explicit ActionServer(std::shared_ptr<detail::ActionServerCore<A>> core)
      : core_(std::move(core)) {}

  std::shared_ptr<detail::ActionServerCore<A>> core_;
};

/// Configures and starts an ActionServer.
template <Action A>
class ActionServerBuilder {
 public:
  /// Decides each arriving goal after the policy admitted it (default: accept). Runs on the
  /// send_goal thread, before the client has its answer: be quick.
  ActionServerBuilder& on_goal(std::function<GoalDecision(const typename A::Goal&)> decide) {
    config_.on_goal = std::move(decide);
    return *this;
  }
  /// Decides each cancel request (default: accept).
  ActionServerBuilder& on_cancel(std::function<bool(const ServerGoal<A>&)> decide) {
    config_.on_cancel = std::move(decide);
    return *this;
  }
  /// Runs each goal on the server's executor thread. Returning without an outcome aborts the
  /// goal. Without it the server is in tick mode (ActionServer::next_goal()).
  ActionServerBuilder& on_execute(std::function<void(ServerGoal<A>&)> execute) {
    config_.on_execute = std::move(execute);
    return *this;
  }
  ActionServerBuilder& policy(ActionPolicy policy) {
    config_.policy = policy;
    return *this;
  }
  /// Queue policy: the most goals waiting (default 8).
  ActionServerBuilder& queue_capacity(std::size_t capacity) {
    config_.queue_capacity = capacity;
    return *this;
  }
  /// The namespace and, when this server creates the topics, their capacity and message size.
  ActionServerBuilder& options(TopicOptions options) {
    config_.options = std::move(options);
    return *this;
  }

  /// Registers the three services and starts the threads. Throws horus::Error as
  /// ServiceServerBuilder::build() does (a live server already serves the action, or the
  /// topics carry other types), and for a Queue policy of capacity 0.
  ActionServer<A> build() {
    if (config_.policy == ActionPolicy::Queue && config_.queue_capacity == 0) {
      throw Error("ActionServerBuilder<" + std::string(A::name()) +
                  ">: the queue policy needs a queue_capacity of at least 1");
    }
    auto core = std::make_shared<detail::ActionServerCore<A>>(config_);
    core->start();
    return ActionServer<A>(std::move(core));
  }

 private:
  typename detail::ActionServerCore<A>::Config config_;
};

}  // namespace horus
