// The byte-level services of horus/raw_service.hpp: the typed frames' layout computed at run
// time from a payload's identity; the client is the typed clients' channel over byte frames
// (detail::BasicServiceChannel<RawServiceWire>), the server claims, answers and withdraws as the
// typed one does (the helpers of detail/service_channel.hpp).
#include "horus/raw_service.hpp"

#include <algorithm>
#include <atomic>
#include <cstring>
#include <map>
#include <utility>

#include "horus/detail/service_channel.hpp"
#include "horus/detail/service_frame.hpp"
#include "horus/error.hpp"
#include "horus/presence.hpp"
#include "horus/type_description.hpp"

namespace horus {

namespace {

using Clock = std::chrono::steady_clock;

/// POD frames: the ids before the payload (request) or before the error text (response).
constexpr std::size_t kPodRequestHead = 3 * sizeof(std::uint64_t);
constexpr std::size_t kPodStatusAt = 2 * sizeof(std::uint64_t);
constexpr std::size_t kPodErrorAt = kPodStatusAt + sizeof(std::uint32_t);
constexpr std::size_t kPodResponseHead = kPodErrorAt + detail::kPodErrorCapacity;
static_assert(kPodResponseHead == 256, "a POD response's payload starts at byte 256");

constexpr std::size_t kRequestFields = 4;
constexpr std::size_t kResponseFields = 5;
constexpr std::uint8_t kFixArray = 0x90;

std::size_t aligned(std::size_t value, std::size_t alignment) {
  return (value + alignment - 1) / alignment * alignment;
}

std::span<const std::byte> bytes_of(std::string_view text) {
  return {reinterpret_cast<const std::byte*>(text.data()), text.size()};
}

// MessagePack, as much of it as a frame's head needs: unsigned integers and a str.
void put_unsigned(std::vector<std::byte>& out, std::uint64_t value) {
  const auto put_big_endian = [&out, value](std::uint8_t marker, int width) {
    out.push_back(std::byte{marker});
    for (int shift = (width - 1) * 8; shift >= 0; shift -= 8) {
      out.push_back(static_cast<std::byte>((value >> shift) & 0xffU));
    }
  };
  if (value <= 0x7f) {
    out.push_back(static_cast<std::byte>(value));
  } else if (value <= 0xff) {
    put_big_endian(0xcc, 1);
  } else if (value <= 0xffff) {
    put_big_endian(0xcd, 2);
  } else if (value <= 0xffffffffULL) {
    put_big_endian(0xce, 4);
  } else {
    put_big_endian(0xcf, 8);
  }
}

void put_text(std::vector<std::byte>& out, std::string_view text) {
  const std::size_t size = text.size();
  const auto put_size = [&out, size](std::uint8_t marker, int width) {
    out.push_back(std::byte{marker});
    for (int shift = (width - 1) * 8; shift >= 0; shift -= 8) {
      out.push_back(static_cast<std::byte>((size >> shift) & 0xffU));
    }
  };
  if (size < 32) {
    out.push_back(static_cast<std::byte>(0xa0U | size));
  } else if (size <= 0xff) {
    put_size(0xd9, 1);
  } else if (size <= 0xffff) {
    put_size(0xda, 2);
  } else {
    put_size(0xdb, 4);
  }
  const std::span<const std::byte> bytes = bytes_of(text);
  out.insert(out.end(), bytes.begin(), bytes.end());
}

/// Reads MessagePack elements off the front of a frame; any malformed element fails it.
class HeadReader {
 public:
  explicit HeadReader(std::span<const std::byte> bytes) : bytes_(bytes) {}

  bool array_of(std::size_t fields) {
    return at_ < bytes_.size() &&
           std::to_integer<std::uint8_t>(bytes_[at_++]) == (kFixArray | fields);
  }

  std::optional<std::uint64_t> unsigned_value() {
    if (at_ >= bytes_.size()) return std::nullopt;
    const auto first = std::to_integer<std::uint8_t>(bytes_[at_]);
    if (first <= 0x7f) {
      ++at_;
      return first;
    }
    const int width = first == 0xcc   ? 1
                      : first == 0xcd ? 2
                      : first == 0xce ? 4
                      : first == 0xcf ? 8
                                      : 0;
    if (width == 0) return std::nullopt;
    return big_endian(1, width);
  }

