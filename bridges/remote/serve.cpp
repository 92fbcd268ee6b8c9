// `horus-remote serve`: the robot's end. Each connection that passes mutual TLS and names a
// peer the policy knows gets a Session of its own, limited to what the policy allows that peer.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <thread>

#include "horus/bridge/identity.hpp"
#include "horus/bridge/peer_policy.hpp"
#include "horus/bridge/topic_policy.hpp"
#include "horus/params.hpp"
#include "horus/service_registry.hpp"
#include "link.hpp"
#include "remote.hpp"
#include "remote_actions.hpp"
#include "remote_frames.hpp"
#include "remote_params.hpp"
#include "services.hpp"

namespace horus::remote {

using bridge::Access;

namespace {

/// Outstanding calls a peer may have before its connection stops reading from it: 256 KiB of
/// call messages (Cap'n Proto counts words).
constexpr std::size_t kFlowLimitWords = (std::size_t{256} << 10) / sizeof(capnp::word);
constexpr std::uint32_t kLargestQueue = 1024;
/// A peer's calls (not its streams) run at most this often on average, after a burst of
/// kCallBurst / kCallSpacing calls.
constexpr kj::Duration kCallSpacing = 1 * kj::MILLISECONDS;
constexpr kj::Duration kCallBurst = 100 * kj::MILLISECONDS;
/// How long a peer the policy refuses is kept connected to be told why.
/// How often a peer's `params` looks at the stores while it waits for a change, and the longest
/// it waits.
constexpr kj::Duration kParamsLookInterval = 50 * kj::MILLISECONDS;
constexpr std::uint32_t kLongestParamsWaitMs = 10000;
/// Parameter writes of one connection waiting for their owners at once (each waits on a thread).
constexpr int kParamWritesAtOnce = 4;
constexpr kj::Duration kRefusalLinger = 10 * kj::SECONDS;
/// serverGone calls one connection may have waiting at once (each looks every 10 ms).
constexpr int kServerWatchesPerConnection = 64;
/// A peer (by its certificate's name, over all its connections) holds at most this many
/// subscriptions and publishes of one topic, each a handle of the topic, of which a topic has
/// 128 for every process on the robot: a peer cannot take them from local code.
constexpr int kHandlesPerTopic = 4;
/// ... and this many in all: each maps its topic in this process, a subscription runs a thread.
constexpr int kHandlesPerPeer = 64;
/// What the queues of all a peer's subscriptions hold at most, together (the oldest messages
/// are dropped beyond it, as beyond --queue).
constexpr std::size_t kQueuedBytesPerPeer = std::size_t{16} << 20;
/// What the streams of one connection may have sent that the peer has not acknowledged yet,
/// together: as much as a socket's send buffer grows to, so one stream runs as fast as it
/// would alone.
constexpr std::size_t kConnectionWindowBytes = std::size_t{4} << 20;
/// What each message in flight counts for at least: the robot's own record of the call, which
/// a small message's bytes do not cover.
constexpr std::size_t kMessageInFlightBytes = 1024;
/// Connections a peer may have at once (more are refused): a laptop's new connection may come
/// before the robot noticed that its last one was lost.
constexpr int kConnectionsPerPeer = 4;
/// After its first line, a kind of refusal is summed up at most this often.
constexpr kj::Duration kRefusalSummaryInterval = 5 * kj::SECONDS;
/// Refused connections kept to be told why (kRefusalLinger), per certificate name and in all;
/// beyond these a refused connection is closed at once: a peer of our CA that opens connection
/// after connection holds no more of the robot than this.
constexpr int kLingeringPerPeer = 4;
constexpr int kLingeringInAll = 32;

/// A topic's type as every bridge compares it (bridges/core): name and fingerprint.
bridge::TopicIdentity identity(std::string type_name, std::uint64_t fingerprint) {
  return bridge::TopicIdentity{std::move(type_name), fingerprint, {}};
}

/// The refusals of a peer (all its connections, one after another or at once), logged once
/// per kind as they begin and then summed up: a peer that is refused a thousand times a second,
/// or reconnects a thousand times to be refused again, costs the log a line every few seconds.
class Refusals final : private kj::TaskSet::ErrorHandler {
 public:
  Refusals(std::string peer, kj::Timer& timer)
      : peer_(std::move(peer)), timer_(timer), summaries_(*this) {}
  Refusals(const Refusals&) = delete;
  Refusals& operator=(const Refusals&) = delete;
  ~Refusals() {
    for (auto& [kind, seen] : kinds_) summarize(kind, seen);
  }

