// horus::AsyncServiceClient<S> and PendingServiceCall<S>: service calls that a node's tick()
// starts and checks every cycle without ever blocking.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <utility>

#include "horus/detail/service_channel.hpp"
#include "horus/service_error.hpp"
#include "horus/service_result.hpp"
#include "horus/service_type.hpp"
#include "horus/topic.hpp"

namespace horus {

/// A call on its way. check() never blocks: call it every tick until it returns a response or an
/// error. A PendingServiceCall and the AsyncServiceClient that made it are used by one thread at a
/// time; dropping it abandons the call (a late answer is then dropped).
template <Service S>
class PendingServiceCall {
 public:
  using Response = typename S::Response;
  using Clock = std::chrono::steady_clock;

  PendingServiceCall(PendingServiceCall&&) noexcept = default;
  PendingServiceCall& operator=(PendingServiceCall&& other) noexcept {
    if (this != &other) {
      abandon();
      channel_ = std::move(other.channel_);
      sent_ = other.sent_;
      deadline_ = other.deadline_;
      next_check_ = other.next_check_;
      outcome_ = std::move(other.outcome_);
    }
    return *this;
  }
  PendingServiceCall(const PendingServiceCall&) = delete;
  PendingServiceCall& operator=(const PendingServiceCall&) = delete;
  ~PendingServiceCall() { abandon(); }

  /// Without blocking: the response once it has arrived, an empty optional while the call is
  /// still pending, or the error (Timeout once the deadline has passed). Once the call has
  /// completed, every further check() returns the same outcome.
  ServiceResult<std::optional<Response>> check() {
    if (!outcome_) {
      poll();
    }
    if (!outcome_) {
      return std::optional<Response>();
    }
    if (*outcome_) {
      return std::optional<Response>(**outcome_);
    }
    return outcome_->error();
  }

  /// Blocks until the response arrives or the deadline passes (not from a real-time tick).
  ServiceResult<Response> wait() && {
    if (!outcome_) {
      outcome_ = channel_->wait(sent_, deadline_);
    }
    return std::move(*outcome_);
  }

  /// Whether the deadline has passed: check() then reports Timeout unless the answer came first.
  bool is_expired() const noexcept { return Clock::now() >= deadline_; }

 private:
  template <Service>
  friend class AsyncServiceClient;

  PendingServiceCall(std::shared_ptr<detail::ServiceChannel<S>> channel, detail::SentRequest sent,
                     Clock::time_point deadline)
      : channel_(std::move(channel)),
        sent_(sent),
        deadline_(deadline),
        next_check_(Clock::now() + detail::kServerCheckInterval) {}
  PendingServiceCall(ServiceError error) : sent_{0, 0}, outcome_(std::move(error)) {}

  void poll() {
    // The deadline first: once is_expired() says so, the call is a Timeout, as documented.
    const Clock::time_point now = Clock::now();
    if (now >= deadline_) {
      channel_->forget(sent_.request_id);
      outcome_ = channel_->timeout_error();
      return;
    }
    channel_->drain();
    if (auto answer = channel_->take(sent_.request_id)) {
      outcome_ = detail::ServiceChannel<S>::to_result(std::move(*answer));
      return;
    }
    if (now >= next_check_) {
      if (std::optional<ServiceError> lost = channel_->check_server(sent_)) {
        channel_->forget(sent_.request_id);
        outcome_ = std::move(*lost);
        return;
      }
      next_check_ = now + detail::kServerCheckInterval;
    }
  }

  void abandon() noexcept {
    if (channel_ && !outcome_) {
      channel_->forget(sent_.request_id);
    }
  }

  std::shared_ptr<detail::ServiceChannel<S>> channel_;
  detail::SentRequest sent_;
  Clock::time_point deadline_{};
  Clock::time_point next_check_{};
  std::optional<ServiceResult<Response>> outcome_;
};

/// Starts service calls without waiting for them. Several calls may be pending at once; each
/// PendingServiceCall gets only its own answer. Used by one thread at a time (a node's tick).
template <Service S>
class AsyncServiceClient {
 public:
  using Request = typename S::Request;
  using Response = typename S::Response;

  /// Opens the service's topics; throws horus::Error like ServiceClient's constructor.
  explicit AsyncServiceClient(const TopicOptions& options = {})
      : channel_(std::make_shared<detail::ServiceChannel<S>>(options)) {}
  AsyncServiceClient(AsyncServiceClient&&) noexcept = default;
  AsyncServiceClient& operator=(AsyncServiceClient&&) noexcept = default;
  // A copy would share the topic handles, which one thread at a time may use.
  AsyncServiceClient(const AsyncServiceClient&) = delete;
  AsyncServiceClient& operator=(const AsyncServiceClient&) = delete;

  /// Sends `request` and returns at once. A call that could not be sent (NoServer, Transport)
  /// comes back already completed with that error.
  PendingServiceCall<S> call_async(const Request& request, std::chrono::nanoseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    ServiceResult<detail::SentRequest> sent = channel_->send(request, true);
    if (!sent) {
      return PendingServiceCall<S>(sent.error());
    }
    return PendingServiceCall<S>(channel_, *sent, deadline);
  }

  /// Blocks up to `timeout` for a live server (set-up code, not a tick); false if none came.
  bool wait_for_server(std::chrono::nanoseconds timeout) {
    return channel_->wait_for_server(timeout);
  }

  std::uint64_t client_id() const noexcept { return channel_->client_id(); }

 private:
  std::shared_ptr<detail::ServiceChannel<S>> channel_;
};

}  // namespace horus
