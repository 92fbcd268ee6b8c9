// Services with their messages as bytes: the seam that language bindings (Python's
// horus.ServiceClient / ServiceServer) and relays (the remote link, the DDS bridge) build on.
//
//   horus::RawServiceServer server(type);              // registers as the service's server
//   while (!server.stopped()) {                        // until stop() from another thread
//     if (auto request = server.next(250ms)) {         // a request's payload and its caller
//       server.answer(request->caller, handle(request->payload));  // or server.fail(...)
//     }
//   }
//   server.withdraw();
//   horus::RawServiceClient client(type);
//   horus::ServiceResult<std::vector<std::byte>> response = client.call(bytes, 100ms);
//
// A payload is a message's bytes as a horus::Topic of its type carries them: a POD message's
// exact bytes, a serialized one's MessagePack encoding. Both ends speak the frames of the typed
// ServiceClient<S> / ServiceServer<S>, so either side of a call may be typed, raw, C++ or Python.
// The wire format, in one place: runtime/src/service/README.md.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "horus/codec.hpp"
#include "horus/raw_topic.hpp"
#include "horus/service_error.hpp"
#include "horus/service_registration.hpp"
#include "horus/service_result.hpp"
#include "horus/service_type.hpp"
#include "horus/topic.hpp"

namespace horus {

/// A service known at run time: what a generated service class says about itself.
struct RawServiceType {
  std::string name;
  std::string request_topic;
  std::string response_topic;
  /// The service's fingerprint (over both messages' schemas), as its registration carries it.
  std::uint64_t fingerprint = 0;
  TypeIdentity request;
  TypeIdentity response;
  /// The encodings of a Request and a Response with every field at its default: the payloads
  /// of a stopping server's wake-up and of a failure's frame. Unused for POD messages (zero
  /// bytes of their size); a serialized one needs them, a serialized frame holding a whole,
  /// decodable message.
  std::vector<std::byte> empty_request;
  std::vector<std::byte> empty_response;
};

/// The RawServiceType of a generated service: what ServiceServer<S> serves with.
template <Service S>
RawServiceType raw_service_type() {
  const auto bytes_of = [](const auto& message) {
    const std::vector<std::uint8_t> encoded = encode(message);
    const auto* first = reinterpret_cast<const std::byte*>(encoded.data());
    return std::vector<std::byte>(first, first + encoded.size());
  };
  using Request = typename S::Request;
  using Response = typename S::Response;
  return {std::string(S::name()),
          std::string(S::request_topic()),
          std::string(S::response_topic()),
          S::fingerprint(),
          type_identity<Request>(),
          type_identity<Response>(),
          bytes_of(Request{}),
          bytes_of(Response{})};
}

/// Who sent a request, and where its answer goes.
struct ServiceCaller {
  std::uint64_t client_id = 0;
  std::uint64_t request_id = 0;
  /// The index of the caller's reply topic (service_reply_topic()).
  std::uint64_t reply_to = 0;

  bool operator==(const ServiceCaller&) const = default;
};

/// The frame type that carries requests (`response` false) or responses of `payload`: the type
/// of `<Service>.request` and `<Service>.response.<k>`, equal to the typed frames'.
TypeIdentity service_frame_type(const TypeIdentity& payload, bool response);

/// The payload type of a service's frames, read back from the frames' identity (a request
/// topic's, or a reply topic's as its segment records it): what service_frame_type() was given,
/// description included. Throws horus::Error naming `frames` when they are not a service's
/// request (`response` false) or response frames.
TypeIdentity service_payload_type(const TypeIdentity& frames, bool response);

/// Whether a topic of this type carries a service's frames or registrations rather than
/// messages of its own.
bool is_service_type(std::string_view type_name) noexcept;

/// A request frame taken apart; `payload` points into the frame.
struct RawRequestFrame {
  ServiceCaller caller;
  std::span<const std::byte> payload;
};

/// A response frame taken apart: the response's payload, or why there is none (ServiceFailed
/// with the handler's text, or the kind a forwarding server passed on). `payload` points into
/// the frame.
struct RawResponseFrame {
  std::uint64_t client_id = 0;
  std::uint64_t request_id = 0;
  /// The frame's status field as it came (0: answered), for tools that show it.
  std::uint32_t status = 0;
  std::optional<ServiceError> failure;
  std::span<const std::byte> payload;
};

/// Builds and reads the frames of one payload type (its requests' or its responses').
class ServiceFrameCodec {
 public:
  /// Throws horus::Error for a POD payload without a size.
  ServiceFrameCodec(TypeIdentity payload, bool response);

  const TypeIdentity& frame_type() const noexcept { return frame_; }
  const TypeIdentity& payload_type() const noexcept { return payload_; }

  /// A request frame; horus::Error when a POD payload is not exactly its type's size.
  std::vector<std::byte> request(const ServiceCaller& caller,
                                 std::span<const std::byte> payload) const;
  /// A response frame answering `caller` with `payload`.
  std::vector<std::byte> response(const ServiceCaller& caller,
                                  std::span<const std::byte> payload) const;
  /// A response frame that fails `caller`'s request with `failure` (its text cut at a character
  /// boundary to what a POD frame holds); `empty_payload` as RawServiceType::empty_response.
  std::vector<std::byte> failure(const ServiceCaller& caller, const ServiceError& failure,
                                 std::span<const std::byte> empty_payload) const;

  /// None when the bytes are not a frame of this type.
  std::optional<RawRequestFrame> read_request(std::span<const std::byte> frame) const;
  std::optional<RawResponseFrame> read_response(std::span<const std::byte> frame) const;

