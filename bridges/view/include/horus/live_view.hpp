// horus::LiveView: a running HORUS namespace served to Foxglove and Lichtblick (and the built-in
// page) over the Foxglove WebSocket protocol (subprotocols foxglove.websocket.v1 and
// foxglove.sdk.v1), on kj-http. Every viewable topic is advertised as a channel while it exists;
// a subscribed topic is read by one thread of its own that encodes each frame once
// (horus/view/codecs.hpp) and offers it to every subscriber. A client that reads slowly is sent
// the newest message of each channel it subscribes to and never holds more: the robot's
// publishers never wait for a viewer, and a stalled viewer costs one message per channel.
// Clients may also publish into existing topics, call the services that have a live server, and
// follow the connection graph (nodes and servers, from the namespace's presence registry). With a
// policy (LiveViewOptions: tokens, TLS) each client is a peer and may do only what it allows.
//
//   horus::LiveView view({.namespace_name = "robot", .port = 0});
//   view.start();                           // listening once it returns; throws if it cannot
//   std::printf("ws://127.0.0.1:%u/\n", view.port());
//   ...
//   view.stop();                            // closes every connection; the destructor does too
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "horus/live_view_options.hpp"

namespace horus {

/// What a LiveView has done since start(), over all its clients.
struct LiveViewCounters {
  /// Clients connected now, and ever.
  std::uint64_t clients = 0;
  std::uint64_t clients_served = 0;
  /// Channels advertised now.
  std::uint64_t channels = 0;
  /// Messages sent to clients, and messages replaced by a newer one before a client took them
  /// (latest wins) or lost in a topic's ring before the view read them.
  std::uint64_t messages_sent = 0;
  std::uint64_t messages_dropped = 0;
  /// Messages clients published into topics, and those refused (with a status to the client).
  std::uint64_t messages_published = 0;
  std::uint64_t publishes_refused = 0;
};

class LiveView {
 public:
  /// `on_stopped` is told why, should the view stop on its own after start() (a bug of its own,
  /// also said on stderr); a scheduler's view stops the scheduler with it.
  explicit LiveView(LiveViewOptions options,
                    std::function<void(const std::string&)> on_stopped = {});
  LiveView(const LiveView&) = delete;
  LiveView& operator=(const LiveView&) = delete;
  /// Stops.
  ~LiveView();

  /// Starts serving on a thread of its own; returns once listening. Throws horus::Error when the
  /// options are refused (detail::check_live_view), a policy, tokens or certificate file will
  /// not do, the address cannot be listened on (in use, not an address of this machine) or on
  /// a second call.
  void start();
  /// Closes every connection and ends the thread. Idempotent.
  void stop();
  /// The port listened on (the one chosen when the options asked for 0); 0 before start().
  std::uint16_t port() const noexcept;
  LiveViewCounters counters() const;
  /// Clients, their subscriptions and each one's sent and dropped counts, as one JSON object
  /// (what `horus-view status` shows): {"pid", "namespace", "listen", "clients": [{"id",
  /// "address", "peer" (null without a policy), "subprotocol", "sent", "dropped",
  /// "subscriptions": [{"id", "topic", "sent", "dropped", "max_rate_hz"}]}], "counters": {...}}.
  std::string status_json() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

namespace view {

/// Makes horus::LiveView what SchedulerConfig::view() starts. A program that links horus::view
/// has it called before main() (src/register_scheduler_view.cpp); nothing else needs to.
void enable_scheduler_view() noexcept;

}  // namespace view

}  // namespace horus