  /// `what`: what the peer was refused and why ("subscribe to cmd_vel: ...").
  void note(const std::string& kind, const std::string& what) {
    Kind& seen = kinds_[kind];
    seen.last = what;
    if (++seen.count == 1) {
      say("refused to let %s %s (%s; more of this kind are counted)", peer_.c_str(), what.c_str(),
          kind.c_str());
      seen.logged = 1;
      seen.logged_at = timer_.now();
      return;
    }
    if (seen.summary_due) return;
    // Summed up kRefusalSummaryInterval after the kind's last line, whether or not the peer
    // is refused again (or still connected) by then.
    seen.summary_due = true;
    summaries_.add(timer_.atTime(seen.logged_at + kRefusalSummaryInterval).then([this, kind] {
      Kind& due = kinds_[kind];
      due.summary_due = false;
      summarize(kind, due);
    }));
  }

 private:
  struct Kind {
    std::uint64_t count = 0;
    std::uint64_t logged = 0;
    kj::TimePoint logged_at = kj::origin<kj::TimePoint>();
    bool summary_due = false;
    std::string last;
  };

  void summarize(const std::string& kind, Kind& seen) {
    if (seen.count == seen.logged) return;
    say("refused to let %s %llu more times (%s), the last: %s", peer_.c_str(),
        static_cast<unsigned long long>(seen.count - seen.logged), kind.c_str(), seen.last.c_str());
    seen.logged = seen.count;
    seen.logged_at = timer_.now();
  }
  void taskFailed(kj::Exception&&) override {}

  std::string peer_;
  kj::Timer& timer_;
  std::map<std::string, Kind> kinds_;
  /// Last: cancelled before what its continuations use.
  kj::TaskSet summaries_;
};

/// "TYPE (fingerprint F)", or with `size` "TYPE (fingerprint F, N bytes)": one side's type of a
/// topic, as a type mismatch names both. Not bridge::identity_mismatch()'s line: that one names
/// what the other side carries the type as (a DDS type name), and no size.
std::string type_text(const std::string& type, std::uint64_t fingerprint,
                      std::optional<std::size_t> size = std::nullopt) {
  return type + " (fingerprint " + bridge::fingerprint_hex(fingerprint) +
         (size ? ", " + std::to_string(*size) + " bytes" : std::string()) + ")";
}

/// What the messages a connection's streams sent and the peer has not acknowledged yet cost,
/// together. Cap'n Proto's own flow control gives each stream a window of its own: a peer
/// that never acknowledges what 64 streams of small messages send would hold 64 windows'
/// worth of calls, each a record much larger than its message.
class SharedWindow {
 public:
  /// Resolves when the connection has room for more.
  kj::Promise<void> room() {
    if (in_flight_ < kConnectionWindowBytes) return kj::READY_NOW;
    auto paf = kj::newPromiseAndFulfiller<void>();
    waiting_.push_back(kj::mv(paf.fulfiller));
    return kj::mv(paf.promise);
  }
  void take(std::size_t bytes) { in_flight_ += bytes; }
  void give_back(std::size_t bytes) {
    in_flight_ -= bytes;
    while (in_flight_ < kConnectionWindowBytes && !waiting_.empty()) {
      waiting_.front()->fulfill();
      waiting_.pop_front();
    }
  }

 private:
  std::size_t in_flight_ = 0;
  std::deque<kj::Own<kj::PromiseFulfiller<void>>> waiting_;
};

/// A stream's flow control within its connection's SharedWindow.
class SharedWindowStream final : public capnp::RpcFlowController,
                                 private kj::TaskSet::ErrorHandler {
 public:
  explicit SharedWindowStream(std::shared_ptr<SharedWindow> window)
      : window_(std::move(window)), acks_(*this) {}

  kj::Promise<void> send(kj::Own<capnp::OutgoingRpcMessage> message,
                         kj::Promise<void> ack) override {
    const std::size_t cost =
        std::max(message->sizeInWords() * sizeof(capnp::word), kMessageInFlightBytes);
    message->send();
    window_->take(cost);
    ++unacknowledged_;
    acks_.add(ack.then([this, cost] { acknowledged(cost); },
                       [this, cost](kj::Exception&& e) {
                         failure_ = kj::mv(e);
                         acknowledged(cost);
                       }));
    KJ_IF_MAYBE (failure, failure_) {
      return kj::cp(*failure);
    }
    return window_->room();
  }

  kj::Promise<void> waitAllAcked() override {
    KJ_IF_MAYBE (failure, failure_) {
      return kj::cp(*failure);
    }
    if (unacknowledged_ == 0) return kj::READY_NOW;
    auto paf = kj::newPromiseAndFulfiller<void>();
    all_acknowledged_ = kj::mv(paf.fulfiller);
    return kj::mv(paf.promise);
  }

 private:
  void acknowledged(std::size_t cost) {
    window_->give_back(cost);
    if (--unacknowledged_ == 0) {
      KJ_IF_MAYBE (waiting, all_acknowledged_) {
        (*waiting)->fulfill();
        all_acknowledged_ = nullptr;
      }
    }
  }
  void taskFailed(kj::Exception&&) override {}

  std::shared_ptr<SharedWindow> window_;
  std::size_t unacknowledged_ = 0;
  kj::Maybe<kj::Exception> failure_;
  kj::Maybe<kj::Own<kj::PromiseFulfiller<void>>> all_acknowledged_;
  /// Last: cancelled before what its continuations use.
  kj::TaskSet acks_;
};

/// A peer's connection, whose streams share one window (SharedWindow).
class PeerNetwork final : public capnp::TwoPartyVatNetwork {
 public:
  explicit PeerNetwork(capnp::MessageStream& messages)
      : capnp::TwoPartyVatNetwork(messages, capnp::rpc::twoparty::Side::SERVER,
                                  LimitedMessageStream::network_options()) {}

