// The client side of a service, shared by ServiceClient and AsyncServiceClient: sending a
// request, routing answers to the calls that wait for them, and watching the server's liveness.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "horus/detail/process.hpp"
#include "horus/detail/service_frame.hpp"
#include "horus/error.hpp"
#include "horus/presence.hpp"
#include "horus/service_error.hpp"
#include "horus/service_result.hpp"
#include "horus/service_type.hpp"
#include "horus/topic.hpp"
#include "horus/topic_registry.hpp"

namespace horus::detail {

/// How long a waiting call trusts the server without re-reading its registration: a server that
/// crashes (or stops, or restarts) mid-call is reported this late at worst, whatever the timeout.
inline constexpr std::chrono::milliseconds kServerCheckInterval{10};

/// Times a client picks another reply topic after finding its choice taken by a concurrent one.
inline constexpr int kMaxReplyCollisions = 8;

/// Slots of a registration topic: only the latest registration matters.
inline constexpr std::size_t kRegistrationCapacity = 4;

/// Whether a server's process has exited, counting one that its parent has not reaped yet (a
/// zombie still answers kill(pid, 0)). Reads /proc: only while waiting, every
/// kServerCheckInterval, and for introspection.
inline bool server_process_gone(std::uint64_t pid) noexcept {
  return !identity_alive(static_cast<std::uint32_t>(pid));
}

/// A process-unique, machine-unique (among live processes) non-zero id for a client or a server.
inline std::uint64_t new_service_endpoint_id() noexcept {
  static std::atomic<std::uint32_t> counter{0};
  return (static_cast<std::uint64_t>(::getpid()) << 32) |
         (counter.fetch_add(1, std::memory_order_relaxed) + 1U);
}

/// The smallest reply topic index that no live client of the service receives on.
inline std::uint64_t free_reply_index(std::string_view response_topic,
                                      const std::string& namespace_name) {
  const std::string prefix = std::string(response_topic) + ".";
  std::vector<std::uint64_t> taken;
  for (const TopicInfo& topic : list_topics(namespace_name)) {
    const std::string_view name = topic.name;
    if (topic.subscribers == 0 || name.substr(0, prefix.size()) != prefix) {
      continue;
    }
    std::uint64_t index = 0;
    const char* first = name.data() + prefix.size();
    const char* last = name.data() + name.size();
    if (const auto [end, error] = std::from_chars(first, last, index);
        error == std::errc() && end == last) {
      taken.push_back(index);
    }
  }
  std::sort(taken.begin(), taken.end());
  std::uint64_t index = 0;
  for (const std::uint64_t used : taken) {
    if (used == index) {
      ++index;
    } else if (used > index) {
      break;
    }
  }
  return index;
}

inline std::size_t reply_subscribers(const std::string& name, const std::string& namespace_name) {
  for (const TopicInfo& topic : list_topics(namespace_name)) {
    if (topic.name == name) {
      return topic.subscribers;
    }
  }
  return 0;
}

inline TopicOptions registration_options(TopicOptions options) {
  options.capacity = kRegistrationCapacity;
  return options;
}

/// Reply topic handles a server keeps open; past this many (clients alive at once) they are
/// re-opened.
inline constexpr std::size_t kMaxServerReplyTopics = 256;

/// The instance of the live server `current` registers, or NoServer (none registered) /
/// Transport (it crashed). Typed and raw clients share these verdicts and their texts.
inline ServiceResult<std::uint64_t> live_server_of(
    const std::optional<ServiceRegistration>& current, std::string_view service,
    std::string_view namespace_name) {
  if (!current || current->server_pid == 0) {
    return ServiceError::no_server("no server for " + std::string(service) + " in namespace " +
                                   std::string(namespace_name));
  }
  // A syscall on every call, not the /proc read of server_process_gone: a zombie server is
  // found out by the first check while waiting.
  if (!process_alive(static_cast<std::uint32_t>(current->server_pid))) {
    return ServiceError::transport("the server of " + std::string(service) + " (pid " +
                                   std::to_string(current->server_pid) + ") died");
  }
  return current->server_instance;
}

/// Why the server a request went to (`instance`) will never answer it (it crashed, stopped or
/// was replaced), if it won't; `current` is the latest registration.
inline std::optional<ServiceError> lost_server(const std::optional<ServiceRegistration>& current,
                                               std::uint64_t instance, std::string_view service) {
  const std::string name(service);
  if (!current || current->server_pid == 0) {
    return ServiceError::transport("the server of " + name + " stopped before answering");
  }
  if (current->server_instance != instance) {
    return ServiceError::transport("the server of " + name +
                                   " was restarted; the request was lost");
  }
  if (server_process_gone(current->server_pid)) {
    return ServiceError::transport("the server of " + name + " (pid " +
                                   std::to_string(current->server_pid) + ") died before answering");
  }
  return std::nullopt;
}

inline ServiceError no_answer_in_time(std::string_view service) {
  return ServiceError::timeout("no answer from " + std::string(service) + " in time");
}

/// Why a request topic refused a request.
inline ServiceError refused_request(std::string_view request_topic, bool oversized) {
  return ServiceError::transport(
      oversized ? "the request does not fit in a slot of " + std::string(request_topic) +
                      " (TopicOptions::max_message_size of its creator)"
                : "the request topic " + std::string(request_topic) +
                      " refused the message (a publisher stalled in its slot)");
}

/// The failure a server sends instead of a response its client's reply topic refused.
inline std::string oversized_response(std::string_view reply_topic) {
  return "the response does not fit in a slot of " + std::string(reply_topic) +
         " (TopicOptions::max_message_size of its creator)";
}

/// The error a response frame's status and text stand for; none for kStatusOk. A status this
/// runtime does not know is a failure of the server.
inline std::optional<ServiceError> error_of_status(std::uint32_t status, std::string text) {
  switch (status) {
    case kStatusOk:
      return std::nullopt;
    case kStatusNoServer:
      return ServiceError::no_server(std::move(text));
    case kStatusTimeout:
      return ServiceError::timeout(std::move(text));
    case kStatusTransport:
      return ServiceError::transport(std::move(text));
    default:
      return ServiceError::service_failed(std::move(text));
  }
}

/// The response frame status that carries `kind` to the caller.
constexpr std::uint32_t status_of(ServiceErrorKind kind) noexcept {
  switch (kind) {
    case ServiceErrorKind::NoServer:
      return kStatusNoServer;
    case ServiceErrorKind::Timeout:
      return kStatusTimeout;
    case ServiceErrorKind::Transport:
      return kStatusTransport;
    case ServiceErrorKind::ServiceFailed:
      break;
  }
  return kStatusFailed;
}

/// Opens (with `open(name)`) a reply topic of `response_topic` that no other live client
/// receives on, and its index. Threads of one process take turns; two processes that pick the
/// same index at the same moment both see it taken twice, and pick again after a random pause.
/// After a few collisions in a row the client shares the topic, which answers' client ids keep
/// correct.
template <class Open>
auto open_free_reply_topic(std::string_view response_topic, const std::string& namespace_name,
                           std::uint64_t& index, Open&& open) {
  static std::mutex picking;
  const std::lock_guard<std::mutex> lock(picking);
  for (int attempt = 0;; ++attempt) {
    index = free_reply_index(response_topic, namespace_name);
    const std::string name = reply_topic(response_topic, index);
    auto replies = open(name);
    // Marks the handle as a subscriber, so other clients see the index taken (and tools count
    // it). Nothing sent before it opened is visible: nothing of ours is discarded.
    if constexpr (requires { replies->try_recv(); }) {
      static_cast<void>(replies->try_recv());
    } else {
      static_cast<void>(replies.try_recv());
    }
    if (attempt >= kMaxReplyCollisions || reply_subscribers(name, namespace_name) <= 1) {
      return replies;
    }
    const auto noise =
        static_cast<std::uint64_t>(::getpid()) * 7919U +
        static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
    std::this_thread::sleep_for(
        std::chrono::microseconds(100 + static_cast<std::int64_t>(noise % 1900U)));
  }
}

/// Publishes `registered` (a new server's record, this process's pid) on `registration`, once
/// no live server is registered: typed and raw servers claim a service alike. Throws
/// horus::Error naming the live server, or when the record cannot be published.
inline void claim_registration(Topic<ServiceRegistration>& registration,
                               const ServiceRegistration& registered, std::string_view service,
                               std::string_view namespace_name) {
  const std::optional<ServiceRegistration> current = registration.read_latest();
  if (current && current->server_pid != 0 && !server_process_gone(current->server_pid)) {
    throw Error("service " + std::string(service) + " in namespace " + std::string(namespace_name) +
                " already has a server (pid " + std::to_string(current->server_pid) + ")");
  }
  if (!registration.send(registered)) {
    throw Error("service " + std::string(service) + ": cannot publish its registration");
  }
}

/// Withdraws `registered` if it is still the latest record: withdrawn, not erased, so tools
/// still list the service and its types, with no server, and waiting clients fail at once.
inline void withdraw_registration(Topic<ServiceRegistration>& registration,
                                  const ServiceRegistration& registered) {
  const std::optional<ServiceRegistration> current = registration.read_latest();
  if (current && current->server_instance == registered.server_instance) {
    ServiceRegistration withdrawn = registered;
    withdrawn.server_instance = 0;
    withdrawn.server_pid = 0;
    static_cast<void>(registration.send(withdrawn));
  }
}

/// The record of a new server of `service` in this process.
inline ServiceRegistration server_registration(std::uint64_t instance, std::uint64_t fingerprint,
                                               std::string_view request_type,
                                               std::string_view response_type) {
  ServiceRegistration registered{};
  registered.server_instance = instance;
  registered.fingerprint = fingerprint;
  registered.request_type.try_assign(request_type);
  registered.response_type.try_assign(response_type);
  registered.server_pid = static_cast<std::uint64_t>(::getpid());
  return registered;
}

/// One request on its way: what the caller needs to wait for its answer.
struct SentRequest {
  std::uint64_t request_id;
  std::uint64_t server_instance;
};

/// The frames of a typed service, as ServiceChannel sends and receives them for
/// ServiceClient<S> and AsyncServiceClient<S>. The other wire is the raw layer's bytes
/// (RawServiceWire, raw_service.cpp): one channel, so typed and raw clients behave alike.
template <Service S>
struct TypedServiceWire {
  using Request = typename S::Request;
  using Response = typename S::Response;
  /// What the reply topic delivers.
  using Answer = ServiceResponseFrame<Response>;
  using RequestTopic = Topic<ServiceRequestFrame<Request>>;
  using ReplyTopic = Topic<Answer>;

