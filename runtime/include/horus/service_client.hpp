// horus::ServiceClient<S>: blocking calls to a service's server, in this or another process.
#pragma once

#include <chrono>
#include <optional>
#include <thread>

#include "horus/detail/service_channel.hpp"
#include "horus/service_error.hpp"
#include "horus/service_result.hpp"
#include "horus/service_retry.hpp"
#include "horus/service_type.hpp"
#include "horus/topic.hpp"

namespace horus {

/// Calls a service and blocks for the answer. Failures are values (ServiceResult), never
/// exceptions: NoServer at once when no server is registered, Transport within a few
/// milliseconds when the server crashes or stops mid-call, Timeout when it does not answer in time.
/// Waiting sleeps on the response topic's futex: there is no poll interval. A client is used by
/// one thread at a time (open one per thread); any number of clients in any number of processes
/// may call one server at once, each gets its own answers.
template <Service S>
class ServiceClient {
 public:
  using Request = typename S::Request;
  using Response = typename S::Response;

  /// Opens the service's topics (creating them when no server exists yet). `options` choose the
  /// namespace and, when this creates the topics, their capacity and message size. Throws
  /// horus::Error when the topics carry other types (a server built from another schema).
  explicit ServiceClient(const TopicOptions& options = {}) : channel_(options) {}

  /// Sends `request` and waits up to `timeout` for the answer.
  ServiceResult<Response> call(const Request& request, std::chrono::nanoseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    ServiceResult<detail::SentRequest> sent = channel_.send(request, false);
    if (!sent) {
      return sent.error();
    }
    return channel_.wait(*sent, deadline);
  }

  /// call() retried after transient errors with the default RetryConfig (3 retries, 10 ms
  /// backoff doubling). NoServer and ServiceFailed are returned at once.
  ServiceResult<Response> call_resilient(const Request& request, std::chrono::nanoseconds timeout) {
    return call_resilient_with(request, timeout, RetryConfig{});
  }

  /// call() retried after transient errors as `config` says; each attempt gets the full timeout.
  ServiceResult<Response> call_resilient_with(const Request& request,
                                              std::chrono::nanoseconds timeout,
                                              const RetryConfig& config) {
    for (std::uint32_t retry = 0;; ++retry) {
      ServiceResult<Response> result = call(request, timeout);
      if (result || !result.error().is_transient() || retry >= config.max_retries()) {
        return result;
      }
      std::this_thread::sleep_for(config.backoff(retry));
    }
  }

  /// call(), with a timeout as an empty optional instead of an error.
  ServiceResult<std::optional<Response>> call_optional(const Request& request,
                                                       std::chrono::nanoseconds timeout) {
    ServiceResult<Response> result = call(request, timeout);
    if (result) {
      return std::optional<Response>(std::move(*result));
    }
    if (result.error().kind() == ServiceErrorKind::Timeout) {
      return std::optional<Response>();
    }
    return result.error();
  }

  /// Waits up to `timeout` for a live server (woken when one registers); false if none came.
  bool wait_for_server(std::chrono::nanoseconds timeout) {
    return channel_.wait_for_server(timeout);
  }

  /// This client's id in the frames it sends (for logs and tools).
  std::uint64_t client_id() const noexcept { return channel_.client_id(); }

 private:
  detail::ServiceChannel<S> channel_;
};

}  // namespace horus
