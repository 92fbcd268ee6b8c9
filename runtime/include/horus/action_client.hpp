// horus::ActionClient<A> and GoalHandle<A>: sending goals to an action's server and following
// them (feedback, state, result, cancel). The wire: runtime/src/action/README.md.
//
//   horus::ActionClient<Navigate> client;
//   auto handle = client.send_goal({.x = 2.0, .y = 1.0}, 1s);   // ServiceResult<GoalHandle<...>>
//   if (handle) {
//     while (auto feedback = handle->next_feedback(1s)) { ... }
//     auto result = handle->result(10s);                         // GoalResult: state, reason,
//     result
//   }
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "horus/action_type.hpp"
#include "horus/detail/action_wire.hpp"
#include "horus/error.hpp"
#include "horus/log.hpp"
#include "horus/raw_service.hpp"
#include "horus/service_client.hpp"
#include "horus/service_result.hpp"
#include "horus/topic.hpp"

namespace horus {

/// How a goal ended: its terminal state, the reason given (empty for a success) and the result
/// (the type's defaults unless the server gave one).
template <class R>
struct GoalResult {
  GoalState state = GoalState::Unknown;
  std::string reason;
  R result{};
};

/// What a client runs for one goal, on its pump thread: keep them short.
template <Action A>
struct GoalCallbacks {
  std::function<void(const typename A::Feedback&)> on_feedback;
  std::function<void(GoalState, std::string_view)> on_state;
};

template <Action A>
class ActionClient;
template <Action A>
class GoalHandle;

namespace detail {

/// A goal as its client sees it; every field under the client's mutex.
template <Action A>
struct ClientGoalRecord {
  GoalId id;
  GoalState state = GoalState::Unknown;
  std::string reason;
  std::deque<typename A::Feedback> feedback;
  std::uint64_t lost_feedback = 0;
  std::optional<typename A::Feedback> latest_feedback;
  typename A::Result result{};
  GoalCallbacks<A> callbacks;
  /// The server's registration when the goal was sent: a change means it went away.
  std::uint64_t server_instance = 0;
  std::uint64_t server_pid = 0;
  /// A terminal status came (at `status_ended_at`) before its result: the pump asks
  /// get_result if the result has not come a live slice later.
  std::optional<GoalState> ended_by_status;
  std::chrono::steady_clock::time_point status_ended_at{};
};

template <Action A>
class ActionClientCore : public std::enable_shared_from_this<ActionClientCore<A>> {
 public:
  using Record = ClientGoalRecord<A>;
  using RecordPtr = std::shared_ptr<Record>;
  using Feedback = typename A::Feedback;

  explicit ActionClientCore(const TopicOptions& options)
      : send_goal_(options),
        cancel_goal_(options),
        get_result_(options),
        send_registration_(A::SendGoal::name(), options),
        feedback_(A::feedback_topic(), options),
        status_(A::status_topic(), options),
        results_(A::result_topic(), options),
        pump_registration_(A::SendGoal::name(), options),
        wait_({std::string(A::feedback_topic()), std::string(A::status_topic()),
               std::string(A::result_topic())},
              options.namespace_name) {}

  std::uint64_t client_id() const noexcept { return send_goal_.client_id(); }

  ServiceResult<RecordPtr> send_goal(const typename A::Goal& goal, std::chrono::nanoseconds timeout,
                                     GoalCallbacks<A> callbacks) {
    typename A::SendGoal::Request request{};
    request.goal = goal;
    auto record = std::make_shared<Record>();
    record->callbacks = std::move(callbacks);
    std::lock_guard send(send_mutex_);
    const std::optional<ServiceRegistration> server = send_registration_.latest();
    if (!server || server->server_pid == 0) {
      return ServiceError::no_server("no server of action " + std::string(A::name()));
    }
    record->server_instance = server->server_instance;
    record->server_pid = server->server_pid;
    {
      std::lock_guard lock(mutex_);
      if (closed_) return ServiceError::transport(std::string(kClientClosedReason));
      record->id = GoalId{send_goal_.client_id(), next_sequence_++};
      // In the table before the request leaves: feedback that beats the answer is kept.
      live_.emplace(record->id, record);
      start_pump_locked();
    }
    // The pump may sleep in an idle slice now: the goal's first status wakes it, and from then
    // on it checks the server every live slice.
    set_goal_id(request, record->id);
    ServiceResult<typename A::SendGoal::Response> answer = send_goal_.call(request, timeout);
    std::lock_guard lock(mutex_);
    if (!answer) {
      live_.erase(record->id);
      return answer.error();
    }
    if (!answer->accepted) {
      live_.erase(record->id);
      record->state = GoalState::Rejected;
      record->reason = text_of(answer->reason);
      changed_.notify_all();
    } else if (record->state == GoalState::Unknown) {
      record->state = GoalState::Accepted;
    }
    return record;
  }

