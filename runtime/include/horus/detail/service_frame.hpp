// The messages that carry a service over topics, hand-written in the shape horus-gen generates
// (not generated from a schema: they are templates over the service's own messages).
//
//   <Service>.request       ServiceRequestFrame<Request>    {client_id, request_id, reply_to,
//                                                            payload}
//   <Service>.response.<k>  ServiceResponseFrame<Response>  {client_id, request_id, status,
//                                                            error, payload}
//   <Service>.service       ServiceRegistration (horus/service_registration.hpp): the live server
//
// Each client receives on a reply topic of its own (`reply_to` = k, the smallest index no live
// client uses): on one shared response topic, a client preempted for a few milliseconds while
// others keep calling would find its answer overwritten by theirs. Indices are re-used, so the
// number of reply topics stays the number of clients alive at once; two clients that pick the
// same index at the same moment merely share a topic (answers carry the client id).
// The payload is the message itself, not its encoded bytes: a POD request or response makes a POD
// frame, copied straight into the slot (no MessagePack, no allocation), and a serialized one is
// encoded once, straight into the slot, as an element of the frame's MessagePack array. Each
// frame's type name and fingerprint derive from its payload's, so a client and a server that
// disagree on a service's types fail to open its topics with the transport's "another type" error;
// its type description is built from its payload's (detail/service_description.hpp).
// The wire format as a whole: runtime/src/service/README.md.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

#include "horus/detail/service_description.hpp"
#include "horus/detail/static_text.hpp"
#include "horus/fixed_string.hpp"
#include "horus/message.hpp"
#include "horus/msgpack.hpp"
#include "horus/service_message.hpp"
#include "horus/service_registration.hpp"

namespace horus::detail {

inline constexpr std::string_view kRequestFrameName = "horus.ServiceRequest<";
inline constexpr std::string_view kResponseFrameName = "horus.ServiceResponse<";
inline constexpr std::string_view kNameClose = ">";
inline constexpr std::string_view kSchemaOpen = "message ";
inline constexpr std::string_view kRequestFrameFields =
    " {\n  client_id: u64,\n  request_id: u64,\n  reply_to: u64,\n  payload: ";
inline constexpr std::string_view kResponseFrameFieldsPod =
    " {\n  client_id: u64,\n  request_id: u64,\n  status: u32,\n  error: string<236>,\n  payload: ";
inline constexpr std::string_view kResponseFrameFieldsSerialized =
    " {\n  client_id: u64,\n  request_id: u64,\n  status: u32,\n  error: String,\n  payload: ";
inline constexpr std::string_view kSchemaClose = ",\n}\n";

/// ServiceResponseFrame::status. A server answers Ok or Failed; a server that forwards calls to
/// another one (the DDS bridge's stand-in for a remote service) answers a call that found no
/// server there, or none in time, or lost its answer, with that kind, so the caller sees the
/// kind it would see calling the remote server itself.
inline constexpr std::uint32_t kStatusOk = 0;
inline constexpr std::uint32_t kStatusFailed = 1;
inline constexpr std::uint32_t kStatusNoServer = 2;
inline constexpr std::uint32_t kStatusTimeout = 3;
inline constexpr std::uint32_t kStatusTransport = 4;

/// The error text a POD response frame holds (sized so that the payload starts at byte 256).
inline constexpr std::size_t kPodErrorCapacity = 236;

/// A request on its way to the server. client_id 0 is no client: the server's own wake-up at
/// stop().
template <Message Req>
struct ServiceRequestFrame {
  std::uint64_t client_id{};
  std::uint64_t request_id{};
  /// Index of the client's reply topic (reply_topic()).
  std::uint64_t reply_to{};
  Req payload{};

  std::string log_summary() const {
    std::string out = "ServiceRequest{client_id: ";
    summary::append_field(out, client_id, "", "");
    out += ", request_id: ";
    summary::append_field(out, request_id, "", "");
    out += ", reply_to: ";
    summary::append_field(out, reply_to, "", "");
    out += ", payload: " + payload.log_summary() + "}";
    return out;
  }
  bool operator==(const ServiceRequestFrame&) const = default;
};

/// An answer, for every client to see; each keeps those with its client_id and pending request_id.
template <Message Res>
struct ServiceResponseFrame {
  /// Fixed-size for a POD response, so the frame stays POD; longer texts are cut (cut_error()).
  using ErrorText =
      std::conditional_t<TypeInfo<Res>::is_pod, FixedString<kPodErrorCapacity>, std::string>;

  std::uint64_t client_id{};
  std::uint64_t request_id{};
  std::uint32_t status{};
  ErrorText error{};
  Res payload{};

