#include "services.hpp"

#include <algorithm>
#include <utility>

#include "horus/error.hpp"
#include "horus/json_string.hpp"
#include "horus/type_description.hpp"
#include "topic_feed.hpp"

namespace horus::view {

namespace {

/// The client's id and the reply topic are the caller's own (LocalServiceCaller's): a request
/// frame is made under none.
constexpr ServiceCaller kAnyCaller{};

std::string schema_object(const ChannelSchema& schema) {
  return "{\"encoding\":" + json_string(schema.encoding) +
         ",\"schemaName\":" + json_string(schema.schema_name) +
         ",\"schemaEncoding\":" + json_string(schema.schema_encoding) +
         ",\"schema\":" + json_string(schema.schema) + "}";
}

}  // namespace

TypeIdentity frame_payload_type(const TopicInfo& frames, const std::string& payload_name,
                                bool response) {
  TypeIdentity payload = service_payload_type(type_identity_of(frames), response);
  if (payload.name != payload_name) {
    throw Error("topic '" + frames.name + "' carries " + frames.type_name + ", not the " +
                (response ? "response" : "request") + " frames of " + payload_name);
  }
  return payload;
}

ViewService::ViewService(std::uint32_t id, const ServiceInfo& info, const TopicInfo& request_frames,
                         const std::optional<TopicInfo>& response_frames,
                         const std::string& namespace_name)
    : id_(id),
      info_(info),
      namespace_(namespace_name),
      request_frames_(frame_payload_type(request_frames, info.request_type, false), false),
      request_codec_(codec_for(request_frames_.payload_type(), info.name)) {
  if (response_frames) learn_response(*response_frames);
  caller_ = std::make_unique<bridge::LocalServiceCaller>(
      info.name, request_frames, response_frames, namespace_name, "",
      [namespace_name](const TopicInfo& topic) {
        return RawTopic::open_recorded(topic, namespace_name);
      });
}

void ViewService::learn_response(const TopicInfo& response_frames) {
  TypeIdentity payload = frame_payload_type(response_frames, info_.response_type, true);
  response_codec_ = codec_for(payload, info_.name);
  response_frames_.emplace(std::move(payload), true);
}

std::string ViewService::advertisement() const {
  // A response whose type no reply topic shows yet is named, with its schema left empty until
  // a call answers.
  const std::string response =
      response_codec_
          ? schema_object(response_codec_->schema())
          : "{\"encoding\":\"json\",\"schemaName\":" + json_string(info_.response_type) +
                ",\"schemaEncoding\":\"jsonschema\",\"schema\":\"\"}";
  return "{\"id\":" + std::to_string(id_) + ",\"name\":" + json_string(info_.name) +
         ",\"type\":" + json_string(info_.name) +
         ",\"request\":" + schema_object(request_codec_->schema()) + ",\"response\":" + response +
         "}";
}

kj::Promise<ViewService::Answer> ViewService::call(std::span<const std::byte> json_request,
                                                   std::chrono::milliseconds timeout) {
  std::vector<std::byte> payload;
  try {
    request_codec_->decode(json_request, payload);
  } catch (const CodecError& error) {
    return Answer{{},
                  std::string("the request is not a ") + info_.request_type + ": " + error.what()};
  }
  std::vector<std::byte> frame;
  try {
    frame = request_frames_.request(kAnyCaller, payload);
  } catch (const Error& error) {
    return Answer{{}, error.what()};
  }
  // The worker hands the outcome over; the event loop that called goes on with it.
  auto outcome = std::make_shared<std::optional<bridge::LocalServiceCaller::Outcome>>();
  auto answered = kj::newPromiseAndCrossThreadFulfiller<void>();
  auto fulfiller =
      std::make_shared<kj::Own<kj::CrossThreadPromiseFulfiller<void>>>(kj::mv(answered.fulfiller));
  caller_->call(std::move(frame), timeout,
                [outcome, fulfiller](bridge::LocalServiceCaller::Outcome done) {
                  outcome->emplace(std::move(done));
                  (*fulfiller)->fulfill();
                });
  return answered.promise.then(
      [self = shared_from_this(), outcome] { return self->answer(std::move(**outcome)); });
}

ViewService::Answer ViewService::answer(bridge::LocalServiceCaller::Outcome outcome) {
  if (!outcome.answer) return Answer{{}, outcome.answer.error().to_string()};
  try {
    if (!response_codec_) {
      if (!outcome.response_type) return Answer{{}, "the response's type is not known"};
      learn_response(*outcome.response_type);
    }
    const auto response = response_frames_->read_response(outcome.answer.value());
    if (!response) return Answer{{}, "the server's answer is not a response frame"};
    if (response->failure) return Answer{{}, response->failure->to_string()};
    Answer answer;
    response_codec_->encode(response->payload, answer.payload);
    return answer;
  } catch (const std::exception& error) {
    return Answer{{}, error.what()};
  }
}

}  // namespace horus::view
