// SchedulerConfig::view(): the options checked, and the live view started through the factory
// horus::view registers (README.md).
#include <arpa/inet.h>

#include <string>

#include "horus/error.hpp"
#include "horus/live_view_options.hpp"

namespace horus::detail {

bool is_loopback_address(const std::string& address) {
  if (address == "localhost") return true;
  in_addr v4{};
  if (::inet_pton(AF_INET, address.c_str(), &v4) == 1) {
    return (ntohl(v4.s_addr) >> 24) == 127;
  }
  in6_addr v6{};
  return ::inet_pton(AF_INET6, address.c_str(), &v6) == 1 && IN6_IS_ADDR_LOOPBACK(&v6);
}

void check_live_view(const LiveViewOptions& options) {
  if (options.listen_address.empty()) {
    throw Error(
        "listen_address is empty: give an address of this machine (127.0.0.1 serves "
        "this machine only)");
  }
  if (options.discovery_interval.count() < 1) {
    throw Error("discovery_interval must be at least 1 ms, got " +
                std::to_string(options.discovery_interval.count()) + " ms");
  }
  const bool tls = !options.tls_folder.empty();
  if (tls != !options.tls_name.empty()) {
    throw Error(
        "tls_folder and tls_name go together (--tls DIR --name NAME: DIR/NAME.crt and "
        "DIR/NAME.key served, DIR/ca.crt trusted)");
  }
  const bool policy = !options.policy_lines.empty() || !options.policy_files.empty();
  if (!is_loopback_address(options.listen_address) && (!tls || !policy)) {
    // Everyone who reaches a wider address would read and publish every topic, in clear.
    std::string missing;
    if (!tls) {
      missing = "--tls DIR --name NAME (tls_folder, tls_name: horus remote keygen's certificates)";
    }
    if (!policy) {
      if (!missing.empty()) missing += " and ";
      missing +=
          "--allow 'PEER read|write|call|param PATTERN' or --policy FILE (policy_lines, "
          "policy_files) "
          "with --tokens FILE (tokens_file) or client certificates";
    }
    throw Error("listening on " + options.listen_address +
                " serves beyond this machine and needs TLS and a policy: add " + missing);
  }
  if (!options.tokens_file.empty() && !policy) {
    throw Error(
        "tokens_file (--tokens) names peers for a policy, and there is none: add --allow "
        "'PEER read|write|call|param PATTERN' or --policy FILE (policy_lines, policy_files)");
  }
  if (policy && !tls && options.tokens_file.empty()) {
    throw Error(
        "with a policy every client authenticates, and none could: add --tokens FILE "
        "(tokens_file) or --tls DIR --name NAME (tls_folder, tls_name) for client "
        "certificates");
  }
}

std::unique_ptr<SchedulerCompanion> start_live_view(
    const LiveViewOptions& options, const std::string& namespace_name,
    std::function<void(const std::string&)> on_failure) {
  check_live_view(options);
  const auto factory =
      scheduler_companion_factory<LiveViewOptions>().load(std::memory_order_acquire);
  if (factory == nullptr) {
    throw Error(
        "this program has no live view: link it with horus::view (target_link_libraries(... "
        "horus::view), built where Cap'n Proto is installed)");
  }
  return factory(options, namespace_name, std::move(on_failure));
}

}  // namespace horus::detail