 private:
  kj::Own<capnp::RpcFlowController> newStream() override {
    return kj::heap<SharedWindowStream>(window_);
  }

  std::shared_ptr<SharedWindow> window_ = std::make_shared<SharedWindow>();
};

/// What all connections of one peer (one certificate name) hold of the robot.
struct PeerHoldings {
  PeerHoldings(const std::string& name, kj::Timer& timer)
      : refusals(std::make_shared<Refusals>(name, timer)) {}

  int connections = 0;
  /// Its refused connections being told why.
  int lingering = 0;
  std::map<std::string, int> per_topic;
  int total = 0;
  std::shared_ptr<QueueBudget> budget = std::make_shared<QueueBudget>(kQueuedBytesPerPeer);
  /// Shared with the sinks of the peer's publishes, which may outlive its sessions.
  std::shared_ptr<Refusals> refusals;
  /// The frames the peer set on the robot: never streamed back to it.
  std::shared_ptr<FrameNames> frames_set = std::make_shared<FrameNames>();
};

/// One topic handle of a peer (a subscription or a publish), counted while it lasts.
class HandleLease {
 public:
  HandleLease(std::shared_ptr<PeerHoldings> holdings, std::string topic)
      : holdings_(std::move(holdings)), topic_(std::move(topic)) {
    ++holdings_->per_topic[topic_];
    ++holdings_->total;
  }
  HandleLease(const HandleLease&) = delete;
  HandleLease& operator=(const HandleLease&) = delete;
  ~HandleLease() {
    if (--holdings_->per_topic[topic_] == 0) holdings_->per_topic.erase(topic_);
    --holdings_->total;
  }