  std::string_view name() const noexcept { return S::name(); }
  std::string_view request_topic() const noexcept { return S::request_topic(); }
  std::string_view response_topic() const noexcept { return S::response_topic(); }
  std::string_view request_type_name() const noexcept { return S::request_type_name(); }
  std::string_view response_type_name() const noexcept { return S::response_type_name(); }

  RequestTopic open_requests(const TopicOptions& options) const {
    return RequestTopic(S::request_topic(), options);
  }
  ReplyTopic open_replies(const std::string& name, const TopicOptions& options) const {
    return ReplyTopic(name, options);
  }
  static std::uint64_t oversized(const RequestTopic& requests) noexcept {
    return requests.stats().oversized;
  }
  bool send(RequestTopic& requests, std::uint64_t client_id, std::uint64_t reply_to,
            std::uint64_t request_id, const Request& request) const {
    return requests.send(
        request_frame(client_id, reply_to, ServiceRequest<Request>{request_id, request}));
  }
  std::optional<Answer> recv(ReplyTopic& replies, std::chrono::nanoseconds timeout) const {
    return replies.recv(timeout);
  }
  std::optional<Answer> try_recv(ReplyTopic& replies) const { return replies.try_recv(); }
  static std::uint64_t client_of(const Answer& answer) noexcept { return answer.client_id; }
  static std::uint64_t request_of(const Answer& answer) noexcept { return answer.request_id; }
  static ServiceResult<Response> result_of(Answer&& answer) {
    const std::uint32_t status = answer.status;
    if (status == kStatusOk || status == kStatusFailed) {
      return response_of(std::move(answer)).into_result();
    }
    return *error_of_status(status, std::string(std::string_view(answer.error)));
  }
};

/// A client's three topic handles (request, reply, registration) and its pending calls, over
/// the frames of `Wire` (TypedServiceWire<S>, or the raw layer's bytes). Used by one thread at
/// a time, like a Topic.
template <class Wire>
class BasicServiceChannel {
 public:
  using Request = typename Wire::Request;
  using Response = typename Wire::Response;
  using Answer = typename Wire::Answer;
  using Clock = std::chrono::steady_clock;

