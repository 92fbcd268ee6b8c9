// `horus-remote serve`: the robot's end. Each connection that passes mutual TLS and names a
// peer the policy knows gets a Session of its own, limited to what the policy allows that peer.
#include <algorithm>
#include <cstdio>
#include <map>

#include "horus/service_registry.hpp"
#include "link.hpp"
#include "remote.hpp"
#include "services.hpp"

namespace horus::remote {

namespace {

/// Outstanding calls a peer may have before its connection stops reading from it: 256 KiB of
/// call messages (Cap'n Proto counts words).
constexpr std::size_t kFlowLimitWords = (std::size_t{256} << 10) / sizeof(capnp::word);
constexpr std::uint32_t kLargestQueue = 1024;
/// A peer's calls (not its streams) run at most this often on average, after a burst of
/// kCallBurst / kCallSpacing calls.
constexpr kj::Duration kCallSpacing = 1 * kj::MILLISECONDS;
constexpr kj::Duration kCallBurst = 100 * kj::MILLISECONDS;

std::string hex(std::uint64_t value) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

/// A subscription of a peer: lasts while the peer holds it and its stream works.
class SubscriptionImpl final : public wire::Subscription::Server {
 public:
  SubscriptionImpl(kj::Own<Forwarder> forwarder, std::string label)
      : forwarder_(kj::mv(forwarder)),
        task_(forwarder_->run().eagerlyEvaluate([label](kj::Exception&& e) {
          say("%s ended: %s", label.c_str(), e.getDescription().cStr());
        })) {}

 protected:
  kj::Promise<void> stats(StatsContext context) override {
    context.getResults().setSent(forwarder_->sent());
    context.getResults().setDropped(forwarder_->dropped());
    return kj::READY_NOW;
  }

 private:
  kj::Own<Forwarder> forwarder_;
  /// Declared last: cancelled before the forwarder it runs is destroyed.
  kj::Promise<void> task_;
};

class SessionImpl final : public wire::Session::Server {
 public:
  SessionImpl(const ServeOptions& options, std::string peer, LimitedMessageStream& messages,
              kj::Timer& timer)
      : options_(options),
        peer_(std::move(peer)),
        messages_(messages),
        timer_(timer),
        next_call_(timer.now()) {}

 protected:
  kj::Promise<void> topics(TopicsContext context) override {
    return throttle().then([this, context]() mutable { return answer_topics(context); });
  }

  kj::Promise<void> answer_topics(TopicsContext context) {
    std::vector<TopicInfo> visible;
    for (TopicInfo& info : list_topics(options_.namespace_name)) {
      if (!info.type_name.empty() && info.error.empty() && !is_service_topic(info) &&
          (allows(Access::Read, info.name) || allows(Access::Write, info.name))) {
        visible.push_back(std::move(info));
      }
    }
    auto list = context.getResults().initTopics(static_cast<unsigned>(visible.size()));
    for (unsigned i = 0; i < visible.size(); ++i) {
      describe(visible[i], list[i]);
      list[i].setMayRead(allows(Access::Read, visible[i].name));
      list[i].setMayWrite(allows(Access::Write, visible[i].name));
    }
    return kj::READY_NOW;
  }

  kj::Promise<void> subscribe(SubscribeContext context) override {
    return throttle().then([this, context]() mutable { return answer_subscribe(context); });
  }

  kj::Promise<void> answer_subscribe(SubscribeContext context) {
    const auto params = context.getParams();
    const std::string name = params.getTopic();
    if (!allows(Access::Read, name)) {
      refuse(denied("read topic", name));
    }
    const TopicInfo info = find(name);
    if (info.type_name != params.getType().cStr() || info.fingerprint != params.getFingerprint()) {
      refuse("topic '" + name + "' is " + info.type_name + " (fingerprint " +
             hex(info.fingerprint) + ") on the robot, not " + params.getType().cStr() +
             " (fingerprint " + hex(params.getFingerprint()) + ")");
    }
    const std::uint32_t queue = std::clamp(params.getQueue(), 1U, kLargestQueue);
    const std::string label = "topic " + name + " to " + peer_;
    auto forwarder =
        kj::heap<Forwarder>(opened(info), params.getSink(), queue, label, options_.namespace_name);
    say("%s subscribed to %s", peer_.c_str(), name.c_str());
    context.getResults().setSubscription(kj::heap<SubscriptionImpl>(kj::mv(forwarder), label));
    return kj::READY_NOW;
  }

  kj::Promise<void> services(ServicesContext context) override {
    return throttle().then([this, context]() mutable { return answer_services(context); });
  }