 private:
  TypeIdentity payload_;
  TypeIdentity frame_;
  std::size_t payload_offset_ = 0;  // POD frames
};

/// The first three ids of any frame without knowing its payload type (request: client,
/// request, reply topic; response: client, request, status); none when the bytes are not a
/// frame. `pod`: whether the frame type is POD.
std::optional<std::array<std::uint64_t, 3>> service_frame_ids(std::span<const std::byte> frame,
                                                              bool pod);
/// `frame` with its first ids replaced by `ids` (at most three; a response's status is not an
/// id: pass two).
std::vector<std::byte> with_service_frame_ids(std::span<const std::byte> frame, bool pod,
                                              std::span<const std::uint64_t> ids);
/// `response_frame` (any response frame of the type, e.g. one with every field zero) turned
/// into the answer that fails `caller`'s request with `failure`.
std::vector<std::byte> with_service_failure(std::span<const std::byte> response_frame, bool pod,
                                            const ServiceCaller& caller,
                                            const ServiceError& failure);

/// The name of reply topic `index` of the service whose responses go to `response_topic`.
std::string service_reply_topic(std::string_view response_topic, std::uint64_t index);
/// The smallest reply topic index that no live client of the service receives on.
std::uint64_t free_service_reply_index(std::string_view response_topic,
                                       std::string_view namespace_name = {});
/// A non-zero id for a client or server, unique among the live processes of the machine.
std::uint64_t new_service_endpoint_id() noexcept;
/// Whether the process of a registered server has exited (or is a zombie).
bool service_server_gone(std::uint64_t pid) noexcept;
/// How often a waiting call re-reads the registration: a server that crashes, stops or
/// restarts mid-call is reported this late at worst.
inline constexpr std::chrono::milliseconds kServiceServerCheckInterval{10};

/// A service's `<Service>.service` topic: the record of its live server (the latest one counts).
class ServiceRegistrationTopic {
 public:
  ServiceRegistrationTopic(std::string_view service, const TopicOptions& options = {});

  std::optional<ServiceRegistration> latest() const;
  bool publish(const ServiceRegistration& registration);
  /// Publishes `registered` with no server (pid and instance 0) if it is still the latest:
  /// tools keep listing the service and its types, and waiting clients fail at once.
  void withdraw(const ServiceRegistration& registered);
  /// Sleeps until a registration arrives or `timeout` passes.
  void wait(std::chrono::nanoseconds timeout);

 private:
  Topic<ServiceRegistration> topic_;
};

/// Serves a service: takes each request's payload and answers it with bytes. Registers as the
/// service's server on construction (horus::Error while another live server serves it) and
/// withdraws on stop() or destruction. next(), answer() and fail() belong to one thread (the
/// serving one); stop() may come from another.
class RawServiceServer {
 public:
  struct Request {
    ServiceCaller caller;
    std::vector<std::byte> payload;
  };

  explicit RawServiceServer(RawServiceType type, const TopicOptions& options = {});
  RawServiceServer(const RawServiceServer&) = delete;
  RawServiceServer& operator=(const RawServiceServer&) = delete;
  ~RawServiceServer();

  const RawServiceType& type() const noexcept;
  /// This server's instance in its registration.
  std::uint64_t instance() const noexcept;

  /// The next request, waiting up to `timeout` (asleep on the request topic); none when none
  /// came, or once stop() was called (which wakes a waiting next() at once).
  std::optional<Request> next(std::chrono::nanoseconds timeout);
  /// Answers `caller` with the response `payload`. False when the reply topic could not take it
  /// (too large: the caller is then told so as a ServiceFailed, or the topic cannot be opened).
  /// `on_refused` runs before the caller is told, so what it counts is seen by then.
  bool answer(const ServiceCaller& caller, std::span<const std::byte> payload,
              const std::function<void()>& on_refused = {});
  /// Answers `caller` with a failure: ServiceFailed for a handler's error, or the kind a call this
  /// server forwarded elsewhere got (NoServer, Timeout, Transport).
  bool fail(const ServiceCaller& caller, const ServiceError& failure);

  /// Stops serving: next() returns none from now on, a waiting one at once. Idempotent.
  void stop() noexcept;
  /// Withdraws the registration (idempotent; the destructor does it too): once the request in
  /// hand is answered, so its caller is not told the server stopped before answering.
  void withdraw() noexcept;
  bool stopped() const noexcept;
  /// Requests lost because more than the request topic's capacity queued up.
  std::uint64_t lost_requests() const noexcept;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// Calls a service with the request's payload and waits for the response's. Failures are
/// values: NoServer at once without a server, Transport when the server dies, stops or restarts
/// mid-call, Timeout, and ServiceFailed with the server's text. Used by one thread at a time.
class RawServiceClient {
 public:
  /// Opens the service's topics; horus::Error when they carry other types.
  explicit RawServiceClient(RawServiceType type, const TopicOptions& options = {});
  RawServiceClient(const RawServiceClient&) = delete;
  RawServiceClient& operator=(const RawServiceClient&) = delete;
  ~RawServiceClient();

  const RawServiceType& type() const noexcept;
  std::uint64_t client_id() const noexcept;

  ServiceResult<std::vector<std::byte>> call(std::span<const std::byte> request,
                                             std::chrono::nanoseconds timeout);
  /// Waits up to `timeout` for a live server; false if none came.
  bool wait_for_server(std::chrono::nanoseconds timeout);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace horus
