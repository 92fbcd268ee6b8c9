// Introspection of the services of a namespace, for tools (`horus service list`).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace horus {

struct ServiceInfo {
  std::string name;
  std::string request_type;
  std::string response_type;
  std::uint64_t fingerprint = 0;
  /// 1 while a live process serves it, 0 once the server stopped or died.
  std::size_t servers = 0;
  /// Pid of the live server (0 without one).
  std::uint32_t server_pid = 0;
  /// Live processes' clients (open ServiceClient / AsyncServiceClient handles).
  std::size_t clients = 0;
};

/// The services that ever had a server in a namespace (empty: the current one), sorted by name;
/// those whose server is gone have servers == 0.
std::vector<ServiceInfo> list_services(std::string_view namespace_name = {});

}  // namespace horus