  std::optional<std::string_view> text() {
    if (at_ >= bytes_.size()) return std::nullopt;
    const auto first = std::to_integer<std::uint8_t>(bytes_[at_]);
    std::optional<std::uint64_t> size;
    if ((first & 0xe0U) == 0xa0U) {
      ++at_;
      size = first & 0x1fU;
    } else {
      const int width = first == 0xd9 ? 1 : first == 0xda ? 2 : first == 0xdb ? 4 : 0;
      if (width == 0) return std::nullopt;
      size = big_endian(1, width);
    }
    if (!size || *size > bytes_.size() - at_) return std::nullopt;
    const std::string_view out(reinterpret_cast<const char*>(bytes_.data() + at_), *size);
    at_ += *size;
    return out;
  }

  std::size_t offset() const noexcept { return at_; }
  std::span<const std::byte> rest() const noexcept { return bytes_.subspan(at_); }

 private:
  std::optional<std::uint64_t> big_endian(std::size_t skip, int width) {
    if (at_ + skip + static_cast<std::size_t>(width) > bytes_.size()) return std::nullopt;
    std::uint64_t value = 0;
    for (int i = 0; i < width; ++i) {
      value = (value << 8) | std::to_integer<std::uint8_t>(bytes_[at_ + skip + i]);
    }
    at_ += skip + static_cast<std::size_t>(width);
    return value;
  }

