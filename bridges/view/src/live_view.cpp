// The live view's server: kj-http's WebSocket server on an event loop of its own thread (over
// TLS when asked), the Foxglove WebSocket protocol's sessions (one Client each, as the peer it
// authenticated as when there is a policy), the channels of the namespace's topics and the feeds
// of the subscribed ones.
#include "horus/live_view.hpp"

#include <kj/async-io.h>
#include <kj/compat/http.h>
#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <deque>
#include <future>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <tuple>

#include "access.hpp"
#include "frames_feed.hpp"
#include "horus/bridge/frame_source.hpp"
#include "horus/bridge/peer_policy.hpp"
#include "horus/bridge/tls.hpp"
#include "horus/error.hpp"
#include "horus/frames.hpp"
#include "horus/json_string.hpp"
#include "horus/pool_frames.hpp"
#include "horus/presence.hpp"
#include "horus/raw_service.hpp"
#include "horus/raw_topic.hpp"
#include "horus/service_registry.hpp"
#include "horus/topic_registry.hpp"
#include "horus/view/codecs.hpp"
#include "page.hpp"
#include "parameters.hpp"
#include "protocol.hpp"
#include "services.hpp"
#include "topic_feed.hpp"

namespace horus {

namespace view {

namespace {

/// The largest message a client may send (a published message's payload, JSON).
constexpr std::size_t kLargestClientMessage = std::size_t{16} << 20;
/// Server messages other than Message Data (advertisements, statuses, time) a client may have
/// waiting; a client that lets more pile up has stopped reading and is disconnected.
constexpr std::size_t kOutboxLimit = 4096;
/// How often a Time message is sent.
constexpr auto kTimeInterval = std::chrono::milliseconds(100);
/// How long a client's service call waits for the server's answer.
constexpr auto kCallTimeout = std::chrono::seconds(10);
/// How often the parameter stores' change counts are looked at, for the clients that subscribed
/// to parameter updates (one load per store: a store's records are read only when it moved).
constexpr auto kParameterCheckInterval = std::chrono::milliseconds(50);

/// What a client asks of a topic or service: every request passes through Server::allowed().
using bridge::Access;
/// How long a client has for its TLS handshake.
constexpr auto kHandshakeTimeout = 10 * kj::SECONDS;

/// "HOST:PORT" of the peer of a connection.
std::string peer_address(kj::AsyncIoStream& stream) {
  sockaddr_storage address{};
  kj::uint length = sizeof(address);
  // Not a socket (an in-process pipe): nothing to name.
  KJ_IF_MAYBE (error, kj::runCatchingExceptions([&] {
                 stream.getpeername(reinterpret_cast<sockaddr*>(&address), &length);
               })) {
    return "local";
  }
  char host[NI_MAXHOST] = {};
  char port[NI_MAXSERV] = {};
  if (::getnameinfo(reinterpret_cast<sockaddr*>(&address), length, host, sizeof(host), port,
                    sizeof(port), NI_NUMERICHOST | NI_NUMERICSERV) != 0) {
    return "unknown";
  }
  return std::string(host) + ":" + port;
}

/// `address` as the host of a URL: an IPv6 address in brackets.
std::string url_host(const std::string& address) {
  return address.find(':') != std::string::npos ? "[" + address + "]" : address;
}

/// The namespace's nodes (a Scheduler's announcement: each node's publishers and subscribers,
/// by node name) and services (a process announcement's servers, as "PROGRAM (pid N)"), from
/// its presence registry. A process announcement does not say which way its topic handles go:
/// those are not in the graph.
ConnectionGraph read_graph(const std::string& namespace_name) {
  ConnectionGraph graph;
  const auto add_topics = [](capnp::json::Value::Reader node, std::string_view key,
                             const std::string& id,
                             std::map<std::string, std::set<std::string>>& into) {
    const auto list = member(node, key);
    if (!list || list->which() != capnp::json::Value::ARRAY) return;
    for (const auto use : list->getArray()) {
      const auto topic = member(use, "topic");
      if (topic && topic->which() == capnp::json::Value::STRING) {
        into[topic->getString().cStr()].insert(id);
      }
    }
  };
  for (const PresenceInfo& entry : list_presence(namespace_name)) {
    if (!entry.alive || !entry.error.empty()) continue;
    try {
      const JsonDocument snapshot(entry.snapshot_json);
      if (const auto nodes = member(snapshot.root(), "nodes");
          nodes && nodes->which() == capnp::json::Value::ARRAY) {
        for (const auto node : nodes->getArray()) {
          const std::string name = string_member(node, "name", "a node");
          add_topics(node, "publishers", name, graph.publishers);
          add_topics(node, "subscribers", name, graph.subscribers);
        }
      }
      if (const auto process = member(snapshot.root(), "process");
          process && process->which() == capnp::json::Value::STRING) {
        const std::string id =
            std::string(process->getString().cStr()) + " (pid " + std::to_string(entry.pid) + ")";
        if (const auto services = member(snapshot.root(), "services");
            services && services->which() == capnp::json::Value::ARRAY) {
          for (const auto service : services->getArray()) {
            if (string_member(service, "role", "a service") == "server") {
              graph.providers[string_member(service, "service", "a service")].insert(id);
            }
          }
        }
      }
    } catch (const ProtocolError&) {
      // An announcement that does not read as expected is left out of the graph.
    }
  }
  return graph;
}

/// What LiveView::start() reads before it serves, so that a policy, tokens file or certificate
/// folder that will not do is its error: who may do what, who each token is, TLS's certificates.
struct AccessSetup {
  std::optional<bridge::PeerPolicy> policy;
  std::optional<PeerTokens> tokens;
  std::optional<bridge::TlsCredentials> credentials;
};

/// Throws horus::Error naming the file (and line) that will not do.
AccessSetup load_access(const LiveViewOptions& options) {
  AccessSetup access;
  if (!options.policy_lines.empty() || !options.policy_files.empty()) {
    access.policy.emplace();
    try {
      for (const std::string& line : options.policy_lines) access.policy->add(line, "--allow");
      for (const std::string& file : options.policy_files) access.policy->load(file);
    } catch (const std::invalid_argument& error) {
      throw Error(error.what());
    }
    if (access.policy->empty()) {
      std::fprintf(stderr,
                   "horus-view: WARNING: the policy has no rule: every client is refused\n");
    }
  }
  if (!options.tokens_file.empty()) access.tokens = PeerTokens::load(options.tokens_file);
  if (!options.tls_folder.empty()) {
    try {
      access.credentials = bridge::load_tls_credentials(options.tls_folder, options.tls_name);
    } catch (const kj::Exception& error) {
      throw Error("the certificates of " + options.tls_folder + " for '" + options.tls_name +
                  "' do not read as PEM: " + error.getDescription().cStr());
    } catch (const std::runtime_error& error) {
      throw Error(error.what());
    }
  }
  return access;
}

class Server;

/// A topic advertised as a channel, and its feed while a client subscribes to it.
struct ChannelEntry {
  Channel channel;
  TopicInfo info;
  std::unique_ptr<TopicFeed> feed;
};

/// The namespace's frame tree, once it exists, as its two channels (frames_feed.hpp), and their
/// feed while a client subscribes to either.
struct FramesChannels {
  explicit FramesChannels(const std::string& namespace_name)
      : tree(FrameTreeOptions{.namespace_name = namespace_name}) {}

  FrameTree tree;
  Channel dynamic;
  Channel statics;
  std::unique_ptr<FramesFeed> feed;
};

/// A topic a client advertised to publish into.
struct ClientChannel {
  std::string topic;
  std::unique_ptr<RawTopic> writer;
  std::unique_ptr<MessageCodec> codec;
};

/// One WebSocket session.
class Client final : private kj::TaskSet::ErrorHandler {
 public:
  /// What a server message other than Message Data is.
  enum class Kind { Text, Binary, Time };

  /// `peer`: who the client authenticated as (empty without a policy).
  Client(Server& server, kj::Own<kj::WebSocket> socket, std::string subprotocol,
         std::string address, std::string peer);
  ~Client();

  /// Until the connection ends (closed, broken, or this client dropped for not reading).
  kj::Promise<void> run();
  /// Queues a server message.
  void send(std::string message, Kind kind = Kind::Text);
  void say(StatusLevel level, const std::string& message) { send(status(level, message)); }
  /// Ends the channel's subscriptions (the channel went).
  void forget_channel(std::uint32_t channel);
  /// Sends the parameters of `changed` this client subscribed to (parameterValues).
  void parameters_changed(const std::vector<ParamInfo>& changed);
  /// Queues a Time message unless one is already waiting.
  void send_time(std::uint64_t time_ns);
  std::string status_json() const;

  std::uint64_t id() const noexcept { return id_; }
  const std::string& peer() const noexcept { return peer_; }
  /// Whether the frames channels were advertised to this client (Server::advertise_frames()).
  bool frames_advertised() const noexcept { return frames_advertised_; }
  void set_frames_advertised() noexcept { frames_advertised_ = true; }