  std::string log_summary() const {
    std::string out = "ServiceResponse{client_id: ";
    summary::append_field(out, client_id, "", "");
    out += ", request_id: ";
    summary::append_field(out, request_id, "", "");
    out += status == kStatusOk ? ", ok, payload: " + payload.log_summary()
                               : ", failed: \"" + std::string(std::string_view(error)) + "\"";
    out += "}";
    return out;
  }
  bool operator==(const ServiceResponseFrame&) const = default;
};

/// Stores a handler's error text in a frame, cut at a UTF-8 character boundary when a POD frame
/// has no room for all of it.
template <Message Res>
void set_error(ServiceResponseFrame<Res>& frame, std::string_view text) {
  if constexpr (TypeInfo<Res>::is_pod) {
    std::size_t size = std::min(text.size(), kPodErrorCapacity);
    while (size > 0 && size < text.size() &&
           (static_cast<unsigned char>(text[size]) & 0xC0U) == 0x80U) {
      --size;
    }
    frame.error.try_assign(text.substr(0, size));
  } else {
    frame.error.assign(text);
  }
}

/// The frame that carries `request` from client `client_id`, to be answered on reply topic
/// `reply_to`.
template <Message Req>
ServiceRequestFrame<Req> request_frame(std::uint64_t client_id, std::uint64_t reply_to,
                                       ServiceRequest<Req> request) {
  return {client_id, request.request_id, reply_to, std::move(request.payload)};
}

/// The frame that carries `response` to client `client_id`. A POD frame holds a failure's text
/// cut to kPodErrorCapacity bytes.
template <Message Res>
ServiceResponseFrame<Res> response_frame(std::uint64_t client_id, ServiceResponse<Res> response) {
  ServiceResponseFrame<Res> frame{};
  frame.client_id = client_id;
  frame.request_id = response.request_id;
  if (response.ok && response.payload) {
    frame.status = kStatusOk;
    frame.payload = std::move(*response.payload);
  } else {
    frame.status = kStatusFailed;
    set_error(frame, response.error.value_or(std::string()));
  }
  return frame;
}

/// The response a frame carries.
template <Message Res>
ServiceResponse<Res> response_of(ServiceResponseFrame<Res>&& frame) {
  if (frame.status == kStatusOk) {
    return ServiceResponse<Res>::success(frame.request_id, std::move(frame.payload));
  }
  return ServiceResponse<Res>::failure(frame.request_id,
                                       std::string(std::string_view(frame.error)));
}

/// The reply topic number `index` of a service.
inline std::string reply_topic(std::string_view response_topic, std::uint64_t index) {
  return std::string(response_topic) + "." + std::to_string(index);
}

/// The description of the frames of `Payload` (TypeInfo<Frame>::description).
template <Message Payload, bool Response>
std::string frame_description() {
  return service_frame_description(TypeInfo<Payload>::name,
                                   std::string_view(TypeInfo<Payload>::description), Response);
}

/// The identity every frame's TypeInfo shares: a name and schema built from the payload's, so two
/// sides that disagree on the payload type disagree on the frame type too. The text is joined
/// here at compile time from the pieces service_frame_schema() joins at run time.
template <class Frame, Message Payload, bool Response, const std::string_view& NameOpen,
          const std::string_view& Fields>
struct FrameTypeInfo {
  using type = Frame;
  static constexpr std::string_view name =
      JoinedText<NameOpen, TypeInfo<Payload>::name, kNameClose>::value;
  static constexpr std::string_view package = "horus";
  static constexpr std::string_view schema =
      JoinedText<kSchemaOpen, name, Fields, TypeInfo<Payload>::name, kSchemaClose,
                 TypeInfo<Payload>::schema>::value;
  static constexpr std::uint64_t fingerprint = fnv1a(schema);
  static constexpr BuiltDescription<frame_description<Payload, Response>> description{};
  static constexpr bool is_pod = TypeInfo<Payload>::is_pod;
  static constexpr std::size_t size = sizeof(type);
  static constexpr std::size_t alignment = alignof(type);
  // Frames are never encoded with horus::encode: the topic copies them whole.
  static constexpr std::array<PaddingRange, 0> padding{};
};

}  // namespace horus::detail

template <horus::Message Req>
struct horus::TypeInfo<horus::detail::ServiceRequestFrame<Req>>
    : horus::detail::FrameTypeInfo<horus::detail::ServiceRequestFrame<Req>, Req, false,
                                   horus::detail::kRequestFrameName,
                                   horus::detail::kRequestFrameFields> {
  static constexpr std::size_t field_count = 4;

  template <class Msg, class Fn>
  static constexpr void visit(Msg& msg, Fn&& fn) {
    fn("client_id", msg.client_id);
    fn("request_id", msg.request_id);
    fn("reply_to", msg.reply_to);
    fn("payload", msg.payload);
  }
};

template <horus::Message Res>
struct horus::TypeInfo<horus::detail::ServiceResponseFrame<Res>>
    : horus::detail::FrameTypeInfo<
          horus::detail::ServiceResponseFrame<Res>, Res, true, horus::detail::kResponseFrameName,
          horus::TypeInfo<Res>::is_pod ? horus::detail::kResponseFrameFieldsPod
                                       : horus::detail::kResponseFrameFieldsSerialized> {
  static constexpr std::size_t field_count = 5;

  template <class Msg, class Fn>
  static constexpr void visit(Msg& msg, Fn&& fn) {
    fn("client_id", msg.client_id);
    fn("request_id", msg.request_id);
    fn("status", msg.status);
    fn("error", msg.error);
    fn("payload", msg.payload);
  }
};
