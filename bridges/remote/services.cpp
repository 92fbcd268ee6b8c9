#include "services.hpp"

#include <unistd.h>

#include <charconv>
#include <cstring>
#include <thread>
#include <utility>

#include "zero_message.hpp"

namespace horus::remote {

namespace {

using Kind = wire::CallFailure::Kind;

TopicOptions namespace_options(const std::string& namespace_name) {
  TopicOptions options;
  options.namespace_name = namespace_name;
  return options;
}

std::string response_topic(const std::string& service) { return service + ".response"; }

/// Why a failed call's caller is not answered: no reply topic, and no type to make it with.
constexpr const char* kUntold =
    " (its caller cannot be told: its reply topic does not exist, and the type of the response "
    "frames is not known here yet; `horus service call -I DIR`, the folder of the service's "
    "schema, opens the topic with it)";

/// The failure a robot's reason of `kind` stands for.
ServiceError failure_of(Kind kind, std::string text) {
  switch (kind) {
    case Kind::NO_SERVER:
      return ServiceError::no_server(std::move(text));
    case Kind::TIMEOUT:
      return ServiceError::timeout(std::move(text));
    default:
      return ServiceError::transport(std::move(text));
  }
}

}  // namespace

bool is_service_topic(const TopicInfo& info) { return is_service_type(info.type_name); }

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

std::vector<std::byte> failure_frame(const TopicInfo& frame_type, std::uint64_t client_id,
                                     std::uint64_t request_id, const ServiceError& failure) {
  const ServiceCaller caller{client_id, request_id, 0};
  if (frame_type.is_pod) {
    const std::vector<std::byte> zero(frame_type.max_message_size);
    return with_service_failure(zero, true, caller, failure);
  }
  return with_service_failure(zero_message(frame_type), false, caller, failure);
}

ServiceRelay::ServiceRelay(const std::string& service, const TopicInfo& request,
                           std::optional<TopicInfo> response, const std::string& namespace_name)
    : service_(service),
      namespace_(namespace_name),
      client_id_(new_service_endpoint_id()),
      reply_index_(free_service_reply_index(response_topic(service), namespace_name)),
      requests_(open_topic(request, namespace_name)),
      response_(response ? std::move(response) : reply_topic_type(service, namespace_name)),
      replies_(open_replies(response_)),
      registration_(service, namespace_options(namespace_name)),
      worker_([this] { work(); }) {}

ServiceRelay::~ServiceRelay() {
  stopping_.store(true);
  wake_.notify_one();
  worker_.join();
}

kj::Promise<ServiceRelay::Outcome> ServiceRelay::call(std::vector<std::byte> frame,
                                                      std::chrono::milliseconds timeout) {
  auto outcome = std::make_shared<Outcome>();
  auto done = kj::newPromiseAndCrossThreadFulfiller<void>();
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back(Job{std::move(frame), timeout, outcome, kj::mv(done.fulfiller)});
  }
  wake_.notify_one();
  return done.promise.then([outcome]() { return std::move(*outcome); });
}

std::unique_ptr<RawTopic> ServiceRelay::open_replies(const std::optional<TopicInfo>& frames) {
  if (!frames) return nullptr;
  TopicInfo reply = *frames;
  reply.name = service_reply_topic(response_topic(service_), reply_index_);
  return open_topic(reply, namespace_);
}

void ServiceRelay::work() {
  // A subscriber now: free_reply_index counts the index as taken.
  if (replies_) replies_->try_recv();
  for (;;) {
    Job job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stopping_.load() || !jobs_.empty(); });
      if (stopping_.load()) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    *job.outcome = ask(job);
    job.outcome->response_type = response_;
    job.done->fulfill();
  }
}

// The kinds and texts of a local client's, naming the robot.
std::optional<ServiceRelay::Outcome> ServiceRelay::server_missing(std::uint64_t instance) {
  const std::optional<ServiceRegistration> current = registration_.latest();
  if (!current || current->server_pid == 0) {
    return Outcome{{},
                   Kind::TRANSPORT,
                   "the server of " + service_ + " on the robot stopped before answering"};
  }
  if (current->server_instance != instance) {
    return Outcome{
        {},
        Kind::TRANSPORT,
        "the server of " + service_ + " on the robot was restarted; the request was lost"};
  }
  if (service_server_gone(current->server_pid)) {
    return Outcome{{},
                   Kind::TRANSPORT,
                   "the server of " + service_ + " on the robot (pid " +
                       std::to_string(current->server_pid) + ") died before answering"};
  }
  return std::nullopt;
}