  ServiceResult<CancelCode> cancel(const GoalId& id, std::chrono::nanoseconds timeout) {
    typename A::CancelGoal::Request request{};
    set_goal_id(request, id);
    std::lock_guard lock(cancel_mutex_);
    ServiceResult<typename A::CancelGoal::Response> answer = cancel_goal_.call(request, timeout);
    if (!answer) return answer.error();
    return static_cast<CancelCode>(answer->return_code);
  }

  bool wait_for_server(std::chrono::nanoseconds timeout) {
    std::lock_guard send(send_mutex_);
    return send_goal_.wait_for_server(timeout);
  }

  /// Cancels the live goals (each waited for kCloseCancelTimeout at most), stops the pump and
  /// aborts what is still live. Idempotent.
  void close() noexcept {
    std::vector<GoalId> live;
    {
      std::lock_guard lock(mutex_);
      if (closed_) return;
      for (const auto& [id, record] : live_) live.push_back(id);
    }
    for (const GoalId& id : live) {
      try {
        static_cast<void>(cancel(id, kCloseCancelTimeout));
      } catch (...) {
        // Out of memory for the request: the server's client check ends the goal later.
      }
    }
    {
      std::lock_guard lock(mutex_);
      closed_ = true;
    }
    wait_.interrupt();
    if (pump_.joinable()) pump_.join();
    std::vector<std::function<void()>> calls;
    {
      std::lock_guard lock(mutex_);
      std::vector<RecordPtr> remaining;
      for (const auto& [id, record] : live_) remaining.push_back(record);
      for (const RecordPtr& record : remaining) {
        end_locked(*record, GoalState::Aborted, kClientClosedReason, calls);
      }
    }
    changed_.notify_all();
    run(calls);
  }

  // The handles' side: each reads its record under the client's mutex.
  template <class F>
  auto with_record(const Record& record, F&& read) const {
    std::lock_guard lock(mutex_);
    return read(record);
  }

  std::optional<Feedback> try_feedback(Record& record) {
    std::lock_guard lock(mutex_);
    return pop_feedback_locked(record);
  }

  std::optional<Feedback> next_feedback(Record& record, std::chrono::nanoseconds timeout) {
    std::unique_lock lock(mutex_);
    changed_.wait_for(lock, timeout,
                      [&] { return !record.feedback.empty() || is_terminal(record.state); });
    return pop_feedback_locked(record);
  }

  std::optional<GoalResult<typename A::Result>> result(const Record& record,
                                                       std::chrono::nanoseconds timeout) {
    std::unique_lock lock(mutex_);
    if (!changed_.wait_for(lock, timeout, [&] { return is_terminal(record.state); })) {
      return std::nullopt;
    }
    return GoalResult<typename A::Result>{record.state, record.reason, record.result};
  }

 private:
  static std::optional<Feedback> pop_feedback_locked(Record& record) {
    if (record.feedback.empty()) return std::nullopt;
    std::optional<Feedback> feedback(std::move(record.feedback.front()));
    record.feedback.pop_front();
    return feedback;
  }

  void start_pump_locked() {
    if (pump_.joinable()) return;
    try {
      pump_ = std::thread([this] { pump(); });
    } catch (const std::system_error& e) {
      live_.clear();
      throw Error("action " + std::string(A::name()) +
                  ": cannot start the client's thread: " + e.what());
    }
  }