 private:
  /// One stderr line the first time this client is refused `what` ("publishing into") of
  /// `name`: a client that asks again and again costs the log one line.
  void log_refusal(const std::string& what, const std::string& name);
  kj::Promise<void> read_loop();
  kj::Promise<void> write_loop();
  void on_text(kj::StringPtr text);
  void on_binary(kj::ArrayPtr<const kj::byte> bytes);
  void subscribe(capnp::json::Value::Reader message);
  void unsubscribe(capnp::json::Value::Reader message);
  void advertise_client_channels(capnp::json::Value::Reader message);
  void unadvertise_client_channels(capnp::json::Value::Reader message);
  void publish(std::uint32_t channel, std::span<const std::byte> payload);
  void call(std::span<const std::byte> request);
  void get_parameters(capnp::json::Value::Reader message);
  void set_parameters(capnp::json::Value::Reader message);
  void watch_parameters(capnp::json::Value::Reader message, bool watch);
  /// The names of a getParameters or (un)subscribeParameterUpdates.
  std::vector<std::string> parameter_names(capnp::json::Value::Reader message,
                                           std::string_view op) const;
  void taskFailed(kj::Exception&& exception) override;
  void end_subscription(std::map<std::uint32_t, std::shared_ptr<Subscription>>::iterator which);

  Server& server_;
  const std::uint64_t id_;
  kj::Own<kj::WebSocket> socket_;
  const std::string subprotocol_;
  const std::string address_;
  const std::string peer_;
  std::set<std::string> refusals_logged_;
  bool frames_advertised_ = false;
  std::shared_ptr<Mailbox> mailbox_ = std::make_shared<Mailbox>();
  std::map<std::uint32_t, std::shared_ptr<Subscription>> subscriptions_;
  std::map<std::uint32_t, ClientChannel> client_channels_;
  /// The parameters ("NODE.PARAMETER") whose updates this client subscribed to.
  std::set<std::string> watched_parameters_;
  /// Server messages other than Message Data, in order.
  std::deque<std::pair<std::string, Kind>> outbox_;
  bool time_waiting_ = false;
  /// Set when the outbox overflowed: the writer ends the connection.
  std::optional<std::string> overflowed_;
  /// What the socket is sending now (kj's send() keeps no copy); a Message Data is sent from
  /// its subscription's buffer.
  std::string in_flight_text_;
  /// The subscription served last: the next one after it goes first (round robin).
  std::uint32_t last_served_ = 0;
  std::uint64_t sent_ = 0;
  std::uint64_t dropped_before_ = 0;
  /// Scratch for a decoded publish.
  std::vector<std::byte> frame_;
  /// Service calls waiting for their answers. Last: cancelled before what they use.
  kj::TaskSet calls_{*this};
};

/// Shared with LiveView::counters() on other threads.
struct Counters {
  std::atomic<std::uint64_t> clients{0};
  std::atomic<std::uint64_t> clients_served{0};
  std::atomic<std::uint64_t> channels{0};
  std::atomic<std::uint64_t> messages_sent{0};
  std::atomic<std::uint64_t> messages_dropped{0};
  std::atomic<std::uint64_t> messages_published{0};
  std::atomic<std::uint64_t> publishes_refused{0};
};

class Server final : private kj::TaskSet::ErrorHandler {
 public:
  Server(const LiveViewOptions& options, AccessSetup access, kj::AsyncIoContext& io,
         Counters& counters);
  ~Server() noexcept(false);

  std::uint16_t port() const noexcept { return port_; }
  /// Serves until the listener fails.
  kj::Promise<void> run();
  std::string status_json() const;

  // For the clients:
  kj::Timer& timer() { return io_.provider->getTimer(); }
  Counters& counters() { return counters_; }
  const std::string& namespace_name() const { return namespace_; }
  /// Whether `client` may have `access` to `name`. Every advertise, subscribe, publish, call
  /// and parameter read or write asks here: without a policy everything is allowed (a loopback
  /// listener), with one what it allows the client's peer.
  bool allowed(const Client& client, Access access, const std::string& name) const;
  std::uint64_t new_client(Client& client);
  void client_gone(const Client& client);
  /// What a new client is sent first: serverInfo and the channels it may read.
  void greet(Client& client);
  const ChannelEntry* channel(std::uint32_t id) const;
  const ChannelEntry* channel_of_topic(const std::string& topic) const;
  /// The frames channel of `id` (none while the namespace has no frame tree).
  const Channel* frames_channel(std::uint32_t id) const;
  /// Which frames `client` may read: its policy's "@frames/CHILD" (empty: every frame).
  std::function<bool(const std::string&)> frame_filter(const Client& client) const;
  /// Adds `subscription` to its channel's feed, started on the first; throws horus::Error when
  /// the topic cannot be opened.
  void subscribe(const std::shared_ptr<Subscription>& subscription);
  void unsubscribe(const Subscription& subscription);
  /// Starts (sending the whole graph) or ends sending `client` the connection graph's updates.
  void watch_graph(Client& client, bool watch);
  /// The part of `graph` `client` may see: the topics it may read, the services it may call.
  ConnectionGraph visible_graph(const Client& client, const ConnectionGraph& graph) const;
  /// Sends `client` what changed in its part of the graph from graph_ to `graph`, if anything.
  void send_graph_update(Client& client, const ConnectionGraph& graph) const;
  std::shared_ptr<ViewService> service(std::uint32_t id) const;
  ParameterStores& parameters() { return parameters_; }
  ParameterWriter& parameter_writer() { return parameter_writer_; }

 private:
  kj::Promise<void> discover_forever();
  /// Advertises the topics that came and unadvertises those that went.
  void discover();
  /// Opens the namespace's frame tree once it exists.
  void discover_frames();
  /// Advertises the frames channels to each client not yet sent them that may read a frame of
  /// the tree (without a policy, every client): a peer whose policy names no frame the tree
  /// holds is not told the channels, as it is not told the topics it may not read.
  void advertise_frames();
  /// The same for the services (`frame_topics`: the namespace's service frame topics by name).
  void discover_services(const std::map<std::string, TopicInfo>& frame_topics);
  kj::Promise<void> send_time_forever();
  /// Sends the parameters that changed to the clients that subscribed to them.
  kj::Promise<void> send_parameter_updates_forever();
  /// Accepts connections over TLS, each handshake on its own, then served by http_.
  kj::Promise<void> accept_tls_forever();
  /// Serves a connection whose handshake ended, knowing its certificate's name (if any).
  kj::Promise<void> serve_tls(kj::AuthenticatedStream secured);
  /// `certificate`: the common name of the client's certificate, when it presented one.
  kj::Promise<void> accept(kj::HttpMethod method, kj::StringPtr url, const kj::HttpHeaders& headers,
                           kj::HttpService::Response& response, const std::string& address,
                           const std::optional<std::string>& certificate);
  /// The peer a client authenticated as (its certificate's name, else its URL's token's); none
  /// when it did not, with `why` set to what the log and the client are told.
  std::optional<std::string> authenticate(kj::StringPtr url,
                                          const std::optional<std::string>& certificate,
                                          std::string& why) const;
  /// A file of the built-in page (or why not).
  kj::Promise<void> serve_page(kj::HttpMethod method, kj::StringPtr url,
                               kj::HttpService::Response& response);
  void taskFailed(kj::Exception&& exception) override;

  /// Serves each connection, knowing its peer's address.
  class Connection final : public kj::HttpService {
   public:
    Connection(Server& server, std::string address, std::optional<std::string> certificate)
        : server_(server), address_(std::move(address)), certificate_(std::move(certificate)) {}
    kj::Promise<void> request(kj::HttpMethod method, kj::StringPtr url,
                              const kj::HttpHeaders& headers, kj::AsyncInputStream&,
                              Response& response) override {
      return server_.accept(method, url, headers, response, address_, certificate_);
    }

   private:
    Server& server_;
    std::string address_;
    std::optional<std::string> certificate_;
  };

