#include "horus/bridge/service_relay.hpp"

#include <algorithm>
#include <charconv>
#include <span>
#include <string_view>
#include <utility>

namespace horus::bridge {

namespace {

std::string response_topic(const std::string& service) { return service + ".response"; }

TopicOptions in_namespace(const std::string& namespace_name) {
  TopicOptions options;
  options.namespace_name = namespace_name;
  return options;
}

}  // namespace

std::optional<TopicInfo> reply_topic_type(const std::string& service,
                                          const std::string& namespace_name,
                                          std::optional<std::uint64_t> index) {
  const std::string prefix = response_topic(service) + ".";
  for (TopicInfo& info : list_topics(namespace_name)) {
    const std::string_view name = info.name;
    if (info.type_name.empty() || !info.error.empty() || !name.starts_with(prefix)) continue;
    const std::string_view suffix = name.substr(prefix.size());
    std::uint64_t number = 0;
    const auto [end, error] = std::from_chars(suffix.data(), suffix.data() + suffix.size(), number);
    if (error == std::errc() && end == suffix.data() + suffix.size() && !suffix.empty() &&
        (!index || *index == number)) {
      return std::move(info);
    }
  }
  return std::nullopt;
}

TopicInfo reply_topic_info(const std::string& service, TopicInfo frames, std::uint64_t index) {
  frames.name = service_reply_topic(response_topic(service), index);
  return frames;
}

class LocalServiceCaller::Calls {
 public:
  virtual ~Calls() = default;
  /// On the worker; `stopping` ends a wait it can end.
  virtual Outcome call(const std::vector<std::byte>& request, std::chrono::milliseconds timeout,
                       const std::atomic<bool>& stopping) = 0;
};

class LocalServiceCaller::PayloadCalls final : public Calls {
 public:
  PayloadCalls(RawServiceType type, const std::string& namespace_name)
      : client_(std::move(type), in_namespace(namespace_name)) {}

  Outcome call(const std::vector<std::byte>& request, std::chrono::milliseconds timeout,
               const std::atomic<bool>& /*stopping*/) override {
    return Outcome{client_.call(request, timeout), std::nullopt};
  }

 private:
  RawServiceClient client_;
};

// The frames of a far client, sent to the local server under this caller's client id and reply
// topic. Until the type of the response frames is known, the reply topic is the one the server
// makes as it answers, found the way `horus service call` finds it. The checks and texts are a
// local client's, naming the server's host.
class LocalServiceCaller::FrameCalls final : public Calls {
 public:
  FrameCalls(const std::string& service, const TopicInfo& request,
             std::optional<TopicInfo> response, const std::string& namespace_name,
             std::string where, TopicOpener open)
      : service_(service),
        where_(std::move(where)),
        namespace_(namespace_name),
        open_(std::move(open)),
        client_id_(new_service_endpoint_id()),
        reply_index_(free_service_reply_index(response_topic(service), namespace_name)),
        requests_(open_(request)),
        response_(response ? std::move(response) : reply_topic_type(service, namespace_name)),
        replies_(open_replies()),
        registration_(service, in_namespace(namespace_name)) {
    // A subscriber now: free_service_reply_index counts the index as taken.
    if (replies_) replies_->try_recv();
  }

  Outcome call(const std::vector<std::byte>& request, std::chrono::milliseconds timeout,
               const std::atomic<bool>& stopping) override {
    Outcome outcome{ask(request, timeout, stopping), std::nullopt};
    outcome.response_type = response_;
    return outcome;
  }