  static void run(std::vector<std::function<void()>>& calls) noexcept {
    for (std::function<void()>& call : calls) {
      try {
        call();
      } catch (const std::exception& e) {
        log::warn("action %s: a goal callback threw: %s", std::string(A::name()).c_str(), e.what());
      } catch (...) {
        log::warn("action %s: a goal callback threw", std::string(A::name()).c_str());
      }
    }
    calls.clear();
  }

  /// The pump: sleeps on the three topics (short slices while a goal is live, for the server
  /// check), then drains them into the goals' records and runs the callbacks.
  void pump() noexcept {
    std::vector<std::function<void()>> calls;
    std::uint64_t results_lost = results_.lost();
    // The server check reads /proc: every check interval, not on every message's wake.
    auto next_server_check = std::chrono::steady_clock::now();
    for (;;) {
      bool live = false;
      {
        std::unique_lock lock(mutex_);
        if (closed_) return;
        live = !live_.empty();
      }
      wait_.wait(live ? kPumpLiveSlice : kPumpIdleSlice);
      try {
        drain(calls);
        run(calls);
        const std::uint64_t lost = results_.lost();
        fetch_results(lost != results_lost);
        results_lost = lost;
        run(calls);
        if (live && std::chrono::steady_clock::now() >= next_server_check) {
          check_server(calls);
          run(calls);
          next_server_check = std::chrono::steady_clock::now() + kServiceServerCheckInterval;
        }
      } catch (const std::exception& e) {
        log::warn("action %s: the client's pump failed: %s", std::string(A::name()).c_str(),
                  e.what());
      }
    }
  }

  void drain(std::vector<std::function<void()>>& calls) {
    // Results are taken first and applied last: the feedback a server published before a
    // result is then visible below, and is not dropped as belonging to an ended goal.
    std::vector<typename A::ResultMessage> results;
    while (std::optional<typename A::ResultMessage> message = results_.try_recv()) {
      results.push_back(std::move(*message));
    }
    while (std::optional<typename A::FeedbackMessage> message = feedback_.try_recv()) {
      std::lock_guard lock(mutex_);
      const auto found = live_.find(goal_id_of(*message));
      if (found == live_.end()) continue;
      Record& record = *found->second;
      if (record.feedback.size() >= kFeedbackKept) {
        record.feedback.pop_front();
        ++record.lost_feedback;
      }
      record.feedback.push_back(message->feedback);
      record.latest_feedback = message->feedback;
      if (record.callbacks.on_feedback) {
        calls.push_back([callback = record.callbacks.on_feedback,
                         feedback = std::move(message->feedback)] { callback(feedback); });
      }
      changed_.notify_all();
    }
    while (std::optional<typename A::Status> status = status_.try_recv()) {
      std::lock_guard lock(mutex_);
      const auto found = live_.find(goal_id_of(*status));
      if (found == live_.end()) continue;
      Record& record = *found->second;
      const auto state = static_cast<GoalState>(status->state);
      if (is_terminal(state)) {
        if (!record.ended_by_status) {  // its result follows on A.result, or get_result has it
          record.ended_by_status = state;
          record.status_ended_at = std::chrono::steady_clock::now();
        }
        if (record.reason.empty()) record.reason = text_of(status->reason);
      } else if (static_cast<std::uint8_t>(state) > static_cast<std::uint8_t>(record.state)) {
        // States only move forward: an Accepted published before the executor's Executing
        // may arrive after it.
        record.state = state;
        if (record.callbacks.on_state) {
          calls.push_back([callback = record.callbacks.on_state, state,
                           reason = text_of(status->reason)] { callback(state, reason); });
        }
        changed_.notify_all();
      }
    }
    for (typename A::ResultMessage& message : results) {
      std::lock_guard lock(mutex_);
      const auto found = live_.find(goal_id_of(message));
      if (found == live_.end()) continue;
      found->second->result = std::move(message.result);
      end_locked(*found->second, static_cast<GoalState>(message.state), text_of(message.reason),
                 calls);
    }
  }