 private:
  std::shared_ptr<PeerHoldings> holdings_;
  std::string topic_;
};

/// A subscription of a peer: lasts while the peer holds it and its stream works.
class SubscriptionImpl final : public wire::Subscription::Server {
 public:
  SubscriptionImpl(kj::Own<HandleLease> lease, kj::Own<Forwarder> forwarder, std::string label)
      : lease_(kj::mv(lease)),
        forwarder_(kj::mv(forwarder)),
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
  kj::Own<HandleLease> lease_;
  kj::Own<Forwarder> forwarder_;
  /// Declared last: cancelled before the forwarder it runs is destroyed.
  kj::Promise<void> task_;
};

class SessionImpl final : public wire::Session::Server {
 public:
  SessionImpl(const ServeOptions& options, std::string peer, LimitedMessageStream& messages,
              kj::Timer& timer, std::shared_ptr<PeerHoldings> holdings, ServedFrames& frames)
      : options_(options),
        frames_(frames),
        peer_(std::move(peer)),
        messages_(messages),
        timer_(timer),
        next_call_(timer.now()),
        holdings_(std::move(holdings)),
        refusals_(holdings_->refusals) {}

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
    const std::string what = "subscribe to " + name;
    if (!allows(Access::Read, name)) {
      refuse(denied("read topic", name));
    }
    auto lease = leased(what, name);
    const std::optional<TopicInfo> info = existing(name);
    if (!info) {
      refused("no such topic", what, "no topic '" + name + "' on the robot");
    }
    if (!identity(info->type_name, info->fingerprint)
             .same_type(identity(params.getType(), params.getFingerprint()))) {
      another_type(what, name, type_text(info->type_name, info->fingerprint),
                   type_text(params.getType().cStr(), params.getFingerprint()));
    }
    const std::uint32_t queue = std::clamp(params.getQueue(), 1U, kLargestQueue);
    const std::string label = "topic " + name + " to " + peer_;
    auto forwarder = kj::heap<Forwarder>(opened(what, *info), params.getSink(), queue, label,
                                         options_.namespace_name, holdings_->budget);
    if (announced_.insert("subscribe " + name).second) {
      say("%s subscribed to %s", peer_.c_str(), name.c_str());
    }
    context.getResults().setSubscription(
        kj::heap<SubscriptionImpl>(kj::mv(lease), kj::mv(forwarder), label));
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
      if (const std::optional<TopicInfo> frames =
              reply_topic_type(service.name, options_.namespace_name)) {
        describe(*frames, list[i].initResponse());
      }
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
        relay = std::make_unique<ServiceRelay>(
            name, *request,
            params.hasResponse() ? std::optional(topic_info(params.getResponse())) : std::nullopt,
            options_.namespace_name);
      } catch (const std::exception& e) {
        relays_.erase(name);
        refused("cannot relay", "call " + name, e.what());
      }
    }
    const capnp::Data::Reader frame = params.getRequest();
    const auto timeout =
        std::chrono::milliseconds(std::clamp(params.getTimeoutMs(), 1U, kLongestCallMs));
    relayed_goals_.sent(name,
                        std::span(reinterpret_cast<const std::byte*>(frame.begin()), frame.size()));
    return relay
        ->call(std::vector<std::byte>(reinterpret_cast<const std::byte*>(frame.begin()),
                                      reinterpret_cast<const std::byte*>(frame.end())),
               timeout)
        .then([context](ServiceRelay::Outcome&& outcome) mutable {
          auto results = context.getResults();
          if (outcome.response_type) describe(*outcome.response_type, results.initResponseType());
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

  kj::Promise<void> serverGone(ServerGoneContext context) override {
    return throttle().then([this, context]() mutable { return answer_server_gone(context); });
  }

  kj::Promise<void> answer_server_gone(ServerGoneContext context) {
    const std::string name = context.getParams().getService();
    if (!allows(Access::Call, name)) {
      refuse(denied("call service", name));
    }
    if (*server_watches_ >= kServerWatchesPerConnection) {
      refused("watch limit", "watch the server of " + name,
              "peer '" + peer_ + "' watches " + std::to_string(kServerWatchesPerConnection) +
                  " servers on this connection already, the most it may");
    }
    ++*server_watches_;
    // Ended with the connection, which would otherwise wait for the answer (and keep the
    // session, whose end cancels the goals the connection sent).
    context.allowCancellation();
    return when_server_gone(timer_, name, options_.namespace_name)
        .then([context](std::string why) mutable { context.getResults().setWhy(why); })
        .attach(kj::defer([watches = server_watches_] { --*watches; }));
  }

  kj::Promise<void> params(ParamsContext context) override {
    return throttle().then([this, context]() mutable {
      const auto asked = context.getParams();
      const kj::TimePoint until =
          timer_.now() + std::min(asked.getWaitMs(), kLongestParamsWaitMs) * kj::MILLISECONDS;
      if (!param_view_) {
        param_view_ = std::make_unique<ParamView>(
            [this](const std::string& name) { return allows(Access::Param, name); },
            options_.namespace_name);
      }
      return answer_params(context, asked.getSince(), until);
    });
  }

  /// Answers once what the peer may see of the parameters differs from `since`, or at `until`.
  kj::Promise<void> answer_params(ParamsContext context, std::uint64_t since, kj::TimePoint until) {
    const std::uint64_t generation = param_view_->refresh();
    if (generation == since && timer_.now() < until) {
      return timer_.afterDelay(kParamsLookInterval).then([this, context, since, until]() mutable {
        return answer_params(context, since, until);
      });
    }
    auto results = context.getResults();
    results.setGeneration(generation);
    param_view_->fill(results.initNodes(static_cast<unsigned>(param_view_->node_count())));
    return kj::READY_NOW;
  }

  kj::Promise<void> setParam(SetParamContext context) override {
    return throttle().then([this, context]() mutable { return answer_set_param(context); });
  }

  kj::Promise<void> answer_set_param(SetParamContext context) {
    const auto asked = context.getParams();
    const std::string node = asked.getNode();
    const std::string name = asked.getName();
    const std::string parameter = node + "." + name;
    if (!allows(Access::Param, parameter)) {
      refusals_->note("set parameter: not in the policy",
                      "set parameter " + parameter + ": not in the policy");
      auto results = context.getResults();
      results.setAccepted(false);
      results.setReason("the robot's policy does not let peer '" + peer_ + "' set parameter '" +
                        parameter + "' (no 'param' rule of '" + peer_ + "' matches it)");
      return kj::READY_NOW;
    }
    if (param_writes_->load() >= kParamWritesAtOnce) {
      refused("write limit", "set parameter " + parameter,
              "peer '" + peer_ + "' has " + std::to_string(kParamWritesAtOnce) +
                  " parameter writes waiting already, the most it may");
    }
    ParamSetOptions options;
    options.source = "remote:" + peer_;
    options.namespace_name = options_.namespace_name;
    options.timeout =
        std::chrono::milliseconds(std::clamp(asked.getTimeoutMs(), 1U, kLongestCallMs));
    const auto bytes = asked.getValue();
    std::string value(reinterpret_cast<const char*>(bytes.begin()), bytes.size());
    // set_param() waits for the owner's verdict: on a thread of its own, never the event loop.
    auto outcome = std::make_shared<ParamSetResult>();
    auto done = kj::newPromiseAndCrossThreadFulfiller<void>();
    // Shared: kj's handles may throw from their destructors, which a thread's state may not.
    auto fulfiller =
        std::make_shared<kj::Own<kj::CrossThreadPromiseFulfiller<void>>>(kj::mv(done.fulfiller));
    ++*param_writes_;
    std::thread([outcome, fulfiller, node, name, value = std::move(value), options,
                 writes = param_writes_]() mutable {
      try {
        *outcome = set_param(node, name, value, options);
      } catch (const std::exception& e) {
        *outcome = ParamSetResult{false, e.what(), 0};
      }
      --*writes;
      (*fulfiller)->fulfill();
    }).detach();
    if (announced_.insert("set " + parameter).second) {
      say("%s sets parameter %s", peer_.c_str(), parameter.c_str());
    }
    return done.promise.then([context, outcome]() mutable {
      auto results = context.getResults();
      results.setAccepted(outcome->accepted);
      results.setReason(outcome->reason);
      results.setVersion(outcome->version);
    });
  }

  kj::Promise<void> frames(FramesContext context) override {
    return throttle().then([this, context]() mutable { return answer_frames(context); });
  }

  kj::Promise<void> answer_frames(FramesContext context) {
    const auto params = context.getParams();
    std::vector<std::string> patterns;
    for (const capnp::Text::Reader pattern : params.getPatterns()) patterns.emplace_back(pattern);
    // Counted as a subscription of a topic "@frames" (no topic's name starts with '@').
    auto lease = leased("stream frames", "@frames");
    FrameTree* tree = nullptr;
    try {
      tree = &frames_.tree();
    } catch (const std::exception& e) {
      refused("cannot open", "stream frames", e.what());
    }
    // What the policy and the patterns say of a name does not change: asked once per frame.
    // Asked on the feed's thread, which may outlive this session: nothing of it is used.
    auto carried =
        [policy = &options_.policy, peer = peer_, patterns = std::move(patterns),
         set = holdings_->frames_set,
         known = std::map<std::string, bool, std::less<>>()](std::string_view child) mutable {
          auto found = known.find(child);
          if (found == known.end()) {
            const std::string name(child);
            const bool allowed =
                bridge::any_matches(name, patterns) &&
                policy->allows(peer, Access::Read, std::string(kFramePolicyPrefix) + name);
            found = known.emplace(name, allowed).first;
          }
          return found->second && !set->contains(child);
        };
    const std::string label = "frames to " + peer_;
    auto follower = std::make_unique<FrameFollower>(*tree, kj::mv(carried));
    if (announced_.insert("frames").second) {
      say("%s streams frames", peer_.c_str());
    }
    context.getResults().setSubscription(
        kj::heap<FrameStream>(std::move(follower), params.getSink(), label).attach(kj::mv(lease)));
    return kj::READY_NOW;
  }

  kj::Promise<void> setFrames(SetFramesContext context) override {
    return throttle().then([this, context]() mutable { return answer_set_frames(context); });
  }

  kj::Promise<void> answer_set_frames(SetFramesContext context) {
    const auto params = context.getParams();
    std::set<std::string> named;
    for (const auto& list : {params.getDynamic(), params.getStatics()}) {
      for (const wire::FrameTransform::Reader transform : list) named.insert(transform.getChild());
    }
    // A tree holds no more: what costs the robot per call stays bounded.
    if (named.size() > kMaxFrames) {
      refused("too many frames", "set frames",
              "a call names " + std::to_string(named.size()) + " frames, more than a tree holds (" +
                  std::to_string(kMaxFrames) + ")");
    }
    std::vector<std::pair<std::string, std::string>> refusals;
    std::set<std::string> refused_children;
    FrameSetter* setter = nullptr;
    try {
      setter = &frames_.setter();
    } catch (const std::exception& e) {
      refused("cannot open", "set frames", e.what());
    }
    auto set = [&](wire::FrameTransform::Reader wire_transform, bool is_static) {
      const StampedTransform transform = from_wire(wire_transform);
      // A frame refused once in this call is refused for its other transforms too.
      if (refused_children.count(transform.child) != 0) return;
      const std::string name = std::string(kFramePolicyPrefix) + transform.child;
      if (!allows(Access::Write, name)) {
        refusals_->note("write frame: not in the policy",
                        "write frame " + transform.child + ": not in the policy");
        refused_children.insert(transform.child);
        refusals.emplace_back(transform.child, "the robot's policy does not let peer '" + peer_ +
                                                   "' write frame '" + transform.child +
                                                   "' (no 'write' rule of '" + peer_ +
                                                   "' matches '" + name + "')");
        return;
      }
      // Before the write: the peer's own frames are never streamed back to it. A frame it
      // never set (the tree refused it) is still the robot's to send.
      const bool first = holdings_->frames_set->add(transform.child);
      std::string why = setter->set(transform, is_static);
      if (why.empty()) {
        if (announced_.insert("set frame " + transform.child).second) {
          say("%s sets frame %s", peer_.c_str(), transform.child.c_str());
        }
        return;
      }
      if (first) holdings_->frames_set->remove(transform.child);
      refusals_->note("set frame: the tree refused", "set frame " + transform.child + ": " + why);
      refused_children.insert(transform.child);
      refusals.emplace_back(transform.child, "the robot's tree refused it: " + why);
    };
    for (const wire::FrameTransform::Reader transform : params.getDynamic()) set(transform, false);
    for (const wire::FrameTransform::Reader transform : params.getStatics()) set(transform, true);
    auto list = context.getResults().initRefusals(static_cast<unsigned>(refusals.size()));
    for (unsigned i = 0; i < refusals.size(); ++i) {
      list[i].setChild(refusals[i].first);
      list[i].setReason(refusals[i].second);
    }
    return kj::READY_NOW;
  }

  kj::Promise<void> publish(PublishContext context) override {
    return throttle().then([this, context]() mutable { return answer_publish(context); });
  }

  kj::Promise<void> answer_publish(PublishContext context) {
    const TopicInfo info = topic_info(context.getParams().getInfo());
    if (!allows(Access::Write, info.name)) {
      refuse(denied("write topic", info.name));
    }
    const std::string what = "publish to " + info.name;
    auto lease = leased(what, info.name);
    if (const std::optional<TopicInfo> here = existing(info.name)) {
      if (!identity(here->type_name, here->fingerprint)
               .same_type(identity(info.type_name, info.fingerprint)) ||
          here->is_pod != info.is_pod ||
          (here->is_pod && here->max_message_size != info.max_message_size)) {
        another_type(what, info.name,
                     type_text(here->type_name, here->fingerprint, here->max_message_size),
                     type_text(info.type_name, info.fingerprint, info.max_message_size));
      }
    }
    if (const std::optional<std::string> problem = description_problem(info)) {
      refused("bad type description", what, "topic '" + info.name + "': " + *problem);
    }
    auto tell = [refusals = refusals_, what](const std::string& why) {
      refusals->note("wrong message", what + ": " + why + "; its stream ends");
    };
    auto sink = kj::heap<TopicSink>(opened(what, info), "topic " + info.name + " from " + peer_,
                                    options_.namespace_name, tell);
    messages_.make_room(sink->largest_message());
    if (announced_.insert("publish " + info.name).second) {
      say("%s publishes to %s", peer_.c_str(), info.name.c_str());
    }
    context.getResults().setSink(sink.attach(kj::mv(lease)));
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

  /// A `call` rule naming an action also lets the peer call its services and read its topics.
  bool allows(Access access, const std::string& name) const {
    return options_.policy.allows(peer_, access, name) ||
           action_allows(options_.policy, peer_, access, name, options_.namespace_name);
  }

  /// `what`: "read topic", "write topic" or "call service".
  std::string denied(const char* what, const std::string& name) const {
    refusals_->note(std::string(what) + ": not in the policy",
                    std::string(what) + " " + name + ": not in the policy");
    return "peer '" + peer_ + "' may not " + what + " '" + name + "'";
  }

  /// Refuses the call with `why`, logged as a refusal of `kind` of `what` the peer asked.
  [[noreturn]] void refused(const std::string& kind, const std::string& what,
                            const std::string& why) const {
    refusals_->note(kind, what + ": " + why);
    refuse(why);
  }

  /// Refuses the peer's `what` of topic `name`, which is of type `here` on the robot, not of
  /// the peer's type `theirs` (type_text()).
  [[noreturn]] void another_type(const std::string& what, const std::string& name,
                                 const std::string& here, const std::string& theirs) const {
    refused("another type", what,
            "topic '" + name + "' is " + here + " on the robot, not " + theirs);
  }

  /// A handle of `topic` for this peer, unless it holds as many as it may.
  kj::Own<HandleLease> leased(const std::string& what, const std::string& topic) const {
    const auto held = holdings_->per_topic.find(topic);
    if (held != holdings_->per_topic.end() && held->second >= kHandlesPerTopic) {
      refused("handle limit", what,
              "peer '" + peer_ + "' holds " + std::to_string(kHandlesPerTopic) +
                  " subscriptions and publishes of '" + topic + "' already, the most it may");
    }
    if (holdings_->total >= kHandlesPerPeer) {
      refused("handle limit", what,
              "peer '" + peer_ + "' holds " + std::to_string(kHandlesPerPeer) +
                  " subscriptions and publishes already, the most it may");
    }
    return kj::heap<HandleLease>(holdings_, topic);
  }

  std::optional<TopicInfo> existing(const std::string& name) const {
    for (TopicInfo& info : list_topics(options_.namespace_name)) {
      if (info.name == name && !info.type_name.empty() && info.error.empty()) {
        return std::move(info);
      }
    }
    return std::nullopt;
  }

  /// `info`'s topic, for the peer to `what`.
  std::unique_ptr<RawTopic> opened(const std::string& what, const TopicInfo& info) const {
    try {
      return RawTopic::open_recorded(info, options_.namespace_name);
    } catch (const std::exception& e) {
      refused("cannot open", what, e.what());
    }
  }

  const ServeOptions& options_;
  ServedFrames& frames_;
  std::string peer_;
  /// The connection's: raised for what this peer may write or call.
  LimitedMessageStream& messages_;
  kj::Timer& timer_;
  /// When this peer's next call may run (throttle()).
  kj::TimePoint next_call_;
  /// Per service the peer called: destroyed (each thread joined) with the session.
  std::map<std::string, std::unique_ptr<ServiceRelay>> relays_;
  /// The goals of actions this connection sent: canceled when it ends.
  RelayedGoals relayed_goals_{options_.namespace_name};
  /// The serverGone calls waiting (shared with each, which may end after the session).
  std::shared_ptr<int> server_watches_ = std::make_shared<int>(0);
  /// What this peer may see of the parameters, made at its first `params`.
  std::unique_ptr<ParamView> param_view_;
  std::shared_ptr<std::atomic<int>> param_writes_ = std::make_shared<std::atomic<int>>(0);
  std::shared_ptr<PeerHoldings> holdings_;
  /// What the peer was granted, logged the first time only on this connection: a peer that
  /// subscribes and drops a thousand times a second costs the log one line.
  std::set<std::string> announced_;
  /// The peer's (holdings_), over all its connections.
  std::shared_ptr<Refusals> refusals_;
};

/// One authenticated peer's RPC connection, whose bootstrap capability `session` makes: the
/// peer's Session, or for a refused peer a broken one that tells it why.
struct Connection {
  template <class MakeSession>
  Connection(kj::Own<kj::AsyncIoStream> stream_, MakeSession&& session)
      : stream(kj::mv(stream_)),
        messages(*stream),
        network(messages),
        rpc(capnp::makeRpcServer(network, session(messages))) {
    rpc.setFlowLimit(kFlowLimitWords);
  }
  kj::Own<kj::AsyncIoStream> stream;
  LimitedMessageStream messages;
  PeerNetwork network;
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
        frames_(options.namespace_name),
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
        [this, address](kj::Exception&& exception) -> kj::Promise<void> {
          const std::string why = exception.getDescription().cStr();
          say("refused %s (no name: %s): %s", address.c_str(), handshake_failure(why).c_str(),
              why.c_str());
          return kj::READY_NOW;
        }));
  }

