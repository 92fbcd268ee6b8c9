// horus::ServiceError: why a service call produced no response.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>

namespace horus {

enum class ServiceErrorKind : std::uint8_t {
  /// No answer within the timeout. Transient: the server may only be busy.
  Timeout,
  /// The server's handler returned an error (or threw); message() is its text.
  ServiceFailed,
  /// No server is registered for the service in the namespace.
  NoServer,
  /// The request or its answer was lost: the server crashed, stopped or restarted before
  /// answering, or a topic refused the message. Transient: a restarted server may answer.
  Transport,
};

/// The name of a kind, as in the specification: "Timeout", "ServiceFailed", "NoServer",
/// "Transport".
constexpr std::string_view to_string(ServiceErrorKind kind) noexcept {
  switch (kind) {
    case ServiceErrorKind::Timeout:
      return "Timeout";
    case ServiceErrorKind::ServiceFailed:
      return "ServiceFailed";
    case ServiceErrorKind::NoServer:
      return "NoServer";
    case ServiceErrorKind::Transport:
      return "Transport";
  }
  return "Unknown";
}

class ServiceError {
 public:
  using Kind = ServiceErrorKind;

  static ServiceError timeout(std::string detail = {}) {
    return {Kind::Timeout, std::move(detail)};
  }
  static ServiceError service_failed(std::string message) {
    return {Kind::ServiceFailed, std::move(message)};
  }
  static ServiceError no_server(std::string detail = {}) {
    return {Kind::NoServer, std::move(detail)};
  }
  static ServiceError transport(std::string message) {
    return {Kind::Transport, std::move(message)};
  }

  Kind kind() const noexcept { return kind_; }
  /// The handler's text for ServiceFailed, what went wrong for the other kinds (may be empty).
  const std::string& message() const noexcept { return message_; }
  /// Whether a retry may succeed: Timeout and Transport. call_resilient() retries only these.
  bool is_transient() const noexcept { return kind_ == Kind::Timeout || kind_ == Kind::Transport; }
  /// "Kind" or "Kind: message", for logs.
  std::string to_string() const {
    std::string text(horus::to_string(kind_));
    if (!message_.empty()) {
      text += ": ";
      text += message_;
    }
    return text;
  }

  bool operator==(const ServiceError&) const = default;

 private:
  ServiceError(Kind kind, std::string message) : kind_(kind), message_(std::move(message)) {}

  Kind kind_;
  std::string message_;
};

}  // namespace horus
