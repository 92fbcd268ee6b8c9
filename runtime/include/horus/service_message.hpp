// horus::ServiceRequest<Req> and horus::ServiceResponse<Res>: a request and its answer as seed
// 004 names them, correlated by request_id. On the wire each travels inside a frame that adds
// what routing needs (which client, which reply topic: detail/service_frame.hpp); a server builds
// every answer as a ServiceResponse, and a client turns the one it receives into a
// ServiceResult.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>

#include "horus/service_error.hpp"
#include "horus/service_result.hpp"
#include "horus/type_info.hpp"

namespace horus {

template <Message Req>
struct ServiceRequest {
  /// Unique among the calls of one client (assigned by the client).
  std::uint64_t request_id{};
  Req payload{};

  bool operator==(const ServiceRequest&) const = default;
};

template <Message Res>
struct ServiceResponse {
  /// The request_id of the request answered.
  std::uint64_t request_id{};
  /// True when the request was handled: payload is set; otherwise error is.
  bool ok = false;
  std::optional<Res> payload;
  std::optional<std::string> error;

  static ServiceResponse success(std::uint64_t request_id, Res payload) {
    return ServiceResponse{request_id, true, std::move(payload), std::nullopt};
  }
  static ServiceResponse failure(std::uint64_t request_id, std::string error) {
    return ServiceResponse{request_id, false, std::nullopt, std::move(error)};
  }

  /// The payload, or ServiceFailed carrying the error text (also for a response that claims
  /// success without a payload: a malformed answer is a failure, not an empty value).
  ServiceResult<Res> into_result() && {
    if (ok && payload) {
      return std::move(*payload);
    }
    return ServiceError::service_failed(ok ? std::string("the response has no payload")
                                           : std::move(error).value_or(std::string()));
  }

  bool operator==(const ServiceResponse&) const = default;
};

}  // namespace horus
