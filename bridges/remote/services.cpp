#include "services.hpp"

#include <unistd.h>

#include <memory>
#include <span>
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

/// The kind a robot's caller gave up with, as the link carries it.
Kind kind_of(ServiceErrorKind failure) {
  switch (failure) {
    case ServiceErrorKind::NoServer:
      return Kind::NO_SERVER;
    case ServiceErrorKind::Timeout:
      return Kind::TIMEOUT;
    default:
      return Kind::TRANSPORT;
  }
}

}  // namespace

bool is_service_topic(const TopicInfo& info) { return is_service_type(info.type_name); }

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
    : caller_(service, request, std::move(response), namespace_name, " on the robot",
              [namespace_name](const TopicInfo& info) {
                return RawTopic::open_recorded(info, namespace_name);
              }) {}

kj::Promise<ServiceRelay::Outcome> ServiceRelay::call(std::vector<std::byte> frame,
                                                      std::chrono::milliseconds timeout) {
  auto outcome = std::make_shared<Outcome>();
  auto done = kj::newPromiseAndCrossThreadFulfiller<void>();
  // Shared: a std::function is copyable, the fulfiller is not.
  auto fulfiller =
      std::make_shared<kj::Own<kj::CrossThreadPromiseFulfiller<void>>>(kj::mv(done.fulfiller));
  caller_.call(std::move(frame), timeout,
               [outcome, fulfiller](bridge::LocalServiceCaller::Outcome called) {
                 outcome->response_type = std::move(called.response_type);
                 if (called.answer) {
                   outcome->answer = std::move(*called.answer);
                 } else {
                   outcome->kind = kind_of(called.answer.error().kind());
                   outcome->failure = called.answer.error().message();
                 }
                 (*fulfiller)->fulfill();
               });
  return done.promise.then([outcome]() { return std::move(*outcome); });
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
    info = bridge::reply_topic_info(service_, *response_, index);
  }
  if (!info) return nullptr;
  try {
    auto topic = RawTopic::open_recorded(*info, namespace_name_);
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
  if (watch_) watch_((*ids)[0], frame);
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
