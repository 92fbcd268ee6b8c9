// horus::ServiceRegistration: the record a service's server publishes on `<Service>.service`
// (the latest one counts), read by its clients before and while they call, and by tools.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "horus/detail/service_description.hpp"
#include "horus/detail/static_text.hpp"
#include "horus/fixed_string.hpp"
#include "horus/log_summary.hpp"
#include "horus/type_info.hpp"

namespace horus {

/// The server of a service. server_pid 0: the server stopped and withdrew.
struct ServiceRegistration {
  /// Unique per server object: tells a restarted server from the one a request went to.
  std::uint64_t server_instance{};
  std::uint64_t fingerprint{};
  FixedString<256> request_type{};
  FixedString<256> response_type{};
  std::uint64_t server_pid{};

  std::string log_summary() const {
    std::string out = "ServiceRegistration{server_instance: ";
    summary::append_field(out, server_instance, "", "");
    out += ", fingerprint: ";
    summary::append_field(out, fingerprint, "", "");
    out += ", request_type: ";
    summary::append_field(out, request_type, "", "");
    out += ", response_type: ";
    summary::append_field(out, response_type, "", "");
    out += ", server_pid: ";
    summary::append_field(out, server_pid, "", "");
    out += "}";
    return out;
  }
  bool operator==(const ServiceRegistration&) const = default;
};

inline constexpr std::string_view kServiceRegistrationSuffix = ".service";

/// The topic that holds a service's registration.
inline std::string service_registration_topic(std::string_view service_name) {
  return std::string(service_name) + std::string(kServiceRegistrationSuffix);
}

}  // namespace horus

template <>
struct horus::TypeInfo<horus::ServiceRegistration> {
  using type = horus::ServiceRegistration;
  static constexpr std::string_view name = "horus.ServiceRegistration";
  static constexpr std::string_view package = "horus";
  static constexpr std::string_view schema =
      "message horus.ServiceRegistration {\n"
      "  server_instance: u64,\n"
      "  fingerprint: u64,\n"
      "  request_type: string<256>,\n"
      "  response_type: string<256>,\n"
      "  server_pid: u64,\n"
      "}\n";
  static constexpr std::uint64_t fingerprint = horus::detail::fnv1a(schema);
  static constexpr horus::detail::BuiltDescription<horus::detail::service_registration_description>
      description{};
  static constexpr bool is_pod = true;
  static constexpr std::size_t size = sizeof(type);
  static constexpr std::size_t alignment = alignof(type);
  static constexpr std::size_t field_count = 5;
  static constexpr std::array<horus::PaddingRange, 0> padding{};

  template <class Msg, class Fn>
  static constexpr void visit(Msg& msg, Fn&& fn) {
    fn("server_instance", msg.server_instance);
    fn("fingerprint", msg.fingerprint);
    fn("request_type", msg.request_type);
    fn("response_type", msg.response_type);
    fn("server_pid", msg.server_pid);
  }
};

static_assert(sizeof(horus::ServiceRegistration) == 536 &&
                  offsetof(horus::ServiceRegistration, server_pid) == 528,
              "horus.ServiceRegistration has no padding: its layout is shared between processes");
