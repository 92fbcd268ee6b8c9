// The namespace's services as the live view offers them to clients (advertiseServices,
// serviceCallRequest): each call's JSON request made into a request frame, sent to the live
// server through the core's LocalServiceCaller (a worker thread per service, so the event loop
// never waits), and the server's response frame made back into JSON.
#pragma once

#include <kj/async.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "horus/bridge/service_relay.hpp"
#include "horus/raw_service.hpp"
#include "horus/service_registry.hpp"
#include "horus/topic_registry.hpp"
#include "horus/view/codecs.hpp"

namespace horus::view {

/// The payload type of the frames of a service frame topic (`frames`: its TopicInfo, whose type is
/// horus.ServiceRequest<X> or horus.ServiceResponse<X>), read from the schema and description
/// the segment records. Throws horus::Error (or TypeDescriptionError) when they do not read as
/// the frames of `payload_name`.
TypeIdentity frame_payload_type(const TopicInfo& frames, const std::string& payload_name,
                                bool response);

/// One service of the namespace, offered to clients.
class ViewService : public std::enable_shared_from_this<ViewService> {
 public:
  /// A call's outcome: the response's JSON payload, or why there is none.
  struct Answer {
    std::vector<std::byte> payload;
    std::optional<std::string> failure;
  };

  /// `request_frames`: the service's request topic; `response_frames`: a reply topic, when one
  /// exists (else the response's type is learned from the first answer). Throws when the
  /// request's type cannot be read or shown (horus::Error, CodecError).
  ViewService(std::uint32_t id, const ServiceInfo& info, const TopicInfo& request_frames,
              const std::optional<TopicInfo>& response_frames, const std::string& namespace_name);

  std::uint32_t id() const noexcept { return id_; }
  const ServiceInfo& info() const noexcept { return info_; }
  /// The advertiseServices entry of this service.
  std::string advertisement() const;
  /// Calls the service with a JSON request; resolves on the event loop that called (the
  /// promise keeps this service alive).
  kj::Promise<Answer> call(std::span<const std::byte> json_request,
                           std::chrono::milliseconds timeout);

 private:
  /// Learns the response's type from its frames' topic.
  void learn_response(const TopicInfo& response_frames);
  Answer answer(bridge::LocalServiceCaller::Outcome outcome);

  std::uint32_t id_;
  ServiceInfo info_;
  std::string namespace_;
  ServiceFrameCodec request_frames_;
  std::unique_ptr<MessageCodec> request_codec_;
  std::optional<ServiceFrameCodec> response_frames_;
  std::unique_ptr<MessageCodec> response_codec_;
  /// Last: its worker ends before what an answer uses.
  std::unique_ptr<bridge::LocalServiceCaller> caller_;
};

}  // namespace horus::view