  kj::Promise<void> answer_services(ServicesContext context) {
    const std::vector<TopicInfo> topics = list_topics(options_.namespace_name);
    std::vector<std::pair<horus::ServiceInfo, TopicInfo>> live;
    for (horus::ServiceInfo& service : list_services(options_.namespace_name)) {
      const auto request = std::find_if(topics.begin(), topics.end(), [&](const TopicInfo& t) {
        return t.name == service.name + ".request" && !t.type_name.empty();
      });
      if (service.servers > 0 && request != topics.end() && allows(Access::Call, service.name)) {
        // Its requests arrive in calls, read before they are looked at.
        messages_.make_room(request->max_message_size);
        live.emplace_back(std::move(service), *request);
      }
    }
    auto list = context.getResults().initServices(static_cast<unsigned>(live.size()));
    for (unsigned i = 0; i < live.size(); ++i) {
      const auto& [service, request] = live[i];
      list[i].setName(service.name);
      describe(request, list[i].initRequest());
      list[i].setRequestType(service.request_type);
      list[i].setResponseType(service.response_type);
      list[i].setFingerprint(service.fingerprint);
    }
    return kj::READY_NOW;
  }

  kj::Promise<void> call(CallContext context) override {
    return throttle().then([this, context]() mutable { return answer_call(context); });
  }

  kj::Promise<void> answer_call(CallContext context) {
    const auto params = context.getParams();
    const std::string name = params.getService();
    if (!allows(Access::Call, name)) {
      refuse(denied("call service", name));
    }
    std::unique_ptr<ServiceRelay>& relay = relays_[name];
    if (!relay) {
      const std::optional<TopicInfo> request = existing(name + ".request");
      if (!request) {  // no server ever ran here
        relays_.erase(name);
        auto failure = context.getResults().initFailure();
        failure.setKind(wire::CallFailure::Kind::NO_SERVER);
        failure.setText("no server for " + name + " on the robot");
        return kj::READY_NOW;
      }
      try {
        relay = std::make_unique<ServiceRelay>(name, *request, topic_info(params.getResponse()),
                                               options_.namespace_name);
      } catch (const std::exception& e) {
        relays_.erase(name);
        refuse(e.what());
      }
    }
    const capnp::Data::Reader frame = params.getRequest();
    const auto timeout =
        std::chrono::milliseconds(std::clamp(params.getTimeoutMs(), 1U, kLongestCallMs));
    return relay
        ->call(std::vector<std::byte>(reinterpret_cast<const std::byte*>(frame.begin()),
                                      reinterpret_cast<const std::byte*>(frame.end())),
               timeout)
        .then([context](ServiceRelay::Outcome&& outcome) mutable {
          auto results = context.getResults();
          if (outcome.kind != wire::CallFailure::Kind::NONE) {
            auto failure = results.initFailure();
            failure.setKind(outcome.kind);
            failure.setText(outcome.failure);
            return;
          }
          results.setResponse(kj::arrayPtr(
              reinterpret_cast<const capnp::byte*>(outcome.answer.data()), outcome.answer.size()));
        });
  }

  kj::Promise<void> publish(PublishContext context) override {
    return throttle().then([this, context]() mutable { return answer_publish(context); });
  }

  kj::Promise<void> answer_publish(PublishContext context) {
    const TopicInfo info = topic_info(context.getParams().getInfo());
    if (!allows(Access::Write, info.name)) {
      refuse(denied("write topic", info.name));
    }
    auto sink = kj::heap<TopicSink>(opened(info), "topic " + info.name + " from " + peer_,
                                    options_.namespace_name);
    messages_.make_room(sink->largest_message());
    say("%s publishes to %s", peer_.c_str(), info.name.c_str());
    context.getResults().setSink(kj::mv(sink));
    return kj::READY_NOW;
  }

 private:
  /// Spaces a peer's calls kCallSpacing apart once it has used its burst: a flood of calls waits
  /// (and, past the flow limit, is not even read) instead of taking the event loop from the
  /// other peers.
  kj::Promise<void> throttle() {
    const kj::TimePoint now = timer_.now();
    next_call_ = std::max(next_call_, now - kCallBurst) + kCallSpacing;
    if (next_call_ <= now) return kj::READY_NOW;
    return timer_.atTime(next_call_);
  }

  bool allows(Access access, const std::string& name) const {
    return options_.policy.allows(peer_, access, name);
  }

  /// `what`: "read topic", "write topic" or "call service".
  std::string denied(const char* what, const std::string& name) const {
    say("refused to let %s %s %s: not in the policy", peer_.c_str(), what, name.c_str());
    return "peer '" + peer_ + "' may not " + what + " '" + name + "'";
  }

  std::optional<TopicInfo> existing(const std::string& name) const {
    for (TopicInfo& info : list_topics(options_.namespace_name)) {
      if (info.name == name && !info.type_name.empty() && info.error.empty()) {
        return std::move(info);
      }
    }
    return std::nullopt;
  }

  TopicInfo find(const std::string& name) const {
    if (std::optional<TopicInfo> info = existing(name)) return std::move(*info);
    refuse("no topic '" + name + "' on the robot");
  }

  std::unique_ptr<detail::ErasedTopic> opened(const TopicInfo& info) const {
    try {
      return open_topic(info, options_.namespace_name);
    } catch (const std::exception& e) {
      refuse(e.what());
    }
  }