  std::span<const std::byte> bytes_;
  std::size_t at_ = 0;
};

template <class T>
T load(std::span<const std::byte> bytes, std::size_t at) {
  T value{};
  std::memcpy(&value, bytes.data() + at, sizeof value);
  return value;
}

template <class T>
void store(std::span<std::byte> bytes, std::size_t at, T value) {
  std::memcpy(bytes.data() + at, &value, sizeof value);
}

/// The error text of a POD frame: `text` cut at a character boundary to what the field holds.
void store_pod_error(std::span<std::byte> frame, std::string_view text) {
  std::size_t size = std::min(text.size(), detail::kPodErrorCapacity);
  while (size > 0 && size < text.size() &&
         (static_cast<unsigned char>(text[size]) & 0xC0U) == 0x80U) {
    --size;
  }
  std::memset(frame.data() + kPodErrorAt, 0, detail::kPodErrorCapacity);
  std::memcpy(frame.data() + kPodErrorAt, text.data(), size);
}

std::string load_pod_error(std::span<const std::byte> frame) {
  const std::string_view field(reinterpret_cast<const char*>(frame.data() + kPodErrorAt),
                               detail::kPodErrorCapacity);
  return std::string(field.substr(0, field.find('\0')));
}

/// A serialized response frame: [client_id, request_id, status, error, payload].
std::vector<std::byte> serialized_response(const ServiceCaller& caller, std::uint32_t status,
                                           std::string_view error,
                                           std::span<const std::byte> payload) {
  std::vector<std::byte> out{static_cast<std::byte>(kFixArray | kResponseFields)};
  put_unsigned(out, caller.client_id);
  put_unsigned(out, caller.request_id);
  put_unsigned(out, status);
  put_text(out, error);
  out.insert(out.end(), payload.begin(), payload.end());
  return out;
}

}  // namespace

TypeIdentity service_frame_type(const TypeIdentity& payload, bool response) {
  TypeIdentity frame;
  frame.name = detail::service_frame_name(payload.name, response);
  frame.schema =
      detail::service_frame_schema(payload.name, payload.schema, response, payload.is_pod);
  frame.fingerprint = detail::fnv1a(frame.schema);
  frame.is_pod = payload.is_pod;
  frame.description =
      detail::service_frame_description(payload.name, payload.description, response);
  if (payload.is_pod) {
    const std::size_t alignment = std::max<std::size_t>(payload.alignment, alignof(std::uint64_t));
    const std::size_t head = response ? kPodResponseHead : kPodRequestHead;
    frame.alignment = alignment;
    frame.size = aligned(aligned(head, payload.alignment) + payload.size, alignment);
  }
  return frame;
}

TypeIdentity service_payload_type(const TypeIdentity& frames, bool response) {
  const std::string_view prefix = response ? detail::kResponseFrameName : detail::kRequestFrameName;
  const std::string what = std::string(response ? "response" : "request") + " frames";
  if (!frames.name.starts_with(prefix) || !frames.name.ends_with('>') ||
      frames.name.size() <= prefix.size() + 1) {  // the prefix ends with '<'
    throw Error(frames.name + " is not a service's " + what);
  }
  const std::string payload_name =
      frames.name.substr(prefix.size(), frames.name.size() - prefix.size() - 1);
  // A frame's description is its payload's with the frame type appended as the root.
  TypeDescription description = TypeDescription::decode(frames.description);
  if (description.messages.empty() || description.messages.back().name != frames.name ||
      description.find_message(payload_name) == nullptr) {
    throw Error("the description of " + frames.name + " does not describe " + what + " of " +
                payload_name);
  }
  description.messages.pop_back();
  description.root = payload_name;
  const MessageType& message = description.message(payload_name);
  TypeIdentity payload;
  payload.name = message.name;
  payload.fingerprint = message.fingerprint;
  payload.schema = message.schema;
  payload.is_pod = message.is_pod;
  payload.size = message.is_pod ? message.size : 0;
  payload.alignment = message.is_pod ? std::max<std::size_t>(message.alignment, 1) : 1;
  payload.description = description.encode();
  if (service_frame_type(payload, response).fingerprint != frames.fingerprint) {
    throw Error(frames.name + " (fingerprint " + std::to_string(frames.fingerprint) +
                ") are not the " + what + " its description's " + payload_name + " makes");
  }
  return payload;
}

bool is_service_type(std::string_view type_name) noexcept {
  return type_name.starts_with(detail::kRequestFrameName) ||
         type_name.starts_with(detail::kResponseFrameName) ||
         type_name == TypeInfo<ServiceRegistration>::name;
}

ServiceFrameCodec::ServiceFrameCodec(TypeIdentity payload, bool response)
    : payload_(std::move(payload)), frame_(service_frame_type(payload_, response)) {
  if (payload_.is_pod) {
    if (payload_.size == 0 || payload_.alignment == 0) {
      throw Error("the service frame of " + payload_.name +
                  ": a POD payload needs its size and alignment");
    }
    payload_offset_ = aligned(response ? kPodResponseHead : kPodRequestHead, payload_.alignment);
  }
}

std::vector<std::byte> ServiceFrameCodec::request(const ServiceCaller& caller,
                                                  std::span<const std::byte> payload) const {
  if (payload_.is_pod) {
    if (payload.size() != payload_.size) {
      throw Error("a request of " + payload_.name + " is " + std::to_string(payload_.size) +
                  " bytes, not " + std::to_string(payload.size()));
    }
    std::vector<std::byte> frame(frame_.size);
    store(std::span(frame), 0, caller.client_id);
    store(std::span(frame), 8, caller.request_id);
    store(std::span(frame), 16, caller.reply_to);
    std::copy(payload.begin(), payload.end(),
              frame.begin() + static_cast<std::ptrdiff_t>(payload_offset_));
    return frame;
  }
  std::vector<std::byte> frame{static_cast<std::byte>(kFixArray | kRequestFields)};
  put_unsigned(frame, caller.client_id);
  put_unsigned(frame, caller.request_id);
  put_unsigned(frame, caller.reply_to);
  frame.insert(frame.end(), payload.begin(), payload.end());
  return frame;
}

std::vector<std::byte> ServiceFrameCodec::response(const ServiceCaller& caller,
                                                   std::span<const std::byte> payload) const {
  if (payload_.is_pod) {
    if (payload.size() != payload_.size) {
      throw Error("a response of " + payload_.name + " is " + std::to_string(payload_.size) +
                  " bytes, not " + std::to_string(payload.size()));
    }
    std::vector<std::byte> frame(frame_.size);
    store(std::span(frame), 0, caller.client_id);
    store(std::span(frame), 8, caller.request_id);
    store(std::span(frame), kPodStatusAt, detail::kStatusOk);
    std::copy(payload.begin(), payload.end(),
              frame.begin() + static_cast<std::ptrdiff_t>(payload_offset_));
    return frame;
  }
  return serialized_response(caller, detail::kStatusOk, {}, payload);
}

std::vector<std::byte> ServiceFrameCodec::failure(const ServiceCaller& caller,
                                                  const ServiceError& failure,
                                                  std::span<const std::byte> empty_payload) const {
  const std::uint32_t status = detail::status_of(failure.kind());
  if (payload_.is_pod) {
    std::vector<std::byte> frame(frame_.size);
    store(std::span(frame), 0, caller.client_id);
    store(std::span(frame), 8, caller.request_id);
    store(std::span(frame), kPodStatusAt, status);
    store_pod_error(frame, failure.message());
    return frame;
  }
  if (empty_payload.empty()) {
    throw Error("a failure of " + payload_.name +
                " needs the encoding of an empty response (RawServiceType::empty_response)");
  }
  return serialized_response(caller, status, failure.message(), empty_payload);
}

std::optional<RawRequestFrame> ServiceFrameCodec::read_request(
    std::span<const std::byte> frame) const {
  if (payload_.is_pod) {
    if (frame.size() != frame_.size) return std::nullopt;
    return RawRequestFrame{{load<std::uint64_t>(frame, 0), load<std::uint64_t>(frame, 8),
                            load<std::uint64_t>(frame, 16)},
                           frame.subspan(payload_offset_, payload_.size)};
  }
  HeadReader head(frame);
  if (!head.array_of(kRequestFields)) return std::nullopt;
  const auto client_id = head.unsigned_value();
  const auto request_id = client_id ? head.unsigned_value() : std::nullopt;
  const auto reply_to = request_id ? head.unsigned_value() : std::nullopt;
  if (!reply_to) return std::nullopt;
  return RawRequestFrame{{*client_id, *request_id, *reply_to}, head.rest()};
}

std::optional<RawResponseFrame> ServiceFrameCodec::read_response(
    std::span<const std::byte> frame) const {
  RawResponseFrame out;
  std::uint32_t status = 0;
  std::string error;
  if (payload_.is_pod) {
    if (frame.size() != frame_.size) return std::nullopt;
    out.client_id = load<std::uint64_t>(frame, 0);
    out.request_id = load<std::uint64_t>(frame, 8);
    status = load<std::uint32_t>(frame, kPodStatusAt);
    error = load_pod_error(frame);
    out.payload = frame.subspan(payload_offset_, payload_.size);
  } else {
    HeadReader head(frame);
    if (!head.array_of(kResponseFields)) return std::nullopt;
    const auto client_id = head.unsigned_value();
    const auto request_id = client_id ? head.unsigned_value() : std::nullopt;
    const auto status_value = request_id ? head.unsigned_value() : std::nullopt;
    const auto text = status_value ? head.text() : std::nullopt;
    if (!text) return std::nullopt;
    out.client_id = *client_id;
    out.request_id = *request_id;
    status = static_cast<std::uint32_t>(*status_value);
    error = std::string(*text);
    out.payload = head.rest();
  }
  out.status = status;
  out.failure = detail::error_of_status(status, std::move(error));
  return out;
}

std::optional<std::array<std::uint64_t, 3>> service_frame_ids(std::span<const std::byte> frame,
                                                              bool pod) {
  std::array<std::uint64_t, 3> ids{};
  if (pod) {
    if (frame.size() < kPodRequestHead) return std::nullopt;
    std::memcpy(ids.data(), frame.data(), kPodRequestHead);
    return ids;
  }
  if (frame.empty() || (std::to_integer<std::uint8_t>(frame[0]) & 0xf0U) != kFixArray) {
    return std::nullopt;
  }
  HeadReader head(frame.subspan(1));
  for (std::uint64_t& id : ids) {
    const auto value = head.unsigned_value();
    if (!value) return std::nullopt;
    id = *value;
  }
  return ids;
}

std::vector<std::byte> with_service_frame_ids(std::span<const std::byte> frame, bool pod,
                                              std::span<const std::uint64_t> ids) {
  if (pod) {
    std::vector<std::byte> out(frame.begin(), frame.end());
    std::memcpy(out.data(), ids.data(), std::min(ids.size_bytes(), out.size()));
    return out;
  }
  if (frame.empty()) return {};
  HeadReader head(frame.subspan(1));
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (!head.unsigned_value()) return {frame.begin(), frame.end()};
  }
  std::vector<std::byte> out{frame[0]};
  for (const std::uint64_t id : ids) put_unsigned(out, id);
  const std::span<const std::byte> rest = head.rest();
  out.insert(out.end(), rest.begin(), rest.end());
  return out;
}