 private:
  ServiceResult<std::vector<std::byte>> ask(const std::vector<std::byte>& request,
                                            std::chrono::milliseconds timeout,
                                            const std::atomic<bool>& stopping) {
    const std::string served = service_ + where_;
    const std::optional<ServiceRegistration> current = registration_.latest();
    if (!current || current->server_pid == 0) {
      return ServiceError::no_server("no server for " + served);
    }
    if (service_server_gone(current->server_pid)) {
      return ServiceError::transport("the server of " + served + " (pid " +
                                     std::to_string(current->server_pid) + ") died");
    }
    const std::uint64_t request_id = ++last_request_;
    const std::array<std::uint64_t, 3> ids{client_id_, request_id, reply_index_};
    if (!requests_->send(with_service_frame_ids(request, requests_->type().is_pod, ids))) {
      return ServiceError::transport("the request topic of " + served + " refused the request");
    }
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const auto now = std::chrono::steady_clock::now();
      if (now >= deadline || stopping.load()) {
        return ServiceError::timeout("no answer from " + served + " within " +
                                     std::to_string(timeout.count()) + " ms");
      }
      const auto wait =
          std::min<std::chrono::nanoseconds>(deadline - now, kServiceServerCheckInterval);
      if (!replies_) {
        // The server makes the reply topic as it answers, the answer then its newest message.
        if (std::optional<TopicInfo> made = reply_topic_type(service_, namespace_, reply_index_)) {
          response_ = std::move(made);
          replies_ = open_replies();
          if (auto answered = answer(replies_->read_latest(), request_id)) {
            return std::move(*answered);
          }
        } else if (auto missing = server_missing(current->server_instance)) {
          return std::move(*missing);
        } else {
          std::this_thread::sleep_for(wait);
        }
        continue;
      }
      const std::ptrdiff_t size = replies_->recv(wait);
      if (size >= 0) {
        if (auto answered = answer(size, request_id)) return std::move(*answered);
      } else if (auto missing = server_missing(current->server_instance)) {
        return std::move(*missing);
      }
    }
  }

  /// The answer to `request_id` in the reply just received (`size` bytes), if it is one.
  std::optional<std::vector<std::byte>> answer(std::ptrdiff_t size, std::uint64_t request_id) {
    if (size < 0) return std::nullopt;
    const std::span<std::byte> reply = replies_->received(static_cast<std::size_t>(size));
    const auto answered = service_frame_ids(reply, replies_->type().is_pod);
    if (!answered || (*answered)[0] != client_id_ || (*answered)[1] != request_id) {
      return std::nullopt;
    }
    return std::vector<std::byte>(reply.begin(), reply.end());
  }

  /// Why the server that had the request (`instance`) will not answer it, if it will not.
  std::optional<ServiceError> server_missing(std::uint64_t instance) {
    const std::string served = service_ + where_;
    const std::optional<ServiceRegistration> current = registration_.latest();
    if (!current || current->server_pid == 0) {
      return ServiceError::transport("the server of " + served + " stopped before answering");
    }
    if (current->server_instance != instance) {
      return ServiceError::transport("the server of " + served +
                                     " was restarted; the request was lost");
    }
    if (service_server_gone(current->server_pid)) {
      return ServiceError::transport("the server of " + served + " (pid " +
                                     std::to_string(current->server_pid) +
                                     ") died before answering");
    }
    return std::nullopt;
  }

  /// This caller's reply topic, with the type of the response frames; none while unknown.
  std::unique_ptr<RawTopic> open_replies() {
    if (!response_) return nullptr;
    return open_(reply_topic_info(service_, *response_, reply_index_));
  }

  std::string service_;
  std::string where_;
  std::string namespace_;
  TopicOpener open_;
  std::uint64_t client_id_;
  std::uint64_t reply_index_;
  std::unique_ptr<RawTopic> requests_;
  /// The type of the response frames, once known; the reply topic, open from then on.
  std::optional<TopicInfo> response_;
  std::unique_ptr<RawTopic> replies_;
  ServiceRegistrationTopic registration_;
  std::uint64_t last_request_ = 0;
};

LocalServiceCaller::LocalServiceCaller(RawServiceType type, const std::string& namespace_name)
    : calls_(std::make_unique<PayloadCalls>(std::move(type), namespace_name)),
      worker_([this] { work(); }) {}

LocalServiceCaller::LocalServiceCaller(const std::string& service, const TopicInfo& request,
                                       std::optional<TopicInfo> response,
                                       const std::string& namespace_name, std::string where,
                                       TopicOpener open)
    : calls_(std::make_unique<FrameCalls>(service, request, std::move(response), namespace_name,
                                          std::move(where), std::move(open))),
      worker_([this] { work(); }) {}

LocalServiceCaller::~LocalServiceCaller() {
  stopping_.store(true);
  wake_.notify_one();
  worker_.join();
}

void LocalServiceCaller::call(std::vector<std::byte> request, std::chrono::milliseconds timeout,
                              Done done) {
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back(Job{std::move(request), timeout, std::move(done)});
  }
  wake_.notify_one();
}

void LocalServiceCaller::work() {
  for (;;) {
    Job job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stopping_.load() || !jobs_.empty(); });
      if (stopping_.load()) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    job.done(calls_->call(job.request, job.timeout, stopping_));
  }
}

}  // namespace horus::bridge
