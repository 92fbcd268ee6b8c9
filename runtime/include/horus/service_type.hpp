// horus::Service: what horus-gen generates for a service of a `.hsrv` file, and what service
// clients and servers are instantiated with.
#pragma once

#include <concepts>
#include <cstdint>
#include <string_view>

#include "horus/type_info.hpp"

namespace horus {

/// A generated service: its Request and Response messages (each POD or serialized) and its
/// identity. Requests travel on request_topic(), answers on response_topic().
template <class S>
concept Service = Message<typename S::Request> && Message<typename S::Response> && requires {
  { S::name() } -> std::convertible_to<std::string_view>;
  { S::request_topic() } -> std::convertible_to<std::string_view>;
  { S::response_topic() } -> std::convertible_to<std::string_view>;
  { S::request_type_name() } -> std::convertible_to<std::string_view>;
  { S::response_type_name() } -> std::convertible_to<std::string_view>;
  { S::fingerprint() } -> std::convertible_to<std::uint64_t>;
};

}  // namespace horus
