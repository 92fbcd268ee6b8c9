// Services across the link. The frames a client and a server exchange (horus/raw_service.hpp)
// cross as they are; only their ids change hands: the robot's relay sends a
// peer's request to its server under the relay's own client id and reply topic, and the peer's
// mirror, a server in the peer's namespace, answers its local client under the client's ids.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "horus/bridge/service_relay.hpp"
#include "horus/raw_service.hpp"
#include "horus/raw_topic.hpp"
#include "horus/topic.hpp"
#include "link.hpp"

namespace horus::remote {

/// Whether a topic carries a service's frames or registration rather than messages of its own.
bool is_service_topic(const TopicInfo& info);

using bridge::reply_topic_type;

/// The response frame a server elsewhere would have sent to say it gave no answer: `failure`
/// of kind NoServer, Timeout or Transport (its text cut as a POD frame cuts it). `frame_type` is
/// the response frames' topic (its type description gives a serialized frame's payload, written
/// with every field zero; horus::TypeDescriptionError without one).
std::vector<std::byte> failure_frame(const TopicInfo& frame_type, std::uint64_t client_id,
                                     std::uint64_t request_id, const ServiceError& failure);

/// The robot's end of one service for one peer: bridge::LocalServiceCaller's frames, each call's
/// outcome a promise on the event loop that asked.
class ServiceRelay {
 public:
  /// The server's response frame, or why there is none (`kind` none: answered); the type of the
  /// response frames when known (always with an answer).
  struct Outcome {
    std::vector<std::byte> answer;
    wire::CallFailure::Kind kind = wire::CallFailure::Kind::NONE;
    std::string failure;
    std::optional<TopicInfo> response_type;
  };

  /// `response`: the type of the response frames, when the peer knows it.
  ServiceRelay(const std::string& service, const TopicInfo& request,
               std::optional<TopicInfo> response, const std::string& namespace_name);

  /// The server's response frame to `frame`, or why there is none.
  kj::Promise<Outcome> call(std::vector<std::byte> frame, std::chrono::milliseconds timeout);

 private:
  bridge::LocalServiceCaller caller_;
};

/// The peer's end of one of the robot's services: registered as its server in the local
/// namespace until the robot has no server for it any more (then withdrawn). A Forwarder streams
/// the local request frames into it. A call the robot's server did not answer is answered here
/// with the robot's reason and its kind (no server, timeout, transport); one that the link lost,
/// also while no connection to the robot is up, with a transport error naming the link. A
/// caller's reply topic that does not exist yet (`horus service call` leaves it to the server)
/// is made here, as a server makes it, with the type of the response frames, known from a typed
/// reply topic here, the robot's listing or the robot's answer.
class ServiceMirror final : public wire::Sink::Server, public kj::TaskSet::ErrorHandler {
 public:
  /// `call_timeout`: how long the robot waits for its server to answer each call.
  ServiceMirror(wire::ServiceInfo::Reader info, const std::string& namespace_name,
                std::chrono::milliseconds call_timeout);
  ~ServiceMirror() noexcept(false);

  /// The session calls go to from now on, and its connection's stream (raised to fit the
  /// answers); none while the connection is down.
  void connect(std::optional<wire::Session::Client> session, LimitedMessageStream* messages);
  /// Learns the type of the response frames from the robot's listing, when it has it.
  void learn(wire::ServiceInfo::Reader info);
  /// The counts of the Forwarder that streams the requests here: a request not passed on to the
  /// robot is taken back from its sent ones.
  void count_in(std::shared_ptr<StreamCounts> counts) { counts_ = std::move(counts); }
  /// Runs on each request frame passed on to the robot, with its caller's client id (the link
  /// notes who sent an action's goals).
  using RequestWatch =
      std::function<void(std::uint64_t client_id, std::span<const std::byte> frame)>;
  void watch_requests(RequestWatch watch) { watch_ = std::move(watch); }

  void taskFailed(kj::Exception&& exception) override;

 protected:
  kj::Promise<void> message(MessageContext context) override;

 private:
  /// A local client's reply topic, where its answers go.
  struct Reply {
    TopicInfo info;
    std::unique_ptr<RawTopic> topic;
  };
  /// The reply topic `index` (opened the first time, made when it does not exist and the type
  /// of the response frames is known), or none.
  Reply* reply_topic(std::uint64_t index);
  /// Answers the caller (`ids`: client, request, reply topic) with `failure`.
  void fail(const std::array<std::uint64_t, 3>& ids, const ServiceError& failure);
  void learn(const TopicInfo& frames);
  /// A request the robot was not asked: counted as dropped (or, not being a request, not at all)
  /// instead of sent.
  void held_back(bool dropped);

  std::optional<wire::Session::Client> session_;
  LimitedMessageStream* messages_ = nullptr;
  std::string service_;
  std::string namespace_name_;
  std::uint32_t call_timeout_ms_;
  bool request_pod_;
  ServiceRegistration registered_;
  ServiceRegistrationTopic registration_;
  /// The type of the response frames, once known.
  std::optional<TopicInfo> response_;
  std::shared_ptr<StreamCounts> counts_;
  RequestWatch watch_;
  std::map<std::uint64_t, Reply> replies_;
  kj::TaskSet calls_;
};

}  // namespace horus::remote
