// horus::ServiceServerBuilder<S> and ServiceServer<S>: answering a service's requests on a
// thread of their own.
#pragma once

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <concepts>
#include <cstdint>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <system_error>
#include <thread>
#include <type_traits>
#include <utility>
#include <variant>

#include "horus/detail/log_source.hpp"
#include "horus/detail/service_channel.hpp"
#include "horus/detail/service_frame.hpp"
#include "horus/error.hpp"
#include "horus/log.hpp"
#include "horus/presence.hpp"
#include "horus/service_message.hpp"
#include "horus/service_type.hpp"
#include "horus/topic.hpp"
#include "horus/topic_registry.hpp"

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
    state_->stopping.store(true, std::memory_order_release);
    // A request frame with no client wakes the server thread from its recv() at once.
    static_cast<void>(state_->waker.send(typename State::RequestFrame{}));
    state_->thread.join();
    const std::optional<detail::ServiceRegistration> current = state_->registration.read_latest();
    if (current && current->server_instance == state_->instance) {
      // Withdrawn, not erased: tools still list the service and its types, with no server.
      detail::ServiceRegistration withdrawn = *current;
      withdrawn.server_instance = 0;
      withdrawn.server_pid = 0;
      static_cast<void>(state_->registration.send(withdrawn));
    }
  }

  bool is_running() const noexcept {
    return state_ && state_->thread.joinable() && !state_->stopping.load(std::memory_order_acquire);
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

  /// Long enough to cost nothing while idle; the wake-up frame of stop() makes it irrelevant
  /// unless that frame could not be sent.
  static constexpr std::chrono::milliseconds kIdleWake{250};
  /// Reply topic handles kept open; past this many (clients alive at once) they are re-opened.
  static constexpr std::size_t kMaxReplyTopics = 256;

  struct State {
    using RequestFrame = detail::ServiceRequestFrame<Request>;
    using ResponseFrame = detail::ServiceResponseFrame<Response>;

    State(Handler handler_in, const TopicOptions& options_in, std::string log_source_in)
        : handler(std::move(handler_in)),
          options(options_in),
          log_source(std::move(log_source_in)),
          incoming(S::request_topic(), options),
          waker(S::request_topic(), options),
          registration(detail::registration_topic(S::name()),
                       detail::registration_options(options)),
          instance(detail::new_service_endpoint_id()),
          announced(detail::ProcessUse{detail::ProcessUse::Kind::ServiceServer,
                                       options.namespace_name, std::string(S::name()),
                                       std::string(S::request_type_name()),
                                       std::string(S::response_type_name())}) {}

    void serve() noexcept {
      static_cast<void>(detail::exchange_thread_log_source(log_source));
      while (!stopping.load(std::memory_order_acquire)) {
        std::optional<RequestFrame> request = incoming.recv(kIdleWake);
        lost_requests.store(incoming.lost(), std::memory_order_relaxed);
        if (!request || request->client_id == 0) {
          continue;
        }
        answer(std::move(*request));
      }
    }

    void answer(RequestFrame&& request) noexcept {
      ResponseFrame reply = frame_of(request, [&] {
        return respond(ServiceRequest<Request>{request.request_id, std::move(request.payload)});
      });
      requests.fetch_add(1, std::memory_order_relaxed);
      if (reply.status != detail::kStatusOk) {
        failures.fetch_add(1, std::memory_order_relaxed);
      }
      Topic<ResponseFrame>* outgoing = reply_topic(request.reply_to);
      if (outgoing == nullptr) {
        send_failures.fetch_add(1, std::memory_order_relaxed);
        return;
      }
      if (!outgoing->send(reply)) {
        send_failures.fetch_add(1, std::memory_order_relaxed);
        // Tell the client why instead of leaving it to time out: a failure always fits.
        reply = frame_of(request, [&] {
          return ServiceResponse<Response>::failure(
              request.request_id, "the response does not fit in a slot of " + outgoing->name() +
                                      " (TopicOptions::max_message_size of its creator)");
        });
        static_cast<void>(outgoing->send(reply));
      }
    }

    /// The handle on a client's reply topic, opened on its first request; nullptr when it cannot
    /// be opened (the client then learns from its timeout).
    Topic<ResponseFrame>* reply_topic(std::uint64_t index) noexcept {
      const auto found = replies.find(index);
      if (found != replies.end()) {
        return &found->second;
      }
      try {
        if (replies.size() >= kMaxReplyTopics) {
          replies.clear();
        }
        return &replies.try_emplace(index, detail::reply_topic(S::response_topic(), index), options)
                    .first->second;
      } catch (...) {
        return nullptr;
      }
    }

    /// The handler's answer: its response, or a failure with its error or what it threw.
    ServiceResponse<Response> respond(ServiceRequest<Request>&& request) {
      try {
        HandlerResult<Response> result = handler(std::move(request.payload));
        if (Response* response = std::get_if<0>(&result)) {
          return ServiceResponse<Response>::success(request.request_id, std::move(*response));
        }
        return ServiceResponse<Response>::failure(request.request_id,
                                                  std::move(std::get<1>(result)));
      } catch (const std::exception& e) {
        return ServiceResponse<Response>::failure(request.request_id,
                                                  std::string("the handler threw: ") + e.what());
      } catch (...) {
        return ServiceResponse<Response>::failure(
            request.request_id, "the handler threw an exception that is not a std::exception");
      }
    }

    /// The frame answering `request` with what `make_response` returns.
    template <class MakeResponse>
    static ResponseFrame frame_of(const RequestFrame& request,
                                  MakeResponse&& make_response) noexcept {
      try {
        return detail::response_frame(request.client_id, make_response());
      } catch (...) {
        // Out of memory for the error text: the client still learns that the request failed.
        ResponseFrame reply{};
        reply.client_id = request.client_id;
        reply.request_id = request.request_id;
        reply.status = detail::kStatusFailed;
        return reply;
      }
    }

    Handler handler;
    TopicOptions options;
    std::string log_source;        // what the handler's log lines carry
    Topic<RequestFrame> incoming;  // the server thread's
    /// Reply topics by index (the server thread's): as many as clients alive at once.
    std::map<std::uint64_t, Topic<ResponseFrame>> replies;
    Topic<RequestFrame> waker;  // stop()'s
    Topic<detail::ServiceRegistration> registration;
    std::uint64_t instance;
    detail::AnnouncedUse announced;  // the server in this process's presence announcement
    std::atomic<bool> stopping{false};
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
    const std::optional<detail::ServiceRegistration> current = state->registration.read_latest();
    if (current && current->server_pid != 0 && !detail::server_process_gone(current->server_pid)) {
      throw Error("service " + std::string(S::name()) + " in namespace " + namespace_name() +
                  " already has a server (pid " + std::to_string(current->server_pid) + ")");
    }
    detail::ServiceRegistration registration{};
    registration.server_instance = state->instance;
    registration.fingerprint = S::fingerprint();
    registration.request_type.try_assign(S::request_type_name());
    registration.response_type.try_assign(S::response_type_name());
    registration.server_pid = static_cast<std::uint64_t>(::getpid());
    // The request handle is open already, so every request sent once this is visible reaches it.
    if (!state->registration.send(registration)) {
      throw Error("service " + std::string(S::name()) + ": cannot publish its registration");
    }
    State* serving = state.get();
    try {
      state->thread = std::thread([serving] { serving->serve(); });
    } catch (const std::system_error& e) {
      registration.server_instance = 0;
      registration.server_pid = 0;
      static_cast<void>(state->registration.send(registration));
      throw Error("service " + std::string(S::name()) +
                  ": cannot start the server thread: " + e.what());
    }
    return ServiceServer<S>(std::move(state));
  }

 private:
  std::string namespace_name() const {
    return options_.namespace_name.empty() ? horus::current_namespace() : options_.namespace_name;
  }

  typename ServiceServer<S>::Handler handler_;
  TopicOptions options_;
};

}  // namespace horus