std::vector<std::byte> with_service_failure(std::span<const std::byte> response_frame, bool pod,
                                            const ServiceCaller& caller,
                                            const ServiceError& failure) {
  const std::uint32_t status = detail::status_of(failure.kind());
  if (pod) {
    std::vector<std::byte> out(response_frame.begin(), response_frame.end());
    out.resize(std::max(out.size(), kPodResponseHead));
    store(std::span(out), 0, caller.client_id);
    store(std::span(out), 8, caller.request_id);
    store(std::span(out), kPodStatusAt, status);
    store_pod_error(out, failure.message());
    return out;
  }
  HeadReader head(response_frame);
  if (!head.array_of(kResponseFields) || !head.unsigned_value() || !head.unsigned_value() ||
      !head.unsigned_value() || !head.text()) {
    throw Error("not a response frame: cannot turn it into a failure");
  }
  return serialized_response(caller, status, failure.message(), head.rest());
}

std::string service_reply_topic(std::string_view response_topic, std::uint64_t index) {
  return detail::reply_topic(response_topic, index);
}

std::uint64_t free_service_reply_index(std::string_view response_topic,
                                       std::string_view namespace_name) {
  return detail::free_reply_index(response_topic, std::string(namespace_name));
}

std::uint64_t new_service_endpoint_id() noexcept { return detail::new_service_endpoint_id(); }

