// horus::ServiceServerBuilder<S> and ServiceServer<S>: answering a service's requests on a
// thread of their own.
#pragma once

#include <atomic>
#include <chrono>
#include <concepts>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <system_error>
#include <thread>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "horus/codec.hpp"
#include "horus/detail/log_source.hpp"
#include "horus/error.hpp"
#include "horus/log.hpp"
#include "horus/raw_service.hpp"
#include "horus/service_message.hpp"
#include "horus/service_type.hpp"
#include "horus/topic.hpp"

namespace horus {

/// What a request handler returns: the response, or why the request failed (the text the
/// client receives as ServiceFailed).
template <Message Res>
using HandlerResult = std::variant<Res, std::string>;

/// Counters of a running server: nothing fails silently.
struct ServiceServerStats {
  /// Requests handled (answered with a response or a failure).
  std::uint64_t requests = 0;
  /// Requests whose handler returned an error or threw.
  std::uint64_t failures = 0;
  /// Requests never seen because more than the request topic's capacity queued up.
  std::uint64_t lost_requests = 0;
  /// Answers the response topic refused (too large: the client got ServiceFailed instead).
  std::uint64_t send_failures = 0;
};

template <Service S>
class ServiceServerBuilder;

/// A running server: one thread that takes requests in arrival order and answers each with the
/// handler's result. A handler that throws answers ServiceFailed and the server keeps serving.
/// stop() (or destruction) finishes the request being handled and withdraws the registration.
/// A typed layer over RawServiceServer (horus/raw_service.hpp): its serve loop, registration and
/// reply topics are the byte-level server's; this one decodes requests and encodes answers.
template <Service S>
class ServiceServer {
 public:
  ServiceServer(ServiceServer&&) noexcept = default;
  ServiceServer& operator=(ServiceServer&& other) noexcept {
    if (this != &other) {
      stop();
      state_ = std::move(other.state_);
    }
    return *this;
  }
  ServiceServer(const ServiceServer&) = delete;
  ServiceServer& operator=(const ServiceServer&) = delete;
  ~ServiceServer() { stop(); }

  /// Stops serving; idempotent. Not to be called from the handler, nor concurrently with itself.
  void stop() noexcept {
    if (!state_ || !state_->thread.joinable()) {
      return;
    }
    // Wakes the serving thread from its wait at once.
    state_->server.stop();
    state_->thread.join();
    state_->server.withdraw();
  }

  bool is_running() const noexcept {
    return state_ && state_->thread.joinable() && !state_->server.stopped();
  }

  ServiceServerStats stats() const noexcept {
    ServiceServerStats stats;
    if (state_) {
      stats.requests = state_->requests.load(std::memory_order_relaxed);
      stats.failures = state_->failures.load(std::memory_order_relaxed);
      stats.lost_requests = state_->lost_requests.load(std::memory_order_relaxed);
      stats.send_failures = state_->send_failures.load(std::memory_order_relaxed);
    }
    return stats;
  }

 private:
  friend class ServiceServerBuilder<S>;
  using Request = typename S::Request;
  using Response = typename S::Response;
  using Handler = std::function<HandlerResult<Response>(Request&&)>;

  /// Long enough to cost nothing while idle; stop() wakes the wait at once.
  static constexpr std::chrono::milliseconds kIdleWake{250};

  struct State {
    /// Registers the server (horus::Error while another live one serves the service).
    State(Handler handler_in, const TopicOptions& options, std::string log_source_in)
        : handler(std::move(handler_in)),
          log_source(std::move(log_source_in)),
          server(raw_service_type<S>(), options) {}

    void serve() noexcept {
      static_cast<void>(detail::exchange_thread_log_source(log_source));
      while (!server.stopped()) {
        std::optional<RawServiceServer::Request> request = server.next(kIdleWake);
        lost_requests.store(server.lost_requests(), std::memory_order_relaxed);
        if (request) {
          answer(*request);
        }
      }
    }

    void answer(RawServiceServer::Request& request) noexcept {
      const ServiceCaller& caller = request.caller;
      std::optional<Request> decoded = try_decode<Request>(std::span(
          reinterpret_cast<const std::uint8_t*>(request.payload.data()), request.payload.size()));
      if (!decoded) {
        return;  // not a request of this type: it passes by, as on a typed request topic
      }
      ServiceResponse<Response> response =
          respond(ServiceRequest<Request>{caller.request_id, std::move(*decoded)});
      requests.fetch_add(1, std::memory_order_relaxed);
      const auto count_send_failure = [this] {
        send_failures.fetch_add(1, std::memory_order_relaxed);
      };
      try {
        if (response.ok && response.payload) {
          const std::vector<std::uint8_t> bytes = encode(*response.payload);
          // Counted before the client hears of the refusal, so its stats() show it then.
          server.answer(caller, std::as_bytes(std::span(bytes)), count_send_failure);
        } else {
          failures.fetch_add(1, std::memory_order_relaxed);
          if (!server.fail(caller,
                           ServiceError::service_failed(response.error.value_or(std::string())))) {
            count_send_failure();
          }
        }
      } catch (...) {
        // Out of memory for the answer: the client still learns that the request failed.
        if (response.ok) failures.fetch_add(1, std::memory_order_relaxed);
        if (!fail_without_text(caller)) count_send_failure();
      }
    }