  /// Asks get_result for goals whose result message may have been lost: every live one when
  /// the result topic lost messages, else those whose terminal status came without a result.
  void fetch_results(bool every_live) {
    std::vector<RecordPtr> wanted;
    {
      std::lock_guard lock(mutex_);
      const auto overdue = std::chrono::steady_clock::now() - kPumpLiveSlice;
      for (const auto& [id, record] : live_) {
        // A result (and the feedback before it) may still be on its way after the status.
        if (every_live || (record->ended_by_status && record->status_ended_at <= overdue)) {
          wanted.push_back(record);
        }
      }
    }
    std::vector<std::function<void()>> calls;
    for (const RecordPtr& record : wanted) {
      typename A::GetResult::Request request{};
      set_goal_id(request, record->id);
      std::optional<typename A::ResultMessage> answer;
      {
        std::lock_guard lock(get_result_mutex_);
        ServiceResult<typename A::ResultMessage> result =
            get_result_.call(request, kCloseCancelTimeout);
        if (result) answer = std::move(*result);
      }
      std::lock_guard lock(mutex_);
      if (answer && is_terminal(static_cast<GoalState>(answer->state))) {
        record->result = std::move(answer->result);
        end_locked(*record, static_cast<GoalState>(answer->state), text_of(answer->reason), calls);
      } else if (!answer && record->ended_by_status) {
        end_locked(*record, *record->ended_by_status, record->reason, calls);
      }
    }
    run(calls);
  }

  /// Ends the live goals of a server that went away: withdrawn (stopped), replaced by a new
  /// instance (restarted), or whose process exited.
  void check_server(std::vector<std::function<void()>>& calls) {
    const std::optional<ServiceRegistration> now = pump_registration_.latest();
    std::lock_guard lock(mutex_);
    std::vector<std::pair<RecordPtr, std::string>> gone;
    for (const auto& [id, record] : live_) {
      if (record->server_instance == 0) continue;
      if (!now || now->server_pid == 0) {
        gone.emplace_back(record, std::string(kServerStoppedReason));
      } else if (now->server_instance != record->server_instance) {
        gone.emplace_back(record, std::string(kServerRestartedReason));
      } else if (service_server_gone(record->server_pid)) {
        gone.emplace_back(record, server_exited_reason(record->server_pid));
      }
    }
    for (auto& [record, reason] : gone) {
      end_locked(*record, GoalState::Aborted, reason, calls);
    }
  }

  void end_locked(Record& record, GoalState state, std::string_view reason,
                  std::vector<std::function<void()>>& calls) {
    if (is_terminal(record.state)) return;
    record.state = state;
    record.reason = std::string(reason);
    live_.erase(record.id);
    if (record.callbacks.on_state) {
      calls.push_back([callback = record.callbacks.on_state, state, text = record.reason] {
        callback(state, text);
      });
    }
    changed_.notify_all();
  }

  std::mutex send_mutex_;  // send_goal_ and send_registration_
  ServiceClient<typename A::SendGoal> send_goal_;
  std::mutex cancel_mutex_;
  ServiceClient<typename A::CancelGoal> cancel_goal_;
  std::mutex get_result_mutex_;
  ServiceClient<typename A::GetResult> get_result_;
  ServiceRegistrationTopic send_registration_;

  // The pump's: opened with the client, so every message after its construction reaches it.
  Topic<typename A::FeedbackMessage> feedback_;
  Topic<typename A::Status> status_;
  Topic<typename A::ResultMessage> results_;
  ServiceRegistrationTopic pump_registration_;
  ActionTopicWait wait_;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool closed_ = false;
  std::uint64_t next_sequence_ = 1;
  std::unordered_map<GoalId, RecordPtr> live_;
  std::thread pump_;
};

}  // namespace detail

/// A goal sent by an ActionClient: its state, feedback and result as the client's pump thread
/// receives them. Move-only; dropping it does not cancel the goal.
template <Action A>
class GoalHandle {
 public:
  using Feedback = typename A::Feedback;

  GoalHandle(GoalHandle&&) noexcept = default;
  GoalHandle& operator=(GoalHandle&&) noexcept = default;
  GoalHandle(const GoalHandle&) = delete;
  GoalHandle& operator=(const GoalHandle&) = delete;

  GoalId id() const { return record_->id; }
  GoalState state() const {
    return core_->with_record(*record_, [](const auto& record) { return record.state; });
  }
  /// Why the goal was rejected, canceled or aborted (empty otherwise).
  std::string reason() const {
    return core_->with_record(*record_, [](const auto& record) { return record.reason; });
  }
  bool is_done() const { return is_terminal(state()); }

