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

inline TopicOptions registration_options(TopicOptions options) {
  options.capacity = kRegistrationCapacity;
  return options;
}

/// One request on its way: what the caller needs to wait for its answer.
struct SentRequest {
  std::uint64_t request_id;
  std::uint64_t server_instance;
};

/// A client's three topic handles (request, response, registration) and its pending calls.
/// Used by one thread at a time, like a Topic.
template <Service S>
class ServiceChannel {
 public:
  using Request = typename S::Request;
  using Response = typename S::Response;
  using RequestFrame = ServiceRequestFrame<Request>;
  using ResponseFrame = ServiceResponseFrame<Response>;
  using Clock = std::chrono::steady_clock;

  explicit ServiceChannel(const TopicOptions& options)
      : namespace_(options.namespace_name.empty() ? horus::current_namespace()
                                                  : options.namespace_name),
        requests_(S::request_topic(), options),
        responses_(open_reply_topic(options, namespace_, reply_index_)),
        registration_(registration_topic(S::name()), registration_options(options)),
        client_id_(new_service_endpoint_id()),
        announced_(ProcessUse{ProcessUse::Kind::ServiceClient, namespace_, std::string(S::name()),
                              std::string(S::request_type_name()),
                              std::string(S::response_type_name())}) {}

  std::uint64_t client_id() const noexcept { return client_id_; }

  /// The live server's instance, or NoServer (none registered) / Transport (it crashed).
  ServiceResult<std::uint64_t> live_server() {
    const std::optional<ServiceRegistration> current = registration_.read_latest();
    if (!current || current->server_pid == 0) {
      return ServiceError::no_server("no server for " + std::string(S::name()) + " in namespace " +
                                     namespace_);
    }
    // A syscall on every call, not the /proc read of server_process_gone: a zombie server is
    // found out by the first check while waiting.
    if (!process_alive(static_cast<std::uint32_t>(current->server_pid))) {
      return ServiceError::transport("the server of " + std::string(S::name()) + " (pid " +
                                     std::to_string(current->server_pid) + ") died");
    }
    return current->server_instance;
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
    const std::uint64_t oversized_before = requests_.stats().oversized;
    if (!requests_.send(request_frame(client_id_, reply_index_,
                                      ServiceRequest<Request>{request_id, request}))) {
      forget(request_id);
      return ServiceError::transport(
          requests_.stats().oversized != oversized_before
              ? "the request does not fit in a slot of " + std::string(S::request_topic()) +
                    " (TopicOptions::max_message_size of its creator)"
              : "the request topic " + std::string(S::request_topic()) +
                    " refused the message (a publisher stalled in its slot)");
    }
    return SentRequest{request_id, *server};
  }

  /// Blocks until the answer to `sent` arrives (asleep on the response topic's futex), the
  /// deadline passes, or the server is found gone.
  ServiceResult<Response> wait(const SentRequest& sent, Clock::time_point deadline) {
    Clock::time_point next_check = Clock::now() + kServerCheckInterval;
    for (;;) {
      const Clock::time_point now = Clock::now();
      if (now >= deadline) {
        forget(sent.request_id);
        return timeout_error();
      }
      if (std::optional<ResponseFrame> answer = take(sent.request_id)) {
        return to_result(std::move(*answer));
      }
      if (now >= next_check) {
        if (std::optional<ServiceError> lost = check_server(sent)) {
          forget(sent.request_id);
          return std::move(*lost);
        }
        next_check = now + kServerCheckInterval;
      }
      if (std::optional<ResponseFrame> frame =
              responses_.recv(std::min(deadline, next_check) - now)) {
        if (frame->client_id == client_id_ && frame->request_id == sent.request_id) {
          forget(sent.request_id);
          return to_result(std::move(*frame));
        }
        route(std::move(*frame));
      }
    }
  }

  /// Files every answer that has arrived, without blocking.
  void drain() {
    while (std::optional<ResponseFrame> frame = responses_.try_recv()) {
      route(std::move(*frame));
    }
  }