  LiveViewOptions options_;
  std::string namespace_;
  /// Who may do what (none: everyone everything), and the peers of the tokens.
  std::optional<bridge::PeerPolicy> policy_;
  std::optional<PeerTokens> tokens_;
  /// Over TLS: the context, and the common names of the certificates of the connections whose
  /// handshake ended, until http_ makes their Connection.
  kj::Own<kj::TlsContext> tls_;
  std::map<const kj::AsyncIoStream*, std::string> certificate_names_;
  kj::AsyncIoContext& io_;
  Counters& counters_;
  const std::string session_id_ = std::to_string(realtime_ns());
  kj::HttpHeaderTable::Builder header_builder_;
  kj::HttpHeaderId protocol_header_;
  kj::Own<kj::HttpHeaderTable> headers_;
  kj::Own<kj::ConnectionReceiver> listener_;
  std::uint16_t port_ = 0;
  std::map<std::string, ChannelEntry> channels_;
  std::map<std::uint32_t, std::string> topic_of_channel_;
  /// Ids given, kept for the server's life: a topic that goes and comes back with the same type
  /// is the same channel (the spec lets a client cache it).
  std::map<std::tuple<std::string, std::string, std::uint64_t>, std::uint32_t> channel_ids_;
  std::uint32_t next_channel_id_ = 1;
  /// Topics no codec shows, by "name type", each said once.
  std::set<std::string> unviewable_;
  /// Outlives the clients (http_'s), whose subscriptions its feed holds.
  std::unique_ptr<FramesChannels> frames_;
  /// Why the frame tree could not be opened, said once.
  std::string frames_refused_;
  std::map<std::uint64_t, Client*> clients_;
  std::uint64_t next_client_id_ = 1;
  std::map<std::string, std::shared_ptr<ViewService>> services_;
  std::map<std::uint32_t, std::string> service_of_id_;
  /// As channel_ids_: a service that goes and comes back with the same type keeps its id.
  std::map<std::pair<std::string, std::uint64_t>, std::uint32_t> service_ids_;
  std::uint32_t next_service_id_ = 1;
  /// Services not offered, by "name fingerprint", each said once.
  std::set<std::string> uncallable_;
  /// The clients sent the connection graph, and the graph as they were sent it last.
  std::set<std::uint64_t> graph_watchers_;
  ConnectionGraph graph_;
  ParameterStores parameters_;
  ParameterWriter parameter_writer_;
  kj::TaskSet tasks_;
  /// Its connections (and their clients) end before what they use.
  kj::HttpServer http_;
  /// Last: the TLS connections http_ serves, each ended before http_.
  kj::TaskSet tls_connections_;
};

// ---------------------------------------------------------------------------------------------

Client::Client(Server& server, kj::Own<kj::WebSocket> socket, std::string subprotocol,
               std::string address, std::string peer)
    : server_(server),
      id_(server.new_client(*this)),
      socket_(kj::mv(socket)),
      subprotocol_(std::move(subprotocol)),
      address_(std::move(address)),
      peer_(std::move(peer)) {
  server_.greet(*this);
}

void Client::log_refusal(const std::string& what, const std::string& name) {
  if (!refusals_logged_.insert(what + " " + name).second) return;
  std::fprintf(stderr, "horus-view: refused %s (%s): %s '%s'\n", peer_.c_str(), address_.c_str(),
               what.c_str(), name.c_str());
}

Client::~Client() {
  while (!subscriptions_.empty()) end_subscription(subscriptions_.begin());
  server_.client_gone(*this);
}

kj::Promise<void> Client::run() { return read_loop().exclusiveJoin(write_loop()); }

void Client::send(std::string message, Kind kind) {
  if (overflowed_) return;
  if (outbox_.size() >= kOutboxLimit) {
    overflowed_ =
        "the client read none of the last " + std::to_string(kOutboxLimit) + " server messages";
  } else {
    outbox_.emplace_back(std::move(message), kind);
  }
  mailbox_->wake_here();
}

void Client::send_time(std::uint64_t time_ns) {
  if (time_waiting_) return;
  time_waiting_ = true;
  send(time_message(time_ns), Kind::Time);
}

void Client::forget_channel(std::uint32_t channel) {
  for (auto it = subscriptions_.begin(); it != subscriptions_.end();) {
    const auto next = std::next(it);
    if (it->second->channel == channel) end_subscription(it);
    it = next;
  }
}

void Client::end_subscription(std::map<std::uint32_t, std::shared_ptr<Subscription>>::iterator it) {
  server_.unsubscribe(*it->second);
  {
    const std::lock_guard lock(mailbox_->mutex());
    dropped_before_ += it->second->dropped;
  }
  subscriptions_.erase(it);
}

kj::Promise<void> Client::read_loop() {
  return socket_->receive(kLargestClientMessage)
      .then([this](kj::WebSocket::Message&& message) -> kj::Promise<void> {
        KJ_SWITCH_ONEOF(message) {
          KJ_CASE_ONEOF(text, kj::String) { on_text(text); }
          KJ_CASE_ONEOF(bytes, kj::Array<kj::byte>) { on_binary(bytes); }
          KJ_CASE_ONEOF(close, kj::WebSocket::Close) {
            return socket_->close(1000, "").catch_([](kj::Exception&&) {});
          }
        }
        return read_loop();
      });
}

kj::Promise<void> Client::write_loop() {
  if (overflowed_) {
    return socket_->close(1008, *overflowed_).catch_([](kj::Exception&&) {});
  }
  if (!outbox_.empty()) {
    auto [bytes, kind] = std::move(outbox_.front());
    outbox_.pop_front();
    in_flight_text_ = std::move(bytes);
    if (kind == Kind::Time) time_waiting_ = false;
    if (kind != Kind::Text) {
      return socket_
          ->send(kj::arrayPtr(reinterpret_cast<const kj::byte*>(in_flight_text_.data()),
                              in_flight_text_.size()))
          .then([this] { return write_loop(); });
    }
    return socket_->send(kj::arrayPtr(in_flight_text_.data(), in_flight_text_.size())).then([this] {
      return write_loop();
    });
  }
  // The next subscription with a message that is due, after the one served last.
  const auto now = std::chrono::steady_clock::now();
  std::optional<std::chrono::steady_clock::time_point> next_due;
  std::shared_ptr<const EncodedMessage> message;
  std::shared_ptr<Subscription> chosen;
  std::optional<kj::Promise<void>> woken;
  {
    const std::lock_guard lock(mailbox_->mutex());
    bool from_threads = false;
    auto it = subscriptions_.upper_bound(last_served_);
    for (std::size_t looked = 0; looked < subscriptions_.size(); ++looked, ++it) {
      if (it == subscriptions_.end()) it = subscriptions_.begin();
      Subscription& subscription = *it->second;
      from_threads = from_threads || subscription.fed_by_thread;
      if (!subscription.has_pending()) continue;
      const auto due = subscription.last_sent + subscription.min_interval;
      if (due > now) {
        next_due = next_due ? std::min(*next_due, due) : due;
        continue;
      }
      message = subscription.take_pending();
      ++subscription.sent;
      chosen = it->second;
      break;
    }
    if (chosen == nullptr) woken = mailbox_->armed(from_threads);
  }
  if (chosen != nullptr) {
    chosen->last_sent = now;
    last_served_ = chosen->id;
    ++sent_;
    server_.counters().messages_sent.fetch_add(1, std::memory_order_relaxed);
    // The next message is picked only once this one is written: one sent at a time is always
    // the newest of its subscription (a CmdVel that waited behind an image is not sent stale),
    // and needs no wake-up when the next is already pending.
    if (message->framed_for == chosen->id) {
      // The message as the feed framed it, held until the send ends.
      const auto framed = kj::arrayPtr(reinterpret_cast<const kj::byte*>(message->framed.data()),
                                       message->framed.size());
      return socket_->send(framed).attach(kj::mv(message)).then([this] { return write_loop(); });
    }
    message_data(chosen->id, message->receive_time_ns, message->payload(), chosen->framed);
    message.reset();
    const auto framed = kj::arrayPtr(reinterpret_cast<const kj::byte*>(chosen->framed.data()),
                                     chosen->framed.size());
    // The subscription (its buffer) lives until the send ends, should it end meanwhile.
    return socket_->send(framed).attach(kj::mv(chosen)).then([this] { return write_loop(); });
  }
  kj::Promise<void> wait = kj::mv(*woken);
  if (next_due) {
    const auto due_in = std::chrono::duration_cast<std::chrono::nanoseconds>(*next_due - now);
    wait = wait.exclusiveJoin(server_.timer().afterDelay(due_in.count() * kj::NANOSECONDS));
  }
  return wait.then([this] { return write_loop(); });
}

void Client::on_text(kj::StringPtr text) {
  try {
    const ClientMessage message(std::string_view(text.cStr(), text.size()));
    const std::string& op = message.op();
    if (op == "subscribe") {
      subscribe(message.root());
    } else if (op == "unsubscribe") {
      unsubscribe(message.root());
    } else if (op == "advertise") {
      advertise_client_channels(message.root());
    } else if (op == "unadvertise") {
      unadvertise_client_channels(message.root());
    } else if (op == "subscribeConnectionGraph") {
      server_.watch_graph(*this, true);
    } else if (op == "unsubscribeConnectionGraph") {
      server_.watch_graph(*this, false);
    } else if (op == "getParameters") {
      get_parameters(message.root());
    } else if (op == "setParameters") {
      set_parameters(message.root());
    } else if (op == "subscribeParameterUpdates") {
      watch_parameters(message.root(), true);
    } else if (op == "unsubscribeParameterUpdates") {
      watch_parameters(message.root(), false);
    } else {
      throw ProtocolError("op \"" + op + "\" is not served by horus-view");
    }
  } catch (const ProtocolError& error) {
    say(StatusLevel::Error, error.what());
  }
}

void Client::on_binary(kj::ArrayPtr<const kj::byte> bytes) {
  const std::span<const std::byte> message(reinterpret_cast<const std::byte*>(bytes.begin()),
                                           bytes.size());
  if (message.empty()) {
    say(StatusLevel::Error, "an empty binary message");
    return;
  }
  const auto opcode = static_cast<ClientOpcode>(message[0]);
  if (opcode == ClientOpcode::MessageData) {
    if (message.size() < 5) {
      say(StatusLevel::Error, "a Client Message Data shorter than its channel id");
      return;
    }
    publish(read_u32(message, 1), message.subspan(5));
    return;
  }
  if (opcode == ClientOpcode::ServiceCallRequest) {
    call(message);
    return;
  }
  say(StatusLevel::Error,
      "binary opcode " + std::to_string(static_cast<int>(message[0])) + " is not served");
}

void Client::subscribe(capnp::json::Value::Reader message) {
  for (const auto entry : array_member(message, "subscriptions", "subscribe")) {
    try {
      const std::uint32_t id = id_member(entry, "id", "a subscription");
      const std::uint32_t channel_id = id_member(entry, "channelId", "a subscription");
      // Not in the spec: a viewer that draws slowly (a page plotting at 10 Hz) asks for no more
      // than maxRateHz messages per second; it is sent the newest each time.
      const std::optional<double> rate =
          optional_number_member(entry, "maxRateHz", "a subscription");
      if (rate && !(*rate > 0)) {
        throw ProtocolError("subscription " + std::to_string(id) +
                            ": maxRateHz must be a positive number of messages per second");
      }
      if (subscriptions_.count(id) != 0) {
        throw ProtocolError("subscription id " + std::to_string(id) +
                            " is in use; unsubscribe it first");
      }
      // A frames channel is subscribed to by every client it was advertised to; each transform
      // then goes only to the clients that may read its frame.
      const Channel* frames = server_.frames_channel(channel_id);
      const ChannelEntry* topic = frames ? nullptr : server_.channel(channel_id);
      if (frames == nullptr && topic == nullptr) {
        throw ProtocolError("subscription " + std::to_string(id) + ": no channel " +
                            std::to_string(channel_id) + " (never advertised, or gone)");
      }
      const Channel& channel = frames ? *frames : topic->channel;
      if (frames ? !frames_advertised_ : !server_.allowed(*this, Access::Read, channel.topic)) {
        // The client was never told the channel's topic: the reply does not name it.
        log_refusal("subscribing to", channel.topic);
        throw ProtocolError("subscription " + std::to_string(id) + ": channel " +
                            std::to_string(channel_id) + " is not one peer '" + peer_ +
                            "' may read");
      }
      for (const auto& [other_id, other] : subscriptions_) {
        if (other->channel == channel_id) {
          throw ProtocolError("subscription " + std::to_string(id) + ": channel " +
                              std::to_string(channel_id) + " is subscribed already (as " +
                              std::to_string(other_id) + ")");
        }
      }
      const auto interval =
          rate ? std::chrono::nanoseconds(std::llround(1e9 / *rate)) : std::chrono::nanoseconds(0);
      auto subscription = std::make_shared<Subscription>(
          id, channel_id, channel.topic, mailbox_, interval, server_.counters().messages_dropped);
      if (frames) {
        subscription->frames = std::make_unique<FrameSlots>();
        subscription->frames->readable = server_.frame_filter(*this);
        subscription->frames->is_static = channel.topic == kStaticFramesTopic;
      }
      try {
        server_.subscribe(subscription);
      } catch (const std::exception& error) {
        throw ProtocolError("subscription " + std::to_string(id) + " to '" + channel.topic +
                            "': " + error.what());
      }
      subscriptions_.emplace(id, std::move(subscription));
      // The writer arms its wait for threads' wakes only while a thread feeds it: it looks again.
      mailbox_->wake_here();
    } catch (const ProtocolError& error) {
      say(StatusLevel::Error, error.what());
    }
  }
}

void Client::unsubscribe(capnp::json::Value::Reader message) {
  for (const auto entry : array_member(message, "subscriptionIds", "unsubscribe")) {
    const std::uint32_t id = id_value(entry, "unsubscribe");
    const auto it = subscriptions_.find(id);
    if (it == subscriptions_.end()) {
      say(StatusLevel::Warning, "unsubscribe: no subscription " + std::to_string(id));
      continue;
    }
    end_subscription(it);
  }
}

void Client::advertise_client_channels(capnp::json::Value::Reader message) {
  for (const auto entry : array_member(message, "channels", "advertise")) {
    try {
      const std::uint32_t id = id_member(entry, "id", "an advertised channel");
      const std::string topic = string_member(entry, "topic", "an advertised channel");
      const std::string encoding = string_member(entry, "encoding", "an advertised channel");
      const std::string schema_name = string_member(entry, "schemaName", "an advertised channel");
      const std::string refused =
          "publishing into '" + topic + "' (client channel " + std::to_string(id) + ") refused: ";
      if (client_channels_.count(id) != 0) {
        throw ProtocolError(refused + "channel id in use; unadvertise it first");
      }
      if (encoding != "json") {
        throw ProtocolError(refused + "encoding \"" + encoding +
                            "\" is not one of the supportedEncodings [\"json\"]");
      }
      // Asked first: a peer that may not write a name is not told whether its topic exists.
      if (!server_.allowed(*this, Access::Write, topic)) {
        log_refusal("publishing into", topic);
        throw ProtocolError(refused + "peer '" + peer_ + "' may not write it");
      }
      const ChannelEntry* channel = server_.channel_of_topic(topic);
      if (channel == nullptr) {
        throw ProtocolError(refused +
                            "no such topic (a viewer publishes only into a topic that exists)");
      }
      if (schema_name != channel->channel.schema.schema_name) {
        throw ProtocolError(refused + "the topic carries " + channel->channel.schema.schema_name +
                            ", not " + schema_name);
      }
      if (channel->channel.schema.encoding != "json") {
        throw ProtocolError(refused + "its channel's encoding is " +
                            channel->channel.schema.encoding + "; viewers publish json only");
      }
      ClientChannel publisher;
      publisher.topic = topic;
      try {
        publisher.writer = RawTopic::open_recorded(channel->info, server_.namespace_name());
        publisher.codec = codec_for(type_identity_of(channel->info), topic);
      } catch (const std::exception& error) {
        throw ProtocolError(refused + error.what());
      }
      client_channels_.emplace(id, std::move(publisher));
    } catch (const ProtocolError& error) {
      server_.counters().publishes_refused.fetch_add(1, std::memory_order_relaxed);
      say(StatusLevel::Error, error.what());
    }
  }
}

void Client::unadvertise_client_channels(capnp::json::Value::Reader message) {
  for (const auto entry : array_member(message, "channelIds", "unadvertise")) {
    const std::uint32_t id = id_value(entry, "unadvertise");
    if (client_channels_.erase(id) == 0) {
      say(StatusLevel::Warning, "unadvertise: no client channel " + std::to_string(id));
    }
  }
}

void Client::publish(std::uint32_t channel, std::span<const std::byte> payload) {
  const auto it = client_channels_.find(channel);
  std::string refused;
  if (it == client_channels_.end()) {
    refused = "a message on client channel " + std::to_string(channel) +
              ", which was not advertised (or was refused)";
  } else {
    try {
      it->second.codec->decode(payload, frame_);
      if (!it->second.writer->send(frame_)) {
        refused = "a message for '" + it->second.topic + "' the topic did not take (" +
                  std::to_string(frame_.size()) + " bytes; the topic takes at most " +
                  std::to_string(it->second.writer->payload_capacity()) + ")";
      }
    } catch (const CodecError& error) {
      refused = "a message for '" + it->second.topic + "': " + error.what();
    }
  }
  if (refused.empty()) {
    server_.counters().messages_published.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  server_.counters().publishes_refused.fetch_add(1, std::memory_order_relaxed);
  say(StatusLevel::Error, "not published: " + refused);
}

void Client::call(std::span<const std::byte> request) {
  // opcode, service id, call id, encoding length, encoding, payload.
  constexpr std::size_t kHead = 1 + 4 + 4 + 4;
  if (request.size() < kHead) {
    say(StatusLevel::Error, "a Service Call Request shorter than its header");
    return;
  }
  const std::uint32_t service_id = read_u32(request, 1);
  const std::uint32_t call_id = read_u32(request, 5);
  const std::uint32_t encoding_size = read_u32(request, 9);
  if (request.size() - kHead < encoding_size) {
    send(service_call_failure(service_id, call_id, "the request's encoding overruns the message"));
    return;
  }
  const std::string_view encoding(reinterpret_cast<const char*>(request.data()) + kHead,
                                  encoding_size);
  if (encoding != "json") {
    send(service_call_failure(service_id, call_id,
                              "encoding \"" + std::string(encoding) +
                                  "\" is not one of the supportedEncodings [\"json\"]"));
    return;
  }
  const std::shared_ptr<ViewService> service = server_.service(service_id);
  if (service == nullptr) {
    send(service_call_failure(
        service_id, call_id,
        "no service " + std::to_string(service_id) + " (never advertised, or gone)"));
    return;
  }
  if (!server_.allowed(*this, Access::Call, service->info().name)) {
    // The client was never told the service's name: the reply does not name it.
    log_refusal("calling", service->info().name);
    send(service_call_failure(
        service_id, call_id,
        "service " + std::to_string(service_id) + " is not one peer '" + peer_ + "' may call"));
    return;
  }
  calls_.add(service->call(request.subspan(kHead + encoding_size), kCallTimeout)
                 .then([this, service_id, call_id](ViewService::Answer answer) {
                   if (answer.failure) {
                     send(service_call_failure(service_id, call_id, *answer.failure));
                   } else {
                     send(service_call_response(service_id, call_id, "json", answer.payload),
                          Kind::Binary);
                   }
                 }));
}

std::vector<std::string> Client::parameter_names(capnp::json::Value::Reader message,
                                                 std::string_view op) const {
  std::vector<std::string> names;
  for (const auto entry : array_member(message, "parameterNames", op)) {
    if (entry.which() != capnp::json::Value::STRING) {
      throw ProtocolError(std::string(op) + ": parameterNames holds an entry that is not a string");
    }
    names.emplace_back(entry.getString().cStr());
  }
  return names;
}

/// The "id" of a parameter request: the answer carries it.
std::optional<std::string> request_id(capnp::json::Value::Reader message, std::string_view op) {
  const auto id = member(message, "id");
  if (!id) return std::nullopt;
  if (id->which() != capnp::json::Value::STRING) {
    throw ProtocolError(std::string(op) + ": \"id\" must be a string");
  }
  return std::string(id->getString().cStr());
}

void Client::get_parameters(capnp::json::Value::Reader message) {
  const std::optional<std::string> id = request_id(message, "getParameters");
  const std::vector<std::string> names = parameter_names(message, "getParameters");
  // A node that started since the last discovery is listed already.
  server_.parameters().discover();
  std::vector<std::string> entries;
  if (names.empty()) {
    // None named: every parameter the peer may see.
    for (const ParamInfo& info : server_.parameters().list()) {
      if (server_.allowed(*this, Access::Param, parameter_name(info))) {
        entries.push_back(parameter_entry(info));
      }
    }
  } else {
    // A parameter the peer may not see is left out, as one that does not exist.
    for (const std::string& name : names) {
      if (!server_.allowed(*this, Access::Param, name)) {
        log_refusal("reading parameter", name);
        continue;
      }
      if (const auto info = server_.parameters().find(name)) {
        entries.push_back(parameter_entry(*info));
      }
    }
  }
  send(parameter_values(entries, id));
}

void Client::set_parameters(capnp::json::Value::Reader message) {
  const std::optional<std::string> id = request_id(message, "setParameters");
  server_.parameters().discover();
  std::vector<ParameterWriter::Write> writes;
  std::vector<std::string> names;
  for (const auto entry : array_member(message, "parameters", "setParameters")) {
    try {
      const std::string name = string_member(entry, "name", "a parameter of setParameters");
      // Asked first: a peer that may not set a name is not told whether it exists.
      if (!server_.allowed(*this, Access::Param, name)) {
        log_refusal("setting parameter", name);
        throw ProtocolError("parameter '" + name + "' is not one peer '" + peer_ + "' may set");
      }
      const std::optional<ParamInfo> info = server_.parameters().find(name);
      if (!info) {
        throw ProtocolError("no parameter '" + name +
                            "' (parameters are named NODE.PARAMETER, of a node that declared "
                            "them)");
      }
      const auto value = member(entry, "value");
      if (!value) {
        throw ProtocolError("parameter '" + name + "' has no value (a parameter cannot be unset)");
      }
      writes.push_back({info->node, info->declaration.name, parameter_value(*value)});
      names.push_back(name);
    } catch (const ProtocolError& error) {
      say(StatusLevel::Error, std::string("setParameters: ") + error.what());
    }
  }
  if (writes.empty()) {
    send(parameter_values({}, id));
    return;
  }
  const std::string source = "view:" + (peer_.empty() ? address_ : peer_);
  calls_.add(server_.parameter_writer()
                 .write(std::move(writes), source)
                 .then([this, names = std::move(names),
                        id](std::vector<ParameterWriter::Outcome> outcomes) {
                   std::vector<std::string> entries;
                   for (std::size_t i = 0; i < names.size(); ++i) {
                     const ParameterWriter::Outcome& outcome = outcomes[i];
                     if (outcome.failure.empty() && outcome.result.accepted) continue;
                     const std::string& why =
                         outcome.failure.empty() ? outcome.result.reason : outcome.failure;
                     std::fprintf(stderr, "horus-view: %s (%s) did not set parameter '%s': %s\n",
                                  peer_.empty() ? "a client" : peer_.c_str(), address_.c_str(),
                                  names[i].c_str(), why.c_str());
                     say(StatusLevel::Error, "parameter '" + names[i] + "' not set: " + why);
                   }
                   // The values after the writes, refused ones unchanged.
                   for (const std::string& name : names) {
                     if (const auto info = server_.parameters().find(name)) {
                       entries.push_back(parameter_entry(*info));
                     }
                   }
                   send(parameter_values(entries, id));
                 }));
}

void Client::watch_parameters(capnp::json::Value::Reader message, bool watch) {
  const std::string_view op = watch ? "subscribeParameterUpdates" : "unsubscribeParameterUpdates";
  for (const std::string& name : parameter_names(message, op)) {
    if (!watch) {
      watched_parameters_.erase(name);
    } else if (server_.allowed(*this, Access::Param, name)) {
      watched_parameters_.insert(name);
    } else {
      log_refusal("watching parameter", name);
    }
  }
}

void Client::parameters_changed(const std::vector<ParamInfo>& changed) {
  if (watched_parameters_.empty()) return;
  std::vector<std::string> entries;
  for (const ParamInfo& info : changed) {
    if (watched_parameters_.count(parameter_name(info)) != 0) {
      entries.push_back(parameter_entry(info));
    }
  }
  if (!entries.empty()) send(parameter_values(entries, std::nullopt));
}

void Client::taskFailed(kj::Exception&& exception) {
  say(StatusLevel::Error,
      std::string("a service call failed: ") + exception.getDescription().cStr());
}

std::string Client::status_json() const {
  std::string out = "{\"id\": " + std::to_string(id_) + ", \"address\": " + json_string(address_) +
                    ", \"peer\": " + (peer_.empty() ? std::string("null") : json_string(peer_)) +
                    ", \"subprotocol\": " + json_string(subprotocol_) +
                    ", \"sent\": " + std::to_string(sent_);
  std::string subscriptions;
  std::uint64_t dropped = dropped_before_;
  {
    const std::lock_guard lock(mailbox_->mutex());
    for (const auto& [id, subscription] : subscriptions_) {
      dropped += subscription->dropped;
      if (!subscriptions.empty()) subscriptions += ", ";
      const auto interval = subscription->min_interval.count();
      subscriptions +=
          "{\"id\": " + std::to_string(id) + ", \"topic\": " + json_string(subscription->topic) +
          ", \"sent\": " + std::to_string(subscription->sent) +
          ", \"dropped\": " + std::to_string(subscription->dropped) + ", \"max_rate_hz\": " +
          (interval == 0 ? std::string("null") : std::to_string(1e9 / interval)) + "}";
    }
  }
  return out + ", \"dropped\": " + std::to_string(dropped) + ", \"subscriptions\": [" +
         subscriptions + "]}";
}

// ---------------------------------------------------------------------------------------------

Server::Server(const LiveViewOptions& options, AccessSetup access, kj::AsyncIoContext& io,
               Counters& counters)
    : options_(options),
      namespace_(options.namespace_name.empty() ? current_namespace() : options.namespace_name),
      policy_(std::move(access.policy)),
      tokens_(std::move(access.tokens)),
      io_(io),
      counters_(counters),
      protocol_header_(header_builder_.add("Sec-WebSocket-Protocol")),
      headers_(header_builder_.build()),
      parameters_(namespace_),
      parameter_writer_(namespace_),
      tasks_(*this),
      http_(io.provider->getTimer(), *headers_,
            [this](kj::AsyncIoStream& stream) -> kj::Own<kj::HttpService> {
              std::optional<std::string> certificate;
              if (const auto named = certificate_names_.find(&stream);
                  named != certificate_names_.end()) {
                certificate = std::move(named->second);
                certificate_names_.erase(named);
              }
              return kj::heap<Connection>(*this, peer_address(stream), std::move(certificate));
            }),
      tls_connections_(*this) {
  if (access.credentials) {
    tls_ = bridge::tls_context(*access.credentials, timer(), kHandshakeTimeout,
                               bridge::ClientCertificates::Optional);
  }
  auto address = io_.provider->getNetwork()
                     .parseAddress(kj::StringPtr(options_.listen_address.c_str()), options_.port)
                     .wait(io_.waitScope);
  listener_ = address->listen();
  port_ = static_cast<std::uint16_t>(listener_->getPort());
  discover();
}

Server::~Server() noexcept(false) = default;

kj::Promise<void> Server::run() {
  tasks_.add(discover_forever());
  tasks_.add(send_time_forever());
  tasks_.add(send_parameter_updates_forever());
  return tls_ ? accept_tls_forever() : http_.listenHttp(*listener_);
}

kj::Promise<void> Server::accept_tls_forever() {
  return listener_->acceptAuthenticated().then([this](kj::AuthenticatedStream&& stream) {
    const std::string address = peer_address(*stream.stream);
    tls_connections_.add(
        tls_->wrapServer(kj::mv(stream))
            .then([this](kj::AuthenticatedStream&& secured) { return serve_tls(kj::mv(secured)); },
                  [this, address](kj::Exception&& error) {
                    const std::string why = error.getDescription().cStr();
                    std::fprintf(
                        stderr, "horus-view: refused a client (%s): %s (%s)\n", address.c_str(),
                        bridge::handshake_failure(
                            why, {.server_name = options_.tls_name,
                                  .expect_name = "a client that connects by address must expect "
                                                 "that name",
                                  .plain_client = "a plain ws:// or http:// client?"})
                            .c_str(),
                        why.c_str());
                  }));
    return accept_tls_forever();
  });
}

kj::Promise<void> Server::serve_tls(kj::AuthenticatedStream secured) {
  auto& identity = kj::downcast<kj::TlsPeerIdentity>(*secured.peerIdentity);
  const kj::AsyncIoStream* stream = secured.stream.get();
  if (identity.hasCertificate()) certificate_names_[stream] = identity.getCommonName().cStr();
  // Forgotten when the connection ends, should http_ not have asked: a later stream at the same
  // address must not inherit the name.
  auto forget = kj::defer([this, stream] { certificate_names_.erase(stream); });
  return http_.listenHttp(kj::mv(secured.stream))
      .attach(kj::mv(secured.peerIdentity), kj::mv(forget))
      .catch_([](kj::Exception&&) {
        // A connection that broke ends its session; nothing else to do.
      });
}

void Server::taskFailed(kj::Exception&& exception) {
  std::fprintf(stderr, "horus-view: %s\n", exception.getDescription().cStr());
}

bool Server::allowed(const Client& client, Access access, const std::string& name) const {
  return !policy_ || policy_->allows(client.peer(), access, name);
}

std::optional<std::string> Server::authenticate(kj::StringPtr url,
                                                const std::optional<std::string>& certificate,
                                                std::string& why) const {
  if (certificate) return certificate;
  const std::optional<std::string> token =
      token_of_target(std::string_view(url.cStr(), url.size()));
  if (!token) {
    why = "it gave no token (?token=TOKEN in its URL) and no client certificate";
    return std::nullopt;
  }
  std::optional<std::string> peer = tokens_ ? tokens_->peer_of(*token) : std::nullopt;
  if (!peer) why = "its token is not one of the tokens file's";
  return peer;
}

std::uint64_t Server::new_client(Client& client) {
  const std::uint64_t id = next_client_id_++;
  clients_.emplace(id, &client);
  counters_.clients.store(clients_.size(), std::memory_order_relaxed);
  counters_.clients_served.fetch_add(1, std::memory_order_relaxed);
  return id;
}

void Server::client_gone(const Client& client) {
  clients_.erase(client.id());
  graph_watchers_.erase(client.id());
  counters_.clients.store(clients_.size(), std::memory_order_relaxed);
}

void Server::greet(Client& client) {
  client.send(server_info(
      "horus-view " + namespace_,
      {"clientPublish", "services", "time", "connectionGraph", "parameters", "parametersSubscribe"},
      session_id_, namespace_));
  std::vector<const Channel*> visible;
  for (const auto& [topic, entry] : channels_) {
    if (allowed(client, Access::Read, topic)) visible.push_back(&entry.channel);
  }
  client.send(advertise(visible));
  advertise_frames();
  std::vector<std::string> services;
  for (const auto& [name, service] : services_) {
    if (allowed(client, Access::Call, name)) services.push_back(service->advertisement());
  }
  if (!services.empty()) client.send(advertise_services(services));
}

std::shared_ptr<ViewService> Server::service(std::uint32_t id) const {
  const auto name = service_of_id_.find(id);
  return name == service_of_id_.end() ? nullptr : services_.at(name->second);
}

const ChannelEntry* Server::channel(std::uint32_t id) const {
  const auto topic = topic_of_channel_.find(id);
  return topic == topic_of_channel_.end() ? nullptr : &channels_.at(topic->second);
}

const ChannelEntry* Server::channel_of_topic(const std::string& topic) const {
  const auto it = channels_.find(topic);
  return it == channels_.end() ? nullptr : &it->second;
}

const Channel* Server::frames_channel(std::uint32_t id) const {
  if (!frames_) return nullptr;
  if (id == frames_->dynamic.id) return &frames_->dynamic;
  return id == frames_->statics.id ? &frames_->statics : nullptr;
}

std::function<bool(const std::string&)> Server::frame_filter(const Client& client) const {
  if (!policy_) return {};
  // The feed's thread asks after the client may have gone: the policy is the server's, which
  // outlives the feed, and the peer a copy.
  return [policy = &*policy_, peer = client.peer()](const std::string& child) {
    return policy->allows(peer, Access::Read, frame_policy_name(child));
  };
}

void Server::subscribe(const std::shared_ptr<Subscription>& subscription) {
  if (subscription->frames) {
    subscription->fed_by_thread = true;
    if (frames_->feed) {
      frames_->feed->add(subscription);
    } else {
      frames_->feed = std::make_unique<FramesFeed>(frames_->tree, options_.clock, subscription);
    }
    return;
  }
  ChannelEntry& entry = channels_.at(subscription->topic);
  if (!entry.feed) {
    auto source = std::make_unique<bridge::FrameSource>(
        RawTopic::open_recorded(entry.info, namespace_), namespace_);
    entry.feed = std::make_unique<TopicFeed>(
        std::move(source), codec_for(type_identity_of(entry.info), entry.info.name),
        entry.info.name, options_.clock, io_.unixEventPort);
  }
  subscription->fed_by_thread = entry.feed->on_thread();
  entry.feed->add(subscription);
}

void Server::unsubscribe(const Subscription& subscription) {
  if (subscription.frames) {
    if (!frames_ || !frames_->feed) return;
    frames_->feed->remove(&subscription);
    if (frames_->feed->unsubscribed()) frames_->feed.reset();
    return;
  }
  const auto it = channels_.find(subscription.topic);
  if (it == channels_.end() || !it->second.feed) return;
  it->second.feed->remove(&subscription);
  if (it->second.feed->unsubscribed()) it->second.feed.reset();
}

void Server::discover_services(const std::map<std::string, TopicInfo>& frame_topics) {
  std::set<std::string> present;
  /// (name, advertisement) of each service that came.
  std::vector<std::pair<std::string, std::string>> added;
  // A node's parameter service carries writes the view makes itself, under the policy's `param`
  // verb: a client does not call it.
  const std::string parameter_services = param_service_name("");
  for (const ServiceInfo& info : list_services(namespace_)) {
    if (info.name.starts_with(parameter_services)) continue;
    // Requests go out on `<service>.request`, once a server (or a client) made it.
    const auto request = frame_topics.find(info.name + ".request");
    if (info.servers == 0 || request == frame_topics.end()) continue;
    const auto existing = services_.find(info.name);
    if (existing != services_.end()) {
      // Served again with another type: unadvertised below, advertised anew next time.
      if (existing->second->info().fingerprint == info.fingerprint) present.insert(info.name);
      continue;
    }
    // A reply topic of the service shows the response's type; else the first answer does.
    std::optional<TopicInfo> response;
    const std::string replies = info.name + ".response.";
    for (auto it = frame_topics.lower_bound(replies);
         it != frame_topics.end() && it->first.starts_with(replies); ++it) {
      response = it->second;
      break;
    }
    const auto [id, fresh] =
        service_ids_.try_emplace(std::make_pair(info.name, info.fingerprint), next_service_id_);
    try {
      auto service =
          std::make_shared<ViewService>(id->second, info, request->second, response, namespace_);
      if (fresh) ++next_service_id_;
      added.emplace_back(info.name, service->advertisement());
      service_of_id_[id->second] = info.name;
      services_.emplace(info.name, std::move(service));
      present.insert(info.name);
    } catch (const std::exception& error) {
      if (fresh) service_ids_.erase(id);
      if (uncallable_.insert(info.name + " " + std::to_string(info.fingerprint)).second) {
        std::fprintf(stderr, "horus-view: service '%s' is not offered: %s\n", info.name.c_str(),
                     error.what());
      }
    }
  }
  /// (name, id) of each service that went.
  std::vector<std::pair<std::string, std::uint32_t>> removed;
  for (auto it = services_.begin(); it != services_.end();) {
    if (present.count(it->first) != 0) {
      ++it;
      continue;
    }
    removed.emplace_back(it->first, it->second->id());
    service_of_id_.erase(it->second->id());
    it = services_.erase(it);
  }
  if (added.empty() && removed.empty()) return;
  for (const auto& [client_id, client] : clients_) {
    std::vector<std::uint32_t> gone;
    for (const auto& [name, id] : removed) {
      if (allowed(*client, Access::Call, name)) gone.push_back(id);
    }
    if (!gone.empty()) client->send(unadvertise_services(gone));
    std::vector<std::string> came;
    for (const auto& [name, advertisement] : added) {
      if (allowed(*client, Access::Call, name)) came.push_back(advertisement);
    }
    if (!came.empty()) client->send(advertise_services(came));
  }
}

void Server::watch_graph(Client& client, bool watch) {
  if (!watch) {
    graph_watchers_.erase(client.id());
    return;
  }
  if (!graph_watchers_.insert(client.id()).second) return;
  // The whole graph for the new watcher; the others are told what changed since their last.
  ConnectionGraph graph = read_graph(namespace_);
  client.send(connection_graph_update({}, visible_graph(client, graph)));
  if (graph != graph_) {
    for (const std::uint64_t id : graph_watchers_) {
      if (id != client.id()) send_graph_update(*clients_.at(id), graph);
    }
  }
  graph_ = std::move(graph);
}

ConnectionGraph Server::visible_graph(const Client& client, const ConnectionGraph& graph) const {
  if (!policy_) return graph;
  const auto keep = [&](const std::map<std::string, std::set<std::string>>& all, Access access) {
    std::map<std::string, std::set<std::string>> kept;
    for (const auto& [name, ids] : all) {
      if (allowed(client, access, name)) kept.emplace(name, ids);
    }
    return kept;
  };
  return ConnectionGraph{keep(graph.publishers, Access::Read),
                         keep(graph.subscribers, Access::Read),
                         keep(graph.providers, Access::Call)};
}

void Server::send_graph_update(Client& client, const ConnectionGraph& graph) const {
  const ConnectionGraph before = visible_graph(client, graph_);
  const ConnectionGraph after = visible_graph(client, graph);
  if (before != after) client.send(connection_graph_update(before, after));
}

kj::Promise<void> Server::discover_forever() {
  return timer().afterDelay(options_.discovery_interval.count() * kj::MILLISECONDS).then([this] {
    discover();
    return discover_forever();
  });
}

kj::Promise<void> Server::send_time_forever() {
  return timer().afterDelay(kTimeInterval.count() * kj::MILLISECONDS).then([this] {
    const std::uint64_t now = view_time_ns(options_.clock);
    for (const auto& [id, client] : clients_) client->send_time(now);
    return send_time_forever();
  });
}

kj::Promise<void> Server::send_parameter_updates_forever() {
  return timer().afterDelay(kParameterCheckInterval.count() * kj::MILLISECONDS).then([this] {
    const std::vector<ParamInfo> changed = parameters_.changed();
    if (!changed.empty()) {
      for (const auto& [id, client] : clients_) client->parameters_changed(changed);
    }
    return send_parameter_updates_forever();
  });
}

void Server::discover() {
  parameters_.discover();
  discover_frames();
  advertise_frames();
  std::vector<TopicInfo> topics = list_topics(namespace_);
  std::map<std::string, TopicInfo> frame_topics;
  std::set<std::string> present;
  std::vector<const Channel*> added;
  for (TopicInfo& info : topics) {
    // Service frames and registrations are a service's, not topics of their own; a topic only
    // notifiers opened has no type yet.
    if (info.type_name.empty() || !info.error.empty()) continue;
    if (is_service_type(info.type_name)) {
      frame_topics.emplace(info.name, info);
      continue;
    }
    const auto existing = channels_.find(info.name);
    if (existing != channels_.end() && existing->second.info.fingerprint == info.fingerprint &&
        existing->second.info.type_name == info.type_name) {
      present.insert(info.name);
      continue;
    }
    if (existing != channels_.end()) continue;  // retyped: unadvertised below, then again
    const std::string key = info.name + " " + info.type_name;
    ChannelSchema schema;
    try {
      schema = codec_for(type_identity_of(info), info.name)->schema();
    } catch (const std::exception& error) {
      if (unviewable_.insert(key).second) {
        std::fprintf(stderr, "horus-view: topic '%s' (%s) is not shown: %s\n", info.name.c_str(),
                     info.type_name.c_str(), error.what());
      }
      continue;
    }
    present.insert(info.name);
    const auto id_key = std::make_tuple(info.name, info.type_name, info.fingerprint);
    auto [id, fresh] = channel_ids_.try_emplace(id_key, next_channel_id_);
    if (fresh) ++next_channel_id_;
    ChannelEntry entry;
    entry.channel = Channel{id->second, info.name, std::move(schema)};
    entry.info = std::move(info);
    topic_of_channel_[id->second] = entry.info.name;
    auto [it, inserted] = channels_.emplace(entry.info.name, std::move(entry));
    added.push_back(&it->second.channel);
  }
  /// (topic, id) of each channel that went.
  std::vector<std::pair<std::string, std::uint32_t>> removed;
  for (auto it = channels_.begin(); it != channels_.end();) {
    if (present.count(it->first) != 0) {
      ++it;
      continue;
    }
    const std::uint32_t id = it->second.channel.id;
    for (const auto& [client_id, client] : clients_) client->forget_channel(id);
    removed.emplace_back(it->first, id);
    topic_of_channel_.erase(id);
    it = channels_.erase(it);
  }
  counters_.channels.store(channels_.size(), std::memory_order_relaxed);
  discover_services(frame_topics);
  if (!graph_watchers_.empty()) {
    ConnectionGraph graph = read_graph(namespace_);
    if (graph != graph_) {
      for (const std::uint64_t id : graph_watchers_) send_graph_update(*clients_.at(id), graph);
    }
    graph_ = std::move(graph);
  }
  if (added.empty() && removed.empty()) return;
  for (const auto& [client_id, client] : clients_) {
    std::vector<std::uint32_t> gone;
    for (const auto& [topic, id] : removed) {
      if (allowed(*client, Access::Read, topic)) gone.push_back(id);
    }
    if (!gone.empty()) client->send(unadvertise(gone));
    std::vector<const Channel*> visible;
    for (const Channel* channel : added) {
      if (allowed(*client, Access::Read, channel->topic)) visible.push_back(channel);
    }
    if (!visible.empty()) client->send(advertise(visible));
  }
}

void Server::discover_frames() {
  if (frames_ || !frame_tree_exists(namespace_)) return;
  try {
    frames_ = std::make_unique<FramesChannels>(namespace_);
  } catch (const FrameError& error) {
    if (frames_refused_ != error.what()) {
      frames_refused_ = error.what();
      std::fprintf(stderr, "horus-view: the frames are not shown: %s\n", error.what());
    }
    return;
  }
  frames_->dynamic =
      Channel{next_channel_id_++, std::string(kFramesTopic), frame_transform_schema()};
  frames_->statics =
      Channel{next_channel_id_++, std::string(kStaticFramesTopic), frame_transform_schema()};
}

void Server::advertise_frames() {
  if (!frames_) return;
  // Read once per look, and only while a client with a policy waits for a frame it may read.
  std::optional<std::vector<FrameInfo>> held;
  for (const auto& [id, client] : clients_) {
    if (client->frames_advertised()) continue;
    if (policy_) {
      if (!held) held = frames_->tree.frames(false);
      const bool reads_one = std::any_of(held->begin(), held->end(), [&](const FrameInfo& frame) {
        return !frame.parent.empty() &&
               allowed(*client, Access::Read, frame_policy_name(frame.name));
      });
      if (!reads_one) continue;
    }
    client->send(advertise({&frames_->dynamic, &frames_->statics}));
    client->set_frames_advertised();
  }
}

kj::Promise<void> Server::serve_page(kj::HttpMethod method, kj::StringPtr url,
                                     kj::HttpService::Response& response) {
  std::string_view path(url.cStr(), url.size());
  path = path.substr(0, path.find_first_of("?#"));  // ?token=... is the page's own
  if (path == "/") path = "/index.html";
  const auto files = page_files();
  const auto file = std::find_if(files.begin(), files.end(),
                                 [&](const PageFile& one) { return one.path == path; });
  kj::HttpHeaders reply(*headers_);
  std::string_view body;
  kj::uint code = 200;
  kj::StringPtr status_text = "OK";
  if (method != kj::HttpMethod::GET && method != kj::HttpMethod::HEAD) {
    code = 405;
    status_text = "Method Not Allowed";
    body = "horus-view serves its page to GET, and the Foxglove WebSocket protocol\n";
    reply.set(kj::HttpHeaderId::CONTENT_TYPE, "text/plain; charset=utf-8");
  } else if (file == files.end()) {
    code = 404;
    status_text = "Not Found";
    body =
        "no such file; horus-view serves its page at / and the Foxglove WebSocket protocol "
        "(subprotocols foxglove.websocket.v1, foxglove.sdk.v1)\n";
    reply.set(kj::HttpHeaderId::CONTENT_TYPE, "text/plain; charset=utf-8");
  } else {
    body = file->content;
    reply.set(kj::HttpHeaderId::CONTENT_TYPE,
              kj::heapString(file->content_type.data(), file->content_type.size()));
  }
  // The page's files are compiled in: they outlive the write.
  auto stream = response.send(code, status_text, reply, body.size());
  if (method == kj::HttpMethod::HEAD) return kj::READY_NOW;
  auto written = stream->write(body.data(), body.size());
  return written.attach(kj::mv(stream));
}

kj::Promise<void> Server::accept(kj::HttpMethod method, kj::StringPtr url,
                                 const kj::HttpHeaders& headers,
                                 kj::HttpService::Response& response, const std::string& address,
                                 const std::optional<std::string>& certificate) {
  const auto refuse = [&](kj::uint code, kj::StringPtr status_text, const std::string& why) {
    kj::HttpHeaders reply(*headers_);
    reply.set(kj::HttpHeaderId::CONTENT_TYPE, "text/plain; charset=utf-8");
    auto body = kj::heapString(why.c_str());
    auto stream = response.send(code, status_text, reply, body.size());
    auto written = stream->write(body.begin(), body.size());
    return written.attach(kj::mv(stream), kj::mv(body));
  };
  // The page holds no data of the robot: it is served to anyone, and connects with its URL's token.
  if (!headers.isWebSocket()) return serve_page(method, url, response);
  std::string peer;
  if (policy_) {
    std::string why;
    const std::optional<std::string> who = authenticate(url, certificate, why);
    if (!who) {
      std::fprintf(stderr, "horus-view: refused a client (%s): %s\n", address.c_str(), why.c_str());
      return refuse(401, "Unauthorized",
                    "horus-view: " + why +
                        "; connect with ?token=TOKEN in the URL, or with a client certificate of "
                        "this server's CA\n");
    }
    if (!policy_->knows(*who)) {
      std::fprintf(stderr, "horus-view: refused %s (%s): no policy line names it\n", who->c_str(),
                   address.c_str());
      return refuse(403, "Forbidden", "horus-view: no policy line names peer '" + *who + "'\n");
    }
    peer = *who;
  }
  const kj::StringPtr offered = headers.get(protocol_header_).orDefault("");
  const std::optional<std::string> chosen =
      choose_subprotocol(std::string_view(offered.cStr(), offered.size()));
  if (!chosen) {
    return refuse(
        400, "Bad Request",
        "horus-view speaks the WebSocket subprotocols foxglove.websocket.v1 and "
        "foxglove.sdk.v1; the client offered " +
            (offered.size() == 0 ? std::string("none") : "'" + std::string(offered.cStr()) + "'") +
            "\n");
  }
  kj::HttpHeaders reply(*headers_);
  reply.set(protocol_header_, kj::heapString(chosen->c_str()));
  auto client =
      kj::heap<Client>(*this, response.acceptWebSocket(reply), *chosen, address, std::move(peer));
  auto session = client->run();
  return session.attach(kj::mv(client)).catch_([](kj::Exception&&) {
    // A connection that broke or was dropped ends its session; nothing else to do.
  });
}

std::string Server::status_json() const {
  std::string clients;
  for (const auto& [id, client] : clients_) {
    if (!clients.empty()) clients += ", ";
    clients += client->status_json();
  }
  return "\"namespace\": " + json_string(namespace_) + ", \"listen\": " +
         json_string((tls_ ? "wss://" : "ws://") + url_host(options_.listen_address) + ":" +
                     std::to_string(port_) + "/") +
         ", \"topic_wait\": " +
         (topic_wait() == TopicWait::EventLoop ? "\"event_loop\"" : "\"reader_thread\"") +
         ", \"clients\": [" + clients + "]";
}

}  // namespace

}  // namespace view

// ---------------------------------------------------------------------------------------------

struct LiveView::State {
  LiveViewOptions options;
  std::function<void(const std::string&)> on_stopped;
  /// Read by start(), handed to the server.
  view::AccessSetup access;
  view::Counters counters;
  std::atomic<std::uint16_t> port{0};
  std::thread thread;
  std::mutex mutex;
  /// The loop's, while it runs: how other threads reach it.
  kj::Own<const kj::Executor> executor;
  kj::Own<kj::CrossThreadPromiseFulfiller<void>> stop;
  /// The loop thread's own (read only there).
  view::Server* server = nullptr;

