// horus::LiveViewOptions: what the live view serves and how (docs/live-view.md), given to
// `horus::LiveView` (horus/live_view.hpp, library horus::view) or to a scheduler that runs the
// view in its own process:
//
//   horus::Scheduler sched{horus::SchedulerConfig{}.view({.port = 8765})};
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "horus/scheduler_companion.hpp"

namespace horus {

/// (Every field has an initializer so that designated initializers may leave any out.)
struct LiveViewOptions {
  /// The namespace served (empty: the current one, HORUS_NAMESPACE or "default"; a scheduler's
  /// view serves the scheduler's).
  std::string namespace_name{};
  /// The address listened on. Loopback by default; any other needs TLS and a policy (the view
  /// refuses to start without them).
  std::string listen_address = "127.0.0.1";
  /// 0: any free port (LiveView::port() says which).
  std::uint16_t port = 8765;
  /// How often the namespace is looked at for topics and services that came or went.
  std::chrono::milliseconds discovery_interval{250};
  /// The time the view tells its viewers (the protocol's `time`), in nanoseconds since the
  /// epoch; empty: the wall clock. A scheduler's view is given the scheduler's clock (simulated
  /// time in deterministic mode), a recording played with --view the recording's time.
  std::function<std::int64_t()> clock{};

  // Access (bridges/view/README.md). Without a policy every client may read, publish into and
  // call everything (loopback only); with one every client authenticates, by a token or a client
  // certificate, as a peer, and may do what the policy allows that peer, nothing else.

  /// TLS (wss://) with `horus remote keygen DIR NAME`'s certificates: the folder DIR (its
  /// NAME.crt and NAME.key served, its ca.crt the one authority trusted for client
  /// certificates) and the server's NAME. Both or neither; neither: plain ws://. A client
  /// certificate is optional: a client that presents one is the peer its common name names.
  std::string tls_folder{};
  std::string tls_name{};
  /// Policy lines "PEER read|write|call|param PATTERN" (horus remote's, globs; everything not
  /// allowed is denied), and files of them (one a line, # comments).
  std::vector<std::string> policy_lines{};
  std::vector<std::string> policy_files{};
  /// A file of lines "PEER TOKEN": a client that connects with ?token=TOKEN in its URL is PEER.
  /// Refused unless this user owns it and neither group nor others may read it.
  std::string tokens_file{};
};

namespace detail {

/// Throws horus::Error naming the first field of `options` the view would refuse (an address
/// beyond this machine without TLS or a policy, a policy no client can authenticate for, ...).
/// The files named are read when the view starts.
void check_live_view(const LiveViewOptions& options);

/// Whether `address` (a listen address) reaches this machine only: 127.0.0.0/8, ::1, localhost.
bool is_loopback_address(const std::string& address);

/// Checks `options` and starts the view; throws horus::Error when they are invalid, or when the
/// program was not linked with horus::view.
std::unique_ptr<SchedulerCompanion> start_live_view(
    const LiveViewOptions& options, const std::string& namespace_name,
    std::function<void(const std::string&)> on_failure);

}  // namespace detail

}  // namespace horus