    bool fail_without_text(const ServiceCaller& caller) noexcept {
      try {
        return server.fail(caller, ServiceError::service_failed({}));
      } catch (...) {
        return false;
      }
    }

    /// The handler's answer: its response, or a failure with its error or what it threw.
    ServiceResponse<Response> respond(ServiceRequest<Request>&& request) noexcept {
      try {
        HandlerResult<Response> result = handler(std::move(request.payload));
        if (Response* response = std::get_if<0>(&result)) {
          return ServiceResponse<Response>::success(request.request_id, std::move(*response));
        }
        return ServiceResponse<Response>::failure(request.request_id,
                                                  std::move(std::get<1>(result)));
      } catch (const std::exception& e) {
        return failure_of(request.request_id, std::string("the handler threw: ") + e.what());
      } catch (...) {
        return failure_of(request.request_id,
                          "the handler threw an exception that is not a std::exception");
      }
    }

    /// A failure with `text`, or without it when there is no memory for it.
    static ServiceResponse<Response> failure_of(std::uint64_t request_id, std::string_view text) {
      try {
        return ServiceResponse<Response>::failure(request_id, std::string(text));
      } catch (...) {
        return ServiceResponse<Response>::failure(request_id, std::string());
      }
    }

    Handler handler;
    std::string log_source;   // what the handler's log lines carry
    RawServiceServer server;  // next() and answers: the serving thread's
    std::atomic<std::uint64_t> requests{0};
    std::atomic<std::uint64_t> failures{0};
    std::atomic<std::uint64_t> lost_requests{0};
    std::atomic<std::uint64_t> send_failures{0};
    std::thread thread;
  };

  explicit ServiceServer(std::unique_ptr<State> state) : state_(std::move(state)) {}

  std::unique_ptr<State> state_;
};

/// Configures and starts a ServiceServer:
///   auto server = horus::ServiceServerBuilder<GetRobotPose>()
///                     .on_request([](const GetRobotPoseRequest& req) -> HandlerResult<...> {...})
///                     .build();
template <Service S>
class ServiceServerBuilder {
 public:
  using Request = typename S::Request;
  using Response = typename S::Response;

  /// The handler, called on the server's thread with each request. It returns the Response, or a
  /// HandlerResult<Response> holding either the response or an error text.
  template <class F>
  ServiceServerBuilder& on_request(F&& handler) {
    static_assert(std::is_invocable_r_v<HandlerResult<Response>, F&, Request&&>,
                  "a service handler takes the Request and returns the Response or a "
                  "HandlerResult<Response> (the response or an error text)");
    handler_ = std::forward<F>(handler);
    return *this;
  }

  /// The namespace and, when this server creates the service's topics, their capacity and
  /// message size (default: HORUS_NAMESPACE, 64 slots, 16 KiB).
  ServiceServerBuilder& options(TopicOptions options) {
    options_ = std::move(options);
    return *this;
  }

  /// Registers the server and starts its thread. The handler's log lines carry the name of the
  /// node whose callback (init(), say) builds the server, else the service's name. Throws
  /// horus::Error without a handler, when a live server already serves the service in the
  /// namespace, or when the topics carry other types.
  ServiceServer<S> build() {
    if (!handler_) {
      throw Error("ServiceServerBuilder<" + std::string(S::name()) +
                  ">: build() without on_request(handler)");
    }
    using State = typename ServiceServer<S>::State;
    std::string log_source(log::current_node());
    if (log_source.empty()) log_source = S::name();
    auto state = std::make_unique<State>(handler_, options_, std::move(log_source));
    State* serving = state.get();
    try {
      state->thread = std::thread([serving] { serving->serve(); });
    } catch (const std::system_error& e) {
      state->server.withdraw();
      throw Error("service " + std::string(S::name()) +
                  ": cannot start the server thread: " + e.what());
    }
    return ServiceServer<S>(std::move(state));
  }

 private:
  typename ServiceServer<S>::Handler handler_;
  TopicOptions options_;
};

}  // namespace horus