  const ServeOptions& options_;
  std::string peer_;
  /// The connection's: raised for what this peer may write or call.
  LimitedMessageStream& messages_;
  kj::Timer& timer_;
  /// When this peer's next call may run (throttle()).
  kj::TimePoint next_call_;
  /// Per service the peer called: destroyed (each thread joined) with the session.
  std::map<std::string, std::unique_ptr<ServiceRelay>> relays_;
};

/// One authenticated peer's RPC connection.
struct Connection {
  Connection(kj::Own<kj::AsyncIoStream> stream_, const ServeOptions& options,
             const std::string& peer, kj::Timer& timer)
      : stream(kj::mv(stream_)),
        messages(*stream),
        network(messages, capnp::rpc::twoparty::Side::SERVER,
                LimitedMessageStream::network_options()),
        rpc(capnp::makeRpcServer(network, kj::heap<SessionImpl>(options, peer, messages, timer))) {
    rpc.setFlowLimit(kFlowLimitWords);
  }
  kj::Own<kj::AsyncIoStream> stream;
  LimitedMessageStream messages;
  capnp::TwoPartyVatNetwork network;
  capnp::RpcSystem<capnp::rpc::twoparty::VatId> rpc;
};

class Server final : public kj::TaskSet::ErrorHandler {
 public:
  Server(const ServeOptions& options, kj::Own<kj::ConnectionReceiver> listener,
         kj::Maybe<kj::TlsContext&> tls, kj::Timer& timer)
      : options_(options),
        listener_(kj::mv(listener)),
        tls_(tls),
        timer_(timer),
        connections_(*this) {}

  kj::Promise<void> accept_next() {
    return listener_->acceptAuthenticated().then([this](kj::AuthenticatedStream&& stream) {
      admit(kj::mv(stream));
      return accept_next();
    });
  }

  void taskFailed(kj::Exception&& exception) override {
    say("a connection failed: %s", exception.getDescription().cStr());
  }

 private:
  void admit(kj::AuthenticatedStream stream) {
    const std::string address = address_of(*stream.peerIdentity);
    kj::Promise<kj::AuthenticatedStream> secured = nullptr;
    KJ_IF_MAYBE (tls, tls_) {
      secured = tls->wrapServer(kj::mv(stream));
    } else {
      secured = kj::Promise<kj::AuthenticatedStream>(kj::mv(stream));
    }
    connections_.add(secured.then(
        [this, address](kj::AuthenticatedStream&& peer) { return serve(kj::mv(peer), address); },
        [address](kj::Exception&& exception) -> kj::Promise<void> {
          say("refused %s (no name: it presented no certificate of our CA): %s", address.c_str(),
              exception.getDescription().cStr());
          return kj::READY_NOW;
        }));
  }

  kj::Promise<void> serve(kj::AuthenticatedStream peer, const std::string& address) {
    const std::string name =
        tls_ == nullptr
            ? std::string(kInsecurePeer)
            : std::string(
                  kj::downcast<kj::TlsPeerIdentity>(*peer.peerIdentity).getCommonName().cStr());
    if (!options_.policy.knows(name)) {
      say("refused %s at %s: no policy line names it", name.c_str(), address.c_str());
      return kj::READY_NOW;
    }
    say("%s connected from %s", name.c_str(), address.c_str());
    auto connection = kj::heap<Connection>(kj::mv(peer.stream), options_, name, timer_);
    return connection->network.onDisconnect().attach(kj::mv(connection)).then([name, address] {
      say("%s at %s disconnected", name.c_str(), address.c_str());
    });
  }

  const ServeOptions& options_;
  kj::Own<kj::ConnectionReceiver> listener_;
  kj::Maybe<kj::TlsContext&> tls_;
  kj::Timer& timer_;
  kj::TaskSet connections_;
};

}  // namespace

int serve(const ServeOptions& options) {
  EventLoop loop;
  kj::Own<kj::TlsContext> tls;
  kj::Maybe<Credentials> credentials;
  if (options.insecure) {
    say("WARNING: --insecure: plain TCP, no authentication, no encryption; every peer is '%s'",
        kInsecurePeer);
  } else {
    credentials = load_credentials(options.certs, options.name);
    tls = tls_context(KJ_ASSERT_NONNULL(credentials), loop.io.provider->getTimer());
  }
  auto address =
      loop.io.provider->getNetwork().parseAddress(options.listen).wait(loop.io.waitScope);
  kj::Own<kj::ConnectionReceiver> listener = address->listen();
  const unsigned port = listener->getPort();
  Server server(options, kj::mv(listener),
                tls ? kj::Maybe<kj::TlsContext&>(*tls) : kj::Maybe<kj::TlsContext&>(nullptr),
                loop.io.provider->getTimer());
  std::printf("serving namespace %s on port %u\n", options.namespace_name.c_str(), port);
  std::fflush(stdout);
  loop.run_until_stopped(server.accept_next(), options.namespace_name, "serve");
  return 0;
}

}  // namespace horus::remote