  /// What a failed TLS handshake says of the peer, from OpenSSL's reason.
  std::string handshake_failure(const std::string& why) const {
    return bridge::handshake_failure(
        why, {.server_name = options_.name,
              .expect_name = "a peer that connects by address needs --server-name " + options_.name,
              .plain_client = "a peer run with --insecure?"});
  }

  kj::Promise<void> serve(kj::AuthenticatedStream peer, const std::string& address) {
    const std::string name =
        tls_ == nullptr
            ? std::string(kInsecurePeer)
            : std::string(
                  kj::downcast<kj::TlsPeerIdentity>(*peer.peerIdentity).getCommonName().cStr());
    // `text`: what the peer is told; `why`: what the log says.
    std::string text;
    std::string why;
    std::shared_ptr<PeerHoldings> held = holdings(name);
    if (!options_.policy.knows(name)) {
      why = "no policy line names it";
      text = "no policy line of this robot names peer '" + name + "'";
    } else if (held->connections >= kConnectionsPerPeer) {
      why =
          "it has " + std::to_string(kConnectionsPerPeer) + " connections already, the most it may";
      text = "peer '" + name + "' has " + std::to_string(kConnectionsPerPeer) +
             " connections to this robot already, the most it may";
    }
    if (!text.empty()) {
      if (held->lingering >= kLingeringPerPeer || lingering_ >= kLingeringInAll) {
        // Not kept to be told: dropped here, the stream closed as it goes.
        held->refusals->note("refused connections over the limit",
                             "connect from " + address + ": " + why + "; closed at once, " +
                                 std::to_string(held->lingering) + " of its refused connections (" +
                                 std::to_string(lingering_) + " in all) being told why already");
        return kj::READY_NOW;
      }
      say("refused %s at %s: %s", name.c_str(), address.c_str(), why.c_str());
      ++held->lingering;
      ++lingering_;
      auto uncounted = kj::defer([this, held] {
        --held->lingering;
        --lingering_;
      });
      // Every call the peer makes fails with the reason, which it prints; then it is let go.
      auto refused = kj::heap<Connection>(
          kj::mv(peer.stream), [&text](LimitedMessageStream&) -> capnp::Capability::Client {
            return kj::Exception(kj::Exception::Type::FAILED, __FILE__, __LINE__,
                                 kj::heapString(text));
          });
      return refused->network.onDisconnect()
          .exclusiveJoin(timer_.afterDelay(kRefusalLinger))
          .attach(kj::mv(refused), kj::mv(uncounted));
    }
    say("%s connected from %s", name.c_str(), address.c_str());
    auto connection = kj::heap<Connection>(
        kj::mv(peer.stream), [&](LimitedMessageStream& messages) -> capnp::Capability::Client {
          return kj::heap<SessionImpl>(options_, name, messages, timer_, held, frames_);
        });
    ++held->connections;
    auto counted = kj::defer([held] { --held->connections; });
    LimitedMessageStream& messages = connection->messages;
    messages.on_read_failure([name, address, &messages](const kj::Exception& e) {
      const std::string why = e.getDescription().cStr();
      if (why.find("too large") != std::string::npos) {
        say("refused a message of %s at %s over its limit of %zu bytes; the connection ends (%s)",
            name.c_str(), address.c_str(), messages.limit_bytes(), why.c_str());
      } else {
        say("%s at %s: %s; the connection ends", name.c_str(), address.c_str(), why.c_str());
      }
    });
    return connection->network.onDisconnect()
        .attach(kj::mv(connection), kj::mv(counted))
        .then([name, address] { say("%s at %s disconnected", name.c_str(), address.c_str()); });
  }