  void run(std::promise<std::string>& ready);
};

void LiveView::State::run(std::promise<std::string>& ready) {
  bool started = false;
  const auto failed = [&](const std::string& why) {
    if (!started) {
      ready.set_value("horus-view: cannot serve on " + options.listen_address + ":" +
                      std::to_string(options.port) + ": " + why);
    } else {
      std::fprintf(stderr, "horus-view: stopped: %s\n", why.c_str());
      if (on_stopped) on_stopped(why);
    }
  };
  try {
    kj::AsyncIoContext io = kj::setupAsyncIo();
    view::Server served(options, std::move(access), io, counters);
    auto stopped = kj::newPromiseAndCrossThreadFulfiller<void>();
    {
      const std::lock_guard lock(mutex);
      executor = kj::getCurrentThreadExecutor().addRef();
      stop = kj::mv(stopped.fulfiller);
    }
    KJ_DEFER({
      server = nullptr;
      const std::lock_guard lock(mutex);
      executor = nullptr;
      stop = nullptr;
    });
    server = &served;
    port.store(served.port());
    started = true;
    ready.set_value({});
    served.run().exclusiveJoin(kj::mv(stopped.promise)).wait(io.waitScope);
  } catch (const kj::Exception& error) {
    failed(error.getDescription().cStr());
  } catch (const std::exception& error) {
    failed(error.what());
  }
}

LiveView::LiveView(LiveViewOptions options, std::function<void(const std::string&)> on_stopped)
    : state_(std::make_unique<State>()) {
  state_->options = std::move(options);
  state_->on_stopped = std::move(on_stopped);
}

LiveView::~LiveView() { stop(); }

void LiveView::start() {
  if (state_->thread.joinable()) throw Error("horus::LiveView: started already");
  try {
    detail::check_live_view(state_->options);
    state_->access = view::load_access(state_->options);
  } catch (const Error& error) {
    throw Error(std::string("horus-view: ") + error.what());
  }
  // Frames of pool-backed topics (Image, PointCloud, ...) are read with their blocks' data.
  enable_pool_frames();
  std::promise<std::string> ready;
  auto outcome = ready.get_future();
  state_->thread = std::thread([this, &ready] { state_->run(ready); });
  const std::string error = outcome.get();
  if (!error.empty()) {
    state_->thread.join();
    throw Error(error);
  }
}

void LiveView::stop() {
  {
    const std::lock_guard lock(state_->mutex);
    if (state_->stop) state_->stop->fulfill();
  }
  if (state_->thread.joinable()) state_->thread.join();
}

std::uint16_t LiveView::port() const noexcept { return state_->port.load(); }

LiveViewCounters LiveView::counters() const {
  const view::Counters& counted = state_->counters;
  LiveViewCounters out;
  out.clients = counted.clients.load();
  out.clients_served = counted.clients_served.load();
  out.channels = counted.channels.load();
  out.messages_sent = counted.messages_sent.load();
  out.messages_dropped = counted.messages_dropped.load();
  out.messages_published = counted.messages_published.load();
  out.publishes_refused = counted.publishes_refused.load();
  return out;
}

std::string LiveView::status_json() const {
  kj::Own<const kj::Executor> executor;
  {
    const std::lock_guard lock(state_->mutex);
    if (state_->executor) executor = state_->executor->addRef();
  }
  const std::string stopped = "\"clients\": []";
  std::string served = stopped;
  if (executor) {
    // On the loop, which owns the clients; a loop that ended meanwhile has none.
    KJ_IF_MAYBE (error, kj::runCatchingExceptions([&] {
                   served = executor->executeSync([this, &stopped] {
                     return state_->server != nullptr ? state_->server->status_json() : stopped;
                   });
                 })) {
      served = stopped;
    }
  }
  const LiveViewCounters counted = counters();
  return "{\"pid\": " + std::to_string(::getpid()) + ", " + served +
         ", \"counters\": {\"clients\": " + std::to_string(counted.clients) +
         ", \"clients_served\": " + std::to_string(counted.clients_served) +
         ", \"channels\": " + std::to_string(counted.channels) +
         ", \"messages_sent\": " + std::to_string(counted.messages_sent) +
         ", \"messages_dropped\": " + std::to_string(counted.messages_dropped) +
         ", \"messages_published\": " + std::to_string(counted.messages_published) +
         ", \"publishes_refused\": " + std::to_string(counted.publishes_refused) + "}}\n";
}

}  // namespace horus