  /// The oldest feedback not taken yet (the last 64 are kept; older ones count in
  /// lost_feedback()).
  std::optional<Feedback> try_feedback() { return core_->try_feedback(*record_); }
  /// try_feedback(), waiting up to `timeout` for one; none once the goal ended and all were taken.
  std::optional<Feedback> next_feedback(std::chrono::nanoseconds timeout) {
    return core_->next_feedback(*record_, timeout);
  }
  std::optional<Feedback> latest_feedback() const {
    return core_->with_record(*record_, [](const auto& record) { return record.latest_feedback; });
  }
  std::uint64_t lost_feedback() const {
    return core_->with_record(*record_, [](const auto& record) { return record.lost_feedback; });
  }

  /// How the goal ended, waiting up to `timeout`; none when it is still live then.
  std::optional<GoalResult<typename A::Result>> result(std::chrono::nanoseconds timeout) {
    return core_->result(*record_, timeout);
  }
  /// result() without waiting: for a node's tick.
  std::optional<GoalResult<typename A::Result>> try_result() {
    return core_->result(*record_, std::chrono::nanoseconds(0));
  }

  /// Asks the server to cancel the goal: Accepted (canceling, or canceled at once if it had not
  /// started), Rejected, UnknownGoal or AlreadyDone; a service error when no answer came.
  ServiceResult<CancelCode> cancel(std::chrono::nanoseconds timeout = std::chrono::seconds(1)) {
    return core_->cancel(record_->id, timeout);
  }

 private:
  friend class ActionClient<A>;
  GoalHandle(std::shared_ptr<detail::ActionClientCore<A>> core,
             std::shared_ptr<detail::ClientGoalRecord<A>> record)
      : core_(std::move(core)), record_(std::move(record)) {}

  std::shared_ptr<detail::ActionClientCore<A>> core_;
  std::shared_ptr<detail::ClientGoalRecord<A>> record_;
};

/// Sends goals to an action's server, in this or another process. Any thread may send and
/// cancel. One pump thread (from the first send_goal) receives the action's topics for all the
/// client's goals and runs their callbacks. Destruction cancels the live goals and aborts their
/// handles ("the action client closed").
template <Action A>
class ActionClient {
 public:
  /// Opens the action's services and topics. Throws horus::Error when they carry other types.
  explicit ActionClient(const TopicOptions& options = {})
      : core_(std::make_shared<detail::ActionClientCore<A>>(options)) {}
  ActionClient(ActionClient&&) noexcept = default;
  ActionClient& operator=(ActionClient&& other) noexcept {
    if (this != &other) {
      if (core_) core_->close();
      core_ = std::move(other.core_);
    }
    return *this;
  }
  ActionClient(const ActionClient&) = delete;
  ActionClient& operator=(const ActionClient&) = delete;
  ~ActionClient() {
    if (core_) core_->close();
  }

  /// Sends `goal`, waiting up to `timeout` for the server's answer: a handle (Rejected with the
  /// server's reason when refused) or the call's error (NoServer at once, Timeout, Transport).
  ServiceResult<GoalHandle<A>> send_goal(const typename A::Goal& goal,
                                         std::chrono::nanoseconds timeout,
                                         GoalCallbacks<A> callbacks = {}) {
    ServiceResult<std::shared_ptr<detail::ClientGoalRecord<A>>> sent =
        core_->send_goal(goal, timeout, std::move(callbacks));
    if (!sent) return sent.error();
    return GoalHandle<A>(core_, std::move(*sent));
  }

  /// Cancels every live goal of the server (whoever sent them).
  ServiceResult<CancelCode> cancel_all(std::chrono::nanoseconds timeout) {
    return core_->cancel(GoalId{}, timeout);
  }
  /// Waits up to `timeout` for a live server; false if none came.
  bool wait_for_server(std::chrono::nanoseconds timeout) { return core_->wait_for_server(timeout); }
  /// The first half of this client's goal ids.
  std::uint64_t client_id() const noexcept { return core_->client_id(); }

 private:
  std::shared_ptr<detail::ActionClientCore<A>> core_;
};

}  // namespace horus