  explicit BasicServiceChannel(const TopicOptions& options, Wire wire = Wire())
      : wire_(std::move(wire)),
        namespace_(options.namespace_name.empty() ? horus::current_namespace()
                                                  : options.namespace_name),
        requests_(wire_.open_requests(options)),
        replies_(open_free_reply_topic(
            wire_.response_topic(), namespace_, reply_index_,
            [&](const std::string& name) { return wire_.open_replies(name, options); })),
        registration_(service_registration_topic(wire_.name()), registration_options(options)),
        client_id_(new_service_endpoint_id()),
        announced_(ProcessUse{ProcessUse::Kind::ServiceClient, namespace_,
                              std::string(wire_.name()), std::string(wire_.request_type_name()),
                              std::string(wire_.response_type_name())}) {}

  const Wire& wire() const noexcept { return wire_; }
  std::uint64_t client_id() const noexcept { return client_id_; }

  /// The live server's instance, or NoServer (none registered) / Transport (it crashed).
  ServiceResult<std::uint64_t> live_server() {
    return live_server_of(registration_.read_latest(), wire_.name(), namespace_);
  }

  /// Waits (asleep on the registration topic) until a live server is registered.
  bool wait_for_server(std::chrono::nanoseconds timeout) {
    const Clock::time_point deadline = Clock::now() + timeout;
    for (;;) {
      if (live_server()) {
        return true;
      }
      const Clock::time_point now = Clock::now();
      if (now >= deadline) {
        return false;
      }
      // A crashed server's registration stays: re-check its pid now and then, not only on news.
      static_cast<void>(
          registration_.recv(std::min(deadline - now, Clock::duration(kServerCheckInterval))));
    }
  }