  /// What the connections of peer `name` hold, together.
  std::shared_ptr<PeerHoldings> holdings(const std::string& name) {
    std::shared_ptr<PeerHoldings>& held = holdings_[name];
    if (!held) held = std::make_shared<PeerHoldings>(name, timer_);
    return held;
  }

  const ServeOptions& options_;
  kj::Own<kj::ConnectionReceiver> listener_;
  kj::Maybe<kj::TlsContext&> tls_;
  kj::Timer& timer_;
  /// Of every name our CA signed that connected: what its connections hold, its refusals.
  std::map<std::string, std::shared_ptr<PeerHoldings>> holdings_;
  /// Refused connections being told why, of all peers.
  int lingering_ = 0;
  ServedFrames frames_;
  /// Last: its connections use the rest.
  kj::TaskSet connections_;
};

}  // namespace

int serve(const ServeOptions& options) {
  EventLoop loop;
  kj::Own<kj::TlsContext> tls;
  kj::Maybe<bridge::TlsCredentials> credentials;
  if (options.policy.empty()) {
    say("WARNING: no --allow or --policy rule: every peer will be refused");
  }
  if (options.insecure) {
    say("WARNING: --insecure: plain TCP, no authentication, no encryption; every peer is '%s'",
        kInsecurePeer);
  } else {
    credentials = bridge::load_tls_credentials(options.certs, options.name);
    tls = bridge::tls_context(KJ_ASSERT_NONNULL(credentials), loop.io.provider->getTimer(),
                              kHandshakeTimeout);
  }
  auto address =
      loop.io.provider->getNetwork().parseAddress(options.listen).wait(loop.io.waitScope);
  kj::Own<kj::ConnectionReceiver> listener = address->listen();
  const unsigned port = listener->getPort();
  Server server(options, kj::mv(listener),
                tls ? kj::Maybe<kj::TlsContext&>(*tls) : kj::Maybe<kj::TlsContext&>(nullptr),
                loop.io.provider->getTimer());
  say("%s", describe_topic_wait().c_str());
  std::printf("serving namespace %s on port %u\n", options.namespace_name.c_str(), port);
  std::fflush(stdout);
  loop.run_until_stopped(server.accept_next(), options.namespace_name, "serve");
  return 0;
}

}  // namespace horus::remote