  /// The answer to a tracked request, once it has been filed; the request is then forgotten.
  std::optional<ResponseFrame> take(std::uint64_t request_id) {
    const auto found = pending_.find(request_id);
    if (found == pending_.end() || !found->second) {
      return std::nullopt;
    }
    std::optional<ResponseFrame> answer = std::move(found->second);
    pending_.erase(found);
    return answer;
  }

  /// Stops tracking a request: an answer that comes later is stale and dropped.
  void forget(std::uint64_t request_id) { pending_.erase(request_id); }

  /// Why the server will never answer `sent` (it crashed, stopped or was replaced), if it won't.
  std::optional<ServiceError> check_server(const SentRequest& sent) {
    const std::optional<ServiceRegistration> current = registration_.read_latest();
    const std::string service(S::name());
    if (!current || current->server_pid == 0) {
      return ServiceError::transport("the server of " + service + " stopped before answering");
    }
    if (current->server_instance != sent.server_instance) {
      return ServiceError::transport("the server of " + service +
                                     " was restarted; the request was lost");
    }
    if (server_process_gone(current->server_pid)) {
      return ServiceError::transport("the server of " + service + " (pid " +
                                     std::to_string(current->server_pid) +
                                     ") died before answering");
    }
    return std::nullopt;
  }

  ServiceError timeout_error() const {
    return ServiceError::timeout("no answer from " + std::string(S::name()) + " in time");
  }

  static ServiceResult<Response> to_result(ResponseFrame&& frame) {
    const auto text = [&frame] { return std::string(std::string_view(frame.error)); };
    switch (frame.status) {
      case kStatusNoServer:
        return ServiceError::no_server(text());
      case kStatusTimeout:
        return ServiceError::timeout(text());
      case kStatusTransport:
        return ServiceError::transport(text());
      default:
        return response_of(std::move(frame)).into_result();
    }
  }

 private:
  /// Opens a reply topic no other live client receives on. Threads of one process take turns;
  /// two processes that pick the same index at the same moment both see it taken twice, and
  /// pick again after a random pause. After a few collisions in a row the client shares the
  /// topic, which answers' client ids keep correct.
  static Topic<ResponseFrame> open_reply_topic(const TopicOptions& options,
                                               const std::string& namespace_name,
                                               std::uint64_t& index) {
    static std::mutex picking;
    const std::lock_guard<std::mutex> lock(picking);
    for (int attempt = 0;; ++attempt) {
      index = free_reply_index(S::response_topic(), namespace_name);
      const std::string name = reply_topic(S::response_topic(), index);
      Topic<ResponseFrame> replies(name, options);
      // Marks the handle as a subscriber, so other clients see the index taken (and tools count
      // it). Nothing sent before it opened is visible: nothing of ours is discarded.
      static_cast<void>(replies.try_recv());
      if (attempt >= kMaxReplyCollisions || reply_subscribers(name, namespace_name) <= 1) {
        return replies;
      }
      const auto noise = static_cast<std::uint64_t>(::getpid()) * 7919U +
                         static_cast<std::uint64_t>(Clock::now().time_since_epoch().count());
      std::this_thread::sleep_for(
          std::chrono::microseconds(100 + static_cast<std::int64_t>(noise % 1900U)));
    }
  }

  static std::size_t reply_subscribers(const std::string& name, const std::string& namespace_name) {
    for (const TopicInfo& topic : list_topics(namespace_name)) {
      if (topic.name == name) {
        return topic.subscribers;
      }
    }
    return 0;
  }

  void route(ResponseFrame&& frame) {
    if (frame.client_id != client_id_) {
      return;
    }
    const auto found = pending_.find(frame.request_id);
    if (found != pending_.end() && !found->second) {
      found->second = std::move(frame);
    }
  }

  std::string namespace_;
  Topic<RequestFrame> requests_;
  std::uint64_t reply_index_ = 0;
  Topic<ResponseFrame> responses_;
  Topic<ServiceRegistration> registration_;
  std::uint64_t client_id_;
  AnnouncedUse announced_;  // the client in this process's presence announcement
  std::uint64_t last_request_id_ = 0;
  /// Tracked (async) requests, with their answer once filed.
  std::unordered_map<std::uint64_t, std::optional<ResponseFrame>> pending_;
};

}  // namespace horus::detail