  /// Sends `request` to the live server. `track`: the answer is kept for take() (async calls).
  ServiceResult<SentRequest> send(const Request& request, bool track) {
    ServiceResult<std::uint64_t> server = live_server();
    if (!server) {
      return server.error();
    }
    const std::uint64_t request_id = ++last_request_id_;
    if (track) {
      pending_.emplace(request_id, std::nullopt);
    }
    const std::uint64_t oversized_before = Wire::oversized(requests_);
    bool sent = false;
    try {
      sent = wire_.send(requests_, client_id_, reply_index_, request_id, request);
    } catch (...) {
      forget(request_id);
      throw;
    }
    if (!sent) {
      forget(request_id);
      return refused_request(wire_.request_topic(), Wire::oversized(requests_) != oversized_before);
    }
    return SentRequest{request_id, *server};
  }

  /// Blocks until the answer to `sent` arrives (asleep on the reply topic's futex), the
  /// deadline passes, or the server is found gone.
  ServiceResult<Response> wait(const SentRequest& sent, Clock::time_point deadline) {
    Clock::time_point next_check = Clock::now() + kServerCheckInterval;
    for (;;) {
      const Clock::time_point now = Clock::now();
      if (now >= deadline) {
        forget(sent.request_id);
        return timeout_error();
      }
      if (std::optional<Answer> answer = take(sent.request_id)) {
        return to_result(std::move(*answer));
      }
      if (now >= next_check) {
        if (std::optional<ServiceError> lost = check_server(sent)) {
          forget(sent.request_id);
          return std::move(*lost);
        }
        next_check = now + kServerCheckInterval;
      }
      if (std::optional<Answer> answer =
              wire_.recv(replies_, std::min(deadline, next_check) - now)) {
        if (Wire::client_of(*answer) == client_id_ &&
            Wire::request_of(*answer) == sent.request_id) {
          forget(sent.request_id);
          return to_result(std::move(*answer));
        }
        route(std::move(*answer));
      }
    }
  }

  /// Files every answer that has arrived, without blocking.
  void drain() {
    while (std::optional<Answer> answer = wire_.try_recv(replies_)) {
      route(std::move(*answer));
    }
  }

  /// The answer to a tracked request, once it has been filed; the request is then forgotten.
  std::optional<Answer> take(std::uint64_t request_id) {
    const auto found = pending_.find(request_id);
    if (found == pending_.end() || !found->second) {
      return std::nullopt;
    }
    std::optional<Answer> answer = std::move(found->second);
    pending_.erase(found);
    return answer;
  }

  /// Stops tracking a request: an answer that comes later is stale and dropped.
  void forget(std::uint64_t request_id) { pending_.erase(request_id); }

  /// Why the server will never answer `sent` (it crashed, stopped or was replaced), if it won't.
  std::optional<ServiceError> check_server(const SentRequest& sent) {
    return lost_server(registration_.read_latest(), sent.server_instance, wire_.name());
  }

  ServiceError timeout_error() const { return no_answer_in_time(wire_.name()); }

  static ServiceResult<Response> to_result(Answer&& answer) {
    return Wire::result_of(std::move(answer));
  }

 private:
  void route(Answer&& answer) {
    if (Wire::client_of(answer) != client_id_) {
      return;
    }
    const auto found = pending_.find(Wire::request_of(answer));
    if (found != pending_.end() && !found->second) {
      found->second = std::move(answer);
    }
  }

  Wire wire_;
  std::string namespace_;
  typename Wire::RequestTopic requests_;
  std::uint64_t reply_index_ = 0;
  typename Wire::ReplyTopic replies_;
  Topic<ServiceRegistration> registration_;
  std::uint64_t client_id_;
  AnnouncedUse announced_;  // the client in this process's presence announcement
  std::uint64_t last_request_id_ = 0;
  /// Tracked (async) requests, with their answer once filed.
  std::unordered_map<std::uint64_t, std::optional<Answer>> pending_;
};

/// The channel of ServiceClient<S> and AsyncServiceClient<S>.
template <Service S>
using ServiceChannel = BasicServiceChannel<TypedServiceWire<S>>;

}  // namespace horus::detail