bool service_server_gone(std::uint64_t pid) noexcept { return detail::server_process_gone(pid); }

static_assert(kServiceServerCheckInterval == detail::kServerCheckInterval);

ServiceRegistrationTopic::ServiceRegistrationTopic(std::string_view service,
                                                   const TopicOptions& options)
    : topic_(service_registration_topic(service), detail::registration_options(options)) {}

std::optional<ServiceRegistration> ServiceRegistrationTopic::latest() const {
  return topic_.read_latest();
}

bool ServiceRegistrationTopic::publish(const ServiceRegistration& registration) {
  return topic_.send(registration);
}

void ServiceRegistrationTopic::withdraw(const ServiceRegistration& registered) {
  detail::withdraw_registration(topic_, registered);
}

void ServiceRegistrationTopic::wait(std::chrono::nanoseconds timeout) {
  static_cast<void>(topic_.recv(timeout));
}

namespace {

std::string namespace_of(const TopicOptions& options) {
  return options.namespace_name.empty() ? current_namespace() : options.namespace_name;
}

detail::ProcessUse use_of(detail::ProcessUse::Kind kind, const RawServiceType& type,
                          const TopicOptions& options) {
  return detail::ProcessUse{kind, options.namespace_name, type.name, type.request.name,
                            type.response.name};
}

}  // namespace

struct RawServiceServer::State {
  State(RawServiceType type_in, const TopicOptions& options_in)
      : type(std::move(type_in)),
        options(options_in),
        requests(type.request, false),
        responses(type.response, true),
        incoming(type.request_topic, requests.frame_type(), options),
        waker(type.request_topic, requests.frame_type(), options),
        registration(service_registration_topic(type.name), detail::registration_options(options)),
        announced(use_of(detail::ProcessUse::Kind::ServiceServer, type, options)) {
    if (!type.response.is_pod && type.empty_response.empty()) {
      throw Error("RawServiceServer(" + type.name +
                  "): a serialized response needs RawServiceType::empty_response");
    }
  }

  /// The handle on a client's reply topic, opened on its first answer; nullptr when it cannot be
  /// opened (the client then learns from its timeout).
  RawTopic* reply_topic(std::uint64_t index) noexcept {
    if (const auto found = replies.find(index); found != replies.end()) {
      return found->second.get();
    }
    try {
      if (replies.size() >= detail::kMaxServerReplyTopics) {
        replies.clear();
      }
      auto topic = std::make_unique<RawTopic>(service_reply_topic(type.response_topic, index),
                                              responses.frame_type(), options);
      return replies.emplace(index, std::move(topic)).first->second.get();
    } catch (...) {
      return nullptr;
    }
  }