ServiceRelay::Outcome ServiceRelay::ask(const Job& job) {
  const std::optional<ServiceRegistration> current = registration_.latest();
  if (!current || current->server_pid == 0) {
    return {{}, Kind::NO_SERVER, "no server for " + service_ + " on the robot"};
  }
  if (service_server_gone(current->server_pid)) {
    return {{},
            Kind::TRANSPORT,
            "the server of " + service_ + " on the robot (pid " +
                std::to_string(current->server_pid) + ") died"};
  }
  const std::uint64_t request_id = ++last_request_;
  const std::array<std::uint64_t, 3> ids{client_id_, request_id, reply_index_};
  if (!requests_->send(with_service_frame_ids(job.frame, requests_->type().is_pod, ids))) {
    return {
        {}, Kind::TRANSPORT, "the robot's request topic of " + service_ + " refused the request"};
  }
  const auto deadline = std::chrono::steady_clock::now() + job.timeout;
  for (;;) {
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline || stopping_.load()) {
      return {{},
              Kind::TIMEOUT,
              "no answer from " + service_ + " on the robot within " +
                  std::to_string(job.timeout.count()) + " ms"};
    }
    const auto wait =
        std::min<std::chrono::nanoseconds>(deadline - now, kServiceServerCheckInterval);
    if (!replies_) {
      // The server makes the reply topic as it answers, the answer then its newest message.
      if (std::optional<TopicInfo> made = reply_topic_type(service_, namespace_, reply_index_)) {
        response_ = std::move(made);
        replies_ = open_replies(response_);
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

std::optional<ServiceRelay::Outcome> ServiceRelay::answer(std::ptrdiff_t size,
                                                          std::uint64_t request_id) {
  if (size < 0) return std::nullopt;
  const std::span<std::byte> reply = replies_->received(static_cast<std::size_t>(size));
  const auto answered = service_frame_ids(reply, replies_->type().is_pod);
  if (!answered || (*answered)[0] != client_id_ || (*answered)[1] != request_id) {
    return std::nullopt;
  }
  return Outcome{std::vector<std::byte>(reply.begin(), reply.end()), Kind::NONE, {}};
}

ServiceMirror::ServiceMirror(wire::ServiceInfo::Reader info, const std::string& namespace_name,
                             std::chrono::milliseconds call_timeout)
    : service_(info.getName()),
      namespace_name_(namespace_name),
      call_timeout_ms_(static_cast<std::uint32_t>(call_timeout.count())),
      request_pod_(info.getRequest().getIsPod()),
      registration_(service_, namespace_options(namespace_name)),
      calls_(*this) {
  registered_.server_instance = new_service_endpoint_id();
  registered_.fingerprint = info.getFingerprint();
  registered_.request_type = std::string_view(info.getRequestType().cStr());
  registered_.response_type = std::string_view(info.getResponseType().cStr());
  registered_.server_pid = static_cast<std::uint64_t>(::getpid());
  registration_.publish(registered_);
  learn(info);
  if (std::optional<TopicInfo> frames = reply_topic_type(service_, namespace_name_)) {
    learn(*frames);
  }
}

void ServiceMirror::connect(std::optional<wire::Session::Client> session,
                            LimitedMessageStream* messages) {
  session_ = std::move(session);
  messages_ = messages;
  if (messages_ != nullptr && response_) messages_->make_room(response_->max_message_size);
}

void ServiceMirror::learn(wire::ServiceInfo::Reader info) {
  if (info.hasResponse()) learn(topic_info(info.getResponse()));
}

void ServiceMirror::learn(const TopicInfo& frames) {
  if (response_) return;
  response_ = frames;
  // Answers of this size arrive on the connection from now on.
  if (messages_ != nullptr) messages_->make_room(frames.max_message_size);
}

void ServiceMirror::held_back(bool dropped) {
  if (!counts_) return;
  counts_->sent.fetch_sub(1);
  if (dropped) counts_->dropped.fetch_add(1);
}

ServiceMirror::~ServiceMirror() noexcept(false) {
  // Withdrawn as a stopping server withdraws: local clients waiting on it fail at once.
  registration_.withdraw(registered_);
}

void ServiceMirror::taskFailed(kj::Exception&& exception) {
  say("a call of %s on the robot failed: %s", service_.c_str(), exception.getDescription().cStr());
}

void ServiceMirror::fail(const std::array<std::uint64_t, 3>& ids, const ServiceError& failure) {
  Reply* back = reply_topic(ids[2]);
  const char* untold = back != nullptr ? "" : kUntold;
  say("a call of %s on the robot failed: %s%s", service_.c_str(), failure.message().c_str(),
      untold);
  if (back == nullptr) return;
  try {
    back->topic->send(failure_frame(back->info, ids[0], ids[1], failure));
  } catch (const std::exception& e) {
    // A frame type without a description: the caller learns from its own timeout.
    say("cannot tell the caller of %s why its call failed: %s", service_.c_str(), e.what());
  }
}

ServiceMirror::Reply* ServiceMirror::reply_topic(std::uint64_t index) {
  if (const auto known = replies_.find(index); known != replies_.end()) return &known->second;
  std::optional<TopicInfo> info = reply_topic_type(service_, namespace_name_, index);
  if (!info && response_) {  // made as the server makes it when it answers
    info = response_;
    info->name = service_reply_topic(response_topic(service_), index);
  }
  if (!info) return nullptr;
  try {
    auto topic = open_topic(*info, namespace_name_);
    learn(*info);
    return &replies_.emplace(index, Reply{std::move(*info), std::move(topic)}).first->second;
  } catch (const std::exception& e) {
    say("cannot answer a call of %s: %s", service_.c_str(), e.what());
    return nullptr;
  }
}

kj::Promise<void> ServiceMirror::message(MessageContext context) {
  const capnp::Data::Reader data = context.getParams().getData();
  const std::span<const std::byte> frame(reinterpret_cast<const std::byte*>(data.begin()),
                                         data.size());
  const auto ids = service_frame_ids(frame, request_pod_);
  if (!ids) {
    held_back(true);
    say("a request of %s is not a request frame: dropped", service_.c_str());
    return kj::READY_NOW;
  }
  if ((*ids)[0] == 0) {  // a stopping server's wake-up
    held_back(false);
    return kj::READY_NOW;
  }
  if (!session_) {
    held_back(true);
    fail(*ids, ServiceError::transport("the link to the robot is down"));
    return kj::READY_NOW;
  }
  auto request = session_->callRequest();
  request.setService(service_);
  request.setRequest(data);
  // Without the type the robot finds it, and says it with the answer.
  if (const Reply* reply = reply_topic((*ids)[2])) {
    messages_->make_room(reply->topic->payload_capacity());
    describe(reply->info, request.initResponse());
  }
  // The local client's own timeout, when shorter, ends its wait sooner.
  request.setTimeoutMs(call_timeout_ms_);
  calls_.add(request.send().then(
      [this, ids = *ids](capnp::Response<wire::Session::CallResults>&& response) {
        if (response.hasResponseType()) learn(topic_info(response.getResponseType()));
        if (response.hasFailure() && response.getFailure().getKind() != Kind::NONE) {
          const auto failure = response.getFailure();
          fail(ids, failure_of(failure.getKind(), failure.getText().cStr()));
          return;
        }
        Reply* back = reply_topic(ids[2]);
        if (back == nullptr) {
          say("an answer of %s from the robot came without the type of its frames: dropped",
              service_.c_str());
          return;
        }
        const capnp::Data::Reader answer = response.getResponse();
        const std::array<std::uint64_t, 2> caller{ids[0], ids[1]};
        back->topic->send(with_service_frame_ids(
            std::span(reinterpret_cast<const std::byte*>(answer.begin()), answer.size()),
            back->topic->type().is_pod, caller));
      },
      [this, ids = *ids](kj::Exception&& failure) {
        fail(ids, ServiceError::transport((failure.getType() == kj::Exception::Type::DISCONNECTED
                                               ? "the link to the robot was lost: "
                                               : "the robot refused the call: ") +
                                          std::string(failure.getDescription().cStr())));
      }));
  return kj::READY_NOW;
}

}  // namespace horus::remote