  RawServiceType type;
  TopicOptions options;
  ServiceFrameCodec requests;
  ServiceFrameCodec responses;
  RawTopic incoming;                                           // the serving thread's
  RawTopic waker;                                              // stop()'s
  std::map<std::uint64_t, std::unique_ptr<RawTopic>> replies;  // the serving thread's
  Topic<ServiceRegistration> registration;
  ServiceRegistration registered{};
  detail::AnnouncedUse announced;
  std::atomic<bool> stopping{false};
  std::atomic<bool> withdrawn{false};
};

RawServiceServer::RawServiceServer(RawServiceType type, const TopicOptions& options)
    : state_(std::make_unique<State>(std::move(type), options)) {
  const RawServiceType& served = state_->type;
  state_->registered = detail::server_registration(new_service_endpoint_id(), served.fingerprint,
                                                   served.request.name, served.response.name);
  // The request handle is open already, so every request sent once this is visible reaches it.
  detail::claim_registration(state_->registration, state_->registered, served.name,
                             namespace_of(options));
}

RawServiceServer::~RawServiceServer() {
  stop();
  withdraw();
}

const RawServiceType& RawServiceServer::type() const noexcept { return state_->type; }

std::uint64_t RawServiceServer::instance() const noexcept {
  return state_->registered.server_instance;
}

std::optional<RawServiceServer::Request> RawServiceServer::next(std::chrono::nanoseconds timeout) {
  const Clock::time_point deadline = Clock::now() + timeout;
  while (!state_->stopping.load(std::memory_order_acquire)) {
    const Clock::time_point now = Clock::now();
    if (now >= deadline) {
      return std::nullopt;
    }
    const std::ptrdiff_t size = state_->incoming.recv(deadline - now);
    if (size < 0) {
      continue;
    }
    const std::optional<RawRequestFrame> frame =
        state_->requests.read_request(state_->incoming.received(static_cast<std::size_t>(size)));
    // client_id 0 is no client: stop()'s wake-up.
    if (frame && frame->caller.client_id != 0) {
      return Request{frame->caller, {frame->payload.begin(), frame->payload.end()}};
    }
  }
  return std::nullopt;
}

bool RawServiceServer::answer(const ServiceCaller& caller, std::span<const std::byte> payload,
                              const std::function<void()>& on_refused) {
  RawTopic* outgoing = state_->reply_topic(caller.reply_to);
  if (outgoing == nullptr) {
    if (on_refused) on_refused();
    return false;
  }
  if (outgoing->send(state_->responses.response(caller, payload))) {
    return true;
  }
  if (on_refused) on_refused();
  // Tell the client why instead of leaving it to time out: a failure always fits.
  static_cast<void>(
      fail(caller, ServiceError::service_failed(detail::oversized_response(outgoing->name()))));
  return false;
}

bool RawServiceServer::fail(const ServiceCaller& caller, const ServiceError& failure) {
  RawTopic* outgoing = state_->reply_topic(caller.reply_to);
  return outgoing != nullptr &&
         outgoing->send(state_->responses.failure(caller, failure, state_->type.empty_response));
}

void RawServiceServer::stop() noexcept {
  if (state_->stopping.exchange(true, std::memory_order_acq_rel)) {
    return;
  }
  try {
    const std::vector<std::byte> zeros(state_->type.request.is_pod ? state_->type.request.size : 0);
    static_cast<void>(state_->waker.send(state_->requests.request(
        ServiceCaller{}, state_->type.request.is_pod ? zeros : state_->type.empty_request)));
  } catch (...) {
    // No wake-up: a waiting next() returns at its timeout instead.
  }
}

void RawServiceServer::withdraw() noexcept {
  if (state_->withdrawn.exchange(true, std::memory_order_acq_rel)) {
    return;
  }
  try {
    detail::withdraw_registration(state_->registration, state_->registered);
  } catch (...) {
    // The registration stays; clients find its pid gone once this process ends.
  }
  state_->announced = detail::AnnouncedUse();
}

bool RawServiceServer::stopped() const noexcept {
  return state_->stopping.load(std::memory_order_acquire);
}

std::uint64_t RawServiceServer::lost_requests() const noexcept {
  return state_->incoming.stats().lost;
}

namespace {

/// The frames of a raw client: bytes in and out, through the codecs of its service's types.
class RawServiceWire {
 public:
  using Request = std::span<const std::byte>;
  using Response = std::vector<std::byte>;
  /// A response frame as it came: its ids and what it says.
  struct Answer {
    std::uint64_t client_id;
    std::uint64_t request_id;
    ServiceResult<Response> result;
  };
  using RequestTopic = std::unique_ptr<RawTopic>;
  using ReplyTopic = std::unique_ptr<RawTopic>;

  explicit RawServiceWire(RawServiceType type)
      : type_(std::move(type)), requests_(type_.request, false), responses_(type_.response, true) {}

  const RawServiceType& type() const noexcept { return type_; }
  std::string_view name() const noexcept { return type_.name; }
  std::string_view request_topic() const noexcept { return type_.request_topic; }
  std::string_view response_topic() const noexcept { return type_.response_topic; }
  std::string_view request_type_name() const noexcept { return type_.request.name; }
  std::string_view response_type_name() const noexcept { return type_.response.name; }

  RequestTopic open_requests(const TopicOptions& options) const {
    return std::make_unique<RawTopic>(type_.request_topic, requests_.frame_type(), options);
  }
  ReplyTopic open_replies(const std::string& name, const TopicOptions& options) const {
    return std::make_unique<RawTopic>(name, responses_.frame_type(), options);
  }
  static std::uint64_t oversized(const RequestTopic& requests) noexcept {
    return requests->stats().oversized;
  }
  bool send(RequestTopic& requests, std::uint64_t client_id, std::uint64_t reply_to,
            std::uint64_t request_id, Request request) const {
    return requests->send(
        requests_.request(ServiceCaller{client_id, request_id, reply_to}, request));
  }
  std::optional<Answer> recv(ReplyTopic& replies, std::chrono::nanoseconds timeout) const {
    return answer_of(*replies, replies->recv(timeout));
  }
  std::optional<Answer> try_recv(ReplyTopic& replies) const {
    return answer_of(*replies, replies->try_recv());
  }
  static std::uint64_t client_of(const Answer& answer) noexcept { return answer.client_id; }
  static std::uint64_t request_of(const Answer& answer) noexcept { return answer.request_id; }
  static ServiceResult<Response> result_of(Answer&& answer) { return std::move(answer.result); }

 private:
  /// The answer in the `size` bytes `replies` received; none for nothing, or bytes that are no
  /// frame of the type (they pass by, as others' answers do).
  std::optional<Answer> answer_of(RawTopic& replies, std::ptrdiff_t size) const {
    if (size < 0) return std::nullopt;
    std::optional<RawResponseFrame> frame =
        responses_.read_response(replies.received(static_cast<std::size_t>(size)));
    if (!frame) return std::nullopt;
    if (frame->failure) {
      return Answer{frame->client_id, frame->request_id, std::move(*frame->failure)};
    }
    return Answer{frame->client_id, frame->request_id,
                  Response(frame->payload.begin(), frame->payload.end())};
  }

  RawServiceType type_;
  ServiceFrameCodec requests_;
  ServiceFrameCodec responses_;
};

}  // namespace

/// The typed clients' channel, over byte frames.
struct RawServiceClient::State {
  State(RawServiceType type, const TopicOptions& options)
      : channel(options, RawServiceWire(std::move(type))) {}

  detail::BasicServiceChannel<RawServiceWire> channel;
};

RawServiceClient::RawServiceClient(RawServiceType type, const TopicOptions& options)
    : state_(std::make_unique<State>(std::move(type), options)) {}

RawServiceClient::~RawServiceClient() = default;

const RawServiceType& RawServiceClient::type() const noexcept {
  return state_->channel.wire().type();
}

std::uint64_t RawServiceClient::client_id() const noexcept { return state_->channel.client_id(); }

bool RawServiceClient::wait_for_server(std::chrono::nanoseconds timeout) {
  return state_->channel.wait_for_server(timeout);
}

ServiceResult<std::vector<std::byte>> RawServiceClient::call(std::span<const std::byte> request,
                                                             std::chrono::nanoseconds timeout) {
  const Clock::time_point deadline = Clock::now() + timeout;
  ServiceResult<detail::SentRequest> sent = state_->channel.send(request, false);
  if (!sent) {
    return sent.error();
  }
  return state_->channel.wait(*sent, deadline);
}

}  // namespace horus
