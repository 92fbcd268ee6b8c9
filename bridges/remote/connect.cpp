// `horus-remote connect`: the far end (a laptop). Mirrors the robot's topics matching --import
// into the local namespace and streams local topics matching --export to the robot, over one
// connection that is made again, with backoff, whenever it ends.
#include <netdb.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <sys/socket.h>
#include <sys/time.h>

#include <algorithm>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <utility>

#include "horus/bridge/topic_policy.hpp"
#include "horus/service_registry.hpp"
#include "link.hpp"
#include "remote.hpp"
#include "remote_actions.hpp"
#include "remote_frames.hpp"
#include "remote_params.hpp"
#include "services.hpp"

namespace horus::remote {

namespace {

/// How often a connection looks for topics that appeared since (on the robot and here).
constexpr auto kRescanInterval = 1 * kj::SECONDS;
constexpr auto kFirstBackoff = 200 * kj::MILLISECONDS;
constexpr auto kLongestBackoff = 5 * kj::SECONDS;

double seconds(kj::Duration duration) {
  return static_cast<double>(duration / kj::MILLISECONDS) / 1e3;
}

/// The text of a failure, without the prefix Cap'n Proto gives the robot's own.
std::string text_of(const kj::Exception& failure) {
  std::string text = failure.getDescription().cStr();
  constexpr std::string_view kRemote = "remote exception: ";
  if (text.starts_with(kRemote)) text.erase(0, kRemote.size());
  return text;
}

/// What certificate_problem() saw of the robot's certificate.
struct Presented {
  std::string name;
  /// Why its chain does not verify against our CA (empty: it does).
  std::string untrusted;
};

/// The verify callback of certificate_problem(): notes the robot's certificate and whether its
/// chain verifies, then ends the handshake (the certificate was all it wanted).
int note_certificate(int verified, X509_STORE_CTX* store) {
  auto* ssl =
      static_cast<SSL*>(X509_STORE_CTX_get_ex_data(store, SSL_get_ex_data_X509_STORE_CTX_idx()));
  auto& presented = *static_cast<Presented*>(SSL_get_app_data(ssl));
  if (verified == 0 && presented.untrusted.empty()) {
    presented.untrusted = X509_verify_cert_error_string(X509_STORE_CTX_get_error(store));
  }
  if (X509_STORE_CTX_get_error_depth(store) != 0) return 1;  // on to the robot's own
  char name[256] = {};
  X509_NAME_get_text_by_NID(X509_get_subject_name(X509_STORE_CTX_get_current_cert(store)),
                            NID_commonName, name, sizeof name);
  presented.name = name;
  // What the robot is told: the alert of the handshake this one stands in for.
  if (X509_STORE_CTX_get_error(store) == X509_V_OK) {
    X509_STORE_CTX_set_error(store, X509_V_ERR_HOSTNAME_MISMATCH);
  }
  return 0;
}

/// Why the robot's certificate failed this laptop's check, learned from a handshake of our own
/// that keeps the certificate kj's does not show: a name other than --server-name, or a chain
/// that does not verify against our CA. Empty when that handshake got no certificate (the
/// failure was not the certificate's). Blocking, 5 s at most per step: only after a failure.
std::string certificate_problem(const ConnectOptions& options) {
  const std::string::size_type colon = options.address.rfind(':');
  std::string host = options.address.substr(0, colon);
  const std::string port = colon == std::string::npos ? "" : options.address.substr(colon + 1);
  if (host.size() > 1 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (::getaddrinfo(host.c_str(), port.c_str(), &hints, &found) != 0) return {};
  const std::unique_ptr<addrinfo, decltype(&::freeaddrinfo)> addresses(found, &::freeaddrinfo);
  const kj::AutoCloseFd socket(::socket(found->ai_family, SOCK_STREAM | SOCK_CLOEXEC, 0));
  const timeval limit{5, 0};
  if (socket.get() < 0 ||
      ::setsockopt(socket.get(), SOL_SOCKET, SO_RCVTIMEO, &limit, sizeof limit) != 0 ||
      ::setsockopt(socket.get(), SOL_SOCKET, SO_SNDTIMEO, &limit, sizeof limit) != 0 ||
      ::connect(socket.get(), found->ai_addr, found->ai_addrlen) != 0) {
    return {};
  }
  const std::unique_ptr<SSL_CTX, decltype(&SSL_CTX_free)> context(SSL_CTX_new(TLS_client_method()),
                                                                  &SSL_CTX_free);
  const std::string authority = options.certs + "/ca.crt";
  if (!context || SSL_CTX_load_verify_locations(context.get(), authority.c_str(), nullptr) != 1) {
    return {};
  }
  SSL_CTX_set_verify(context.get(), SSL_VERIFY_PEER, note_certificate);
  const std::unique_ptr<SSL, decltype(&SSL_free)> ssl(SSL_new(context.get()), &SSL_free);
  Presented presented;
  if (!ssl || SSL_set_fd(ssl.get(), socket.get()) != 1) return {};
  SSL_set_app_data(ssl.get(), &presented);
  static_cast<void>(SSL_connect(ssl.get()));  // fails in note_certificate, by design
  if (presented.name.empty()) return {};
  if (!presented.untrusted.empty()) {
    return "the robot's certificate (named '" + presented.name + "') does not verify against " +
           authority + ": " + presented.untrusted;
  }
  if (presented.name != options.server_name) {
    return "the robot's certificate is named '" + presented.name + "', not '" +
           options.server_name + "': pass --server-name " + presented.name;
  }
  return {};
}

/// A topic streaming to the robot (or a service's requests into its mirror).
struct Export {
  kj::Own<Forwarder> forwarder;
  /// Declared last: cancelled before the forwarder it runs is destroyed.
  kj::Promise<void> task;
};

/// One of the robot's services served here; `mirror` lives as long as `requests` streams into it.
struct Served {
  ServiceMirror* mirror;
  /// The type of the request frames.
  TopicInfo request_frames;
  Export requests;
};

/// What outlives a connection: the local topics the robot's are mirrored into, so that their
/// subscribers see one topic across reconnects, and the services served here, so that a call
/// during an outage ends with a transport error rather than finding no server.
struct Mirrors {
  std::map<std::string, std::shared_ptr<RawTopic>> imported;
  std::map<std::string, Served> served;
  /// With --import-frames or --export-frames: the local tree's side of the frames.
  std::unique_ptr<LaptopFrames> frames;
  /// The goals local processes sent to the robot's actions, canceled there as a sender exits.
  std::unique_ptr<CallerGoals> goals;
};

/// One connection to the robot and the streams it carries; all of them end with it.
class Link {
 public:
  /// `admitted`: called when the robot answers its first request (it refused the peer when
  /// that fails instead).
  Link(const ConnectOptions& options, Mirrors& mirrors, kj::Timer& timer,
       kj::Own<kj::AsyncIoStream> stream, std::function<void()> admitted)
      : options_(options),
        mirrors_(mirrors),
        timer_(timer),
        admitted_(std::move(admitted)),
        stream_(kj::mv(stream)),
        messages_(*stream_),
        network_(messages_, capnp::rpc::twoparty::Side::CLIENT,
                 LimitedMessageStream::network_options()),
        rpc_(capnp::makeRpcClient(network_)),
        session_(bootstrap()),
        watches_(errors_) {
    for (auto& [name, served] : mirrors_.served) served.mirror->connect(session_, &messages_);
    mirrors_.goals->connect(session_);
  }
  Link(const Link&) = delete;
  Link& operator=(const Link&) = delete;
  ~Link() {
    for (auto& [name, served] : mirrors_.served) served.mirror->connect(std::nullopt, nullptr);
    mirrors_.goals->connect(std::nullopt);
    // The robot cancels the goals this connection sent as it ends: a client here must not wait
    // on them. Without a stand-in for send_goal its goals end (aborted) and new ones find no
    // server until the robot serves the action here again.
    for (const std::string& action : actions_) {
      if (mirrors_.served.erase(action + ".send_goal") != 0) {
        say("%s.send_goal no longer served here while the link is down", action.c_str());
      }
    }
  }

  /// Until the connection ends (resolved) or fails (rejected).
  kj::Promise<void> run() {
    kj::Promise<void> running = rescan().exclusiveJoin(network_.onDisconnect());
    if (mirrors_.frames) {
      // A robot that cannot share its frames (an older one) still shares the rest.
      running = running.exclusiveJoin(mirrors_.frames->run(session_).then(
          []() -> kj::Promise<void> { return kj::NEVER_DONE; },
          [](kj::Exception&& failure) -> kj::Promise<void> {
            say("the robot's frames are not carried: %s", text_of(failure).c_str());
            return kj::NEVER_DONE;
          }));
    }
    if (options_.params.empty()) return running;
    params_ = kj::heap<ParamMirrors>(session_, options_.params, options_.namespace_name);
    // A robot that cannot share its parameters (an older one) still shares its topics.
    return running.exclusiveJoin(params_->run().then(
        []() -> kj::Promise<void> { return kj::NEVER_DONE; },
        [](kj::Exception&& failure) -> kj::Promise<void> {
          say("the robot's parameters are not mirrored here: %s", text_of(failure).c_str());
          return kj::NEVER_DONE;
        }));
  }

 private:
  wire::Session::Client bootstrap() {
    capnp::word scratch[4] = {};
    capnp::MallocMessageBuilder message(scratch);
    auto robot = message.getRoot<capnp::rpc::twoparty::VatId>();
    robot.setSide(capnp::rpc::twoparty::Side::SERVER);
    return rpc_.bootstrap(robot).castAs<wire::Session>();
  }

  bool settled(const std::string& name) const {
    return imports_.count(name) != 0 || exports_.count(name) != 0 || refused_.count(name) != 0;
  }

  kj::Promise<void> rescan() {
    return session_.topicsRequest()
        .send()
        .then([this](capnp::Response<wire::Session::TopicsResults>&& response) {
          if (admitted_) std::exchange(admitted_, nullptr)();
          kj::Vector<kj::Promise<void>> requests;
          action_topics_.clear();
          for (const wire::TopicInfo::Reader info : response.getTopics()) {
            const std::string name = info.getName();
            if (info.getMayRead() && bridge::any_matches(name, options_.imports) &&
                !settled(name)) {
              requests.add(import(topic_info(info)));
            }
            if (info.getMayRead() && action_of_part(name, bridge::Access::Read)) {
              action_topics_.emplace(name, topic_info(info));
            }
          }
          for (const TopicInfo& info : list_topics(options_.namespace_name)) {
            if (!info.type_name.empty() && info.error.empty() &&
                bridge::any_matches(info.name, options_.exports) &&
                mirrors_.imported.count(info.name) == 0 && !settled(info.name)) {
              requests.add(export_topic(info));
            }
          }
          return kj::joinPromises(requests.releaseAsArray());
        })
        .then([this] { return session_.servicesRequest().send(); })
        .then([this](capnp::Response<wire::Session::ServicesResults>&& response) {
          std::set<std::string> live;
          for (const wire::ServiceInfo::Reader info : response.getServices()) {
            live.insert(info.getName());
          }
          for (const wire::ServiceInfo::Reader info : response.getServices()) {
            if (!awaits_action_topics(info.getName(), live)) serve_locally(info);
          }
          kj::Vector<kj::Promise<void>> imports;
          for (const wire::ServiceInfo::Reader info : response.getServices()) {
            carry_action(info, live, imports);
          }
          for (auto it = mirrors_.served.begin(); it != mirrors_.served.end();) {
            if (live.count(it->first) != 0) {
              ++it;
              continue;
            }
            say("%s has no server on the robot any more: no longer served here", it->first.c_str());
            it = mirrors_.served.erase(it);
          }
          return kj::joinPromises(imports.releaseAsArray());
        })
        .then([this] { return timer_.afterDelay(kRescanInterval); })
        .then([this] { return rescan(); });
  }

  kj::Promise<void> import(const TopicInfo& remote) {
    const std::string name = remote.name;
    std::shared_ptr<RawTopic>& local = mirrors_.imported[name];
    if (!local) {
      try {
        if (const std::optional<std::string> problem = description_problem(remote)) {
          throw Error(*problem);
        }
        local = RawTopic::open_recorded(remote, options_.namespace_name);
      } catch (const std::exception& e) {
        mirrors_.imported.erase(name);
        refused_.insert(name);
        say("cannot import %s: %s", name.c_str(), e.what());
        return kj::READY_NOW;
      }
    }
    auto sink =
        kj::heap<TopicSink>(local, "topic " + name + " from the robot", options_.namespace_name);
    messages_.make_room(sink->largest_message());
    // The robot checks the local topic's type against its own: both ends check.
    auto request = session_.subscribeRequest();
    request.setTopic(name);
    request.setType(local->type().name);
    request.setFingerprint(local->type().fingerprint);
    request.setSink(kj::mv(sink));
    request.setQueue(options_.queue);
    refused_.insert(name);  // until the answer: asked once per connection
    return request.send().then(
        [this, name](capnp::Response<wire::Session::SubscribeResults>&& response) {
          refused_.erase(name);
          imports_.emplace(name, response.getSubscription());
          say("importing %s", name.c_str());
        },
        [this, name](kj::Exception&& refusal) {
          mirrors_.imported.erase(name);
          say("the robot refused to send %s: %s", name.c_str(), refusal.getDescription().cStr());
        });
  }

  kj::Promise<void> export_topic(const TopicInfo& local) {
    const std::string name = local.name;
    std::unique_ptr<RawTopic> topic;
    try {
      topic = RawTopic::open_recorded(local, options_.namespace_name);
    } catch (const std::exception& e) {
      refused_.insert(name);
      say("cannot export %s: %s", name.c_str(), e.what());
      return kj::READY_NOW;
    }
    auto request = session_.publishRequest();
    describe(local, request.initInfo());
    refused_.insert(name);
    return request.send().then(
        [this, name, topic = std::move(topic)](
            capnp::Response<wire::Session::PublishResults>&& response) mutable {
          refused_.erase(name);
          auto forwarder =
              kj::heap<Forwarder>(std::move(topic), response.getSink(), options_.queue,
                                  "topic " + name + " to the robot", options_.namespace_name);
          kj::Promise<void> task = forwarder->run().eagerlyEvaluate([name](kj::Exception&& e) {
            say("export of %s ended: %s", name.c_str(), e.getDescription().cStr());
          });
          exports_.emplace(name, Export{kj::mv(forwarder), kj::mv(task)});
          say("exporting %s", name.c_str());
        },
        [name](kj::Exception&& refusal) {
          say("the robot refused %s: %s", name.c_str(), refusal.getDescription().cStr());
        });
  }

  /// Whether `service` is an action's send_goal whose topics are not imported here yet: its
  /// stand-in waits for them (the next look at the robot's services), so that no goal is sent
  /// before its feedback, status and result can arrive here.
  bool awaits_action_topics(const std::string& service, const std::set<std::string>& live) const {
    const std::optional<std::string> action = action_of_part(service, bridge::Access::Call);
    if (!action || service != *action + ".send_goal" || live.count(*action + ".cancel_goal") == 0 ||
        mirrors_.served.count(service) != 0) {
      return false;
    }
    for (const char* part : {".feedback", ".status", ".result"}) {
      const std::string topic = *action + part;
      if (action_topics_.count(topic) != 0 && imports_.count(topic) == 0) return true;
    }
    return false;
  }

  /// For the cancel_goal service of an action the robot lets this peer call (`live`: the services
  /// it listed): imports the action's topics, whatever --import says, notes the goals local
  /// clients send, and watches the robot's server of send_goal, whose stand-in here is withdrawn
  /// as soon as it is gone.
  void carry_action(wire::ServiceInfo::Reader info, const std::set<std::string>& live,
                    kj::Vector<kj::Promise<void>>& imports) {
    const std::string name = info.getName();
    const std::optional<std::string> action = action_of_part(name, bridge::Access::Call);
    if (!action || name != *action + ".cancel_goal" || live.count(*action + ".send_goal") == 0) {
      return;
    }
    for (const char* part : {".feedback", ".status", ".result"}) {
      const auto topic = action_topics_.find(*action + part);
      if (topic != action_topics_.end() && !settled(topic->first)) {
        imports.add(import(topic->second));
      }
    }
    mirrors_.goals->learn_cancel(*action, topic_info(info.getRequest()));
    const auto served = mirrors_.served.find(*action + ".send_goal");
    if (served == mirrors_.served.end() || !actions_.insert(*action).second) return;
    served->second.mirror->watch_requests(
        [goals = mirrors_.goals.get(), action = *action, frames = served->second.request_frames](
            std::uint64_t client_id, std::span<const std::byte> frame) {
          goals->sent(action, client_id, frame, frames);
        });
    auto request = session_.serverGoneRequest();
    request.setService(*action + ".send_goal");
    watches_.add(request.send().then(
        [this, action = *action](capnp::Response<wire::Session::ServerGoneResults>&& response) {
          actions_.erase(action);
          if (mirrors_.served.erase(action + ".send_goal") != 0) {
            say("%s.send_goal no longer served here: on the robot %s", action.c_str(),
                response.getWhy().cStr());
          }
        },
        [action = *action](kj::Exception&& failure) {
          // A robot older than serverGone: the rescan withdraws the stand-in, within a second.
          say("the robot does not say when the server of %s goes: %s", action.c_str(),
              text_of(failure).c_str());
        }));
  }

  /// Serves one of the robot's services here, unless a local server of its own serves it.
  void serve_locally(wire::ServiceInfo::Reader info) {
    const std::string name = info.getName();
    if (const auto served = mirrors_.served.find(name); served != mirrors_.served.end()) {
      served->second.mirror->learn(info);
      return;
    }
    if (refused_services_.count(name) != 0) return;
    for (const horus::ServiceInfo& local : list_services(options_.namespace_name)) {
      if (local.name == name && local.servers > 0) {
        refused_services_.insert(name);
        say("not serving %s of the robot: it has a server here (pid %u)", name.c_str(),
            local.server_pid);
        return;
      }
    }
    try {
      auto requests =
          RawTopic::open_recorded(topic_info(info.getRequest()), options_.namespace_name);
      auto mirror = kj::heap<ServiceMirror>(info, options_.namespace_name, options_.call_timeout);
      ServiceMirror* serving = mirror.get();
      serving->connect(session_, &messages_);
      auto forwarder =
          kj::heap<Forwarder>(std::move(requests), kj::mv(mirror), options_.queue,
                              "requests of " + name + " to the robot", options_.namespace_name);
      serving->count_in(forwarder->counts());
      kj::Promise<void> task = forwarder->run().eagerlyEvaluate([name](kj::Exception&& e) {
        say("serving %s of the robot ended: %s", name.c_str(), e.getDescription().cStr());
      });
      mirrors_.served.emplace(name, Served{serving, topic_info(info.getRequest()),
                                           Export{kj::mv(forwarder), kj::mv(task)}});
      say("serving %s of the robot here", name.c_str());
    } catch (const std::exception& e) {
      refused_services_.insert(name);
      say("cannot serve %s of the robot here: %s", name.c_str(), e.what());
    }
  }

  const ConnectOptions& options_;
  Mirrors& mirrors_;
  kj::Timer& timer_;
  std::function<void()> admitted_;
  kj::Own<kj::AsyncIoStream> stream_;
  /// Raised before a topic or service whose messages would not fit is asked for.
  LimitedMessageStream messages_;
  capnp::TwoPartyVatNetwork network_;
  capnp::RpcSystem<capnp::rpc::twoparty::VatId> rpc_;
  wire::Session::Client session_;
  std::map<std::string, wire::Subscription::Client> imports_;
  std::map<std::string, Export> exports_;
  /// The robot's parameters mirrored here (--params), ended with the connection.
  kj::Own<ParamMirrors> params_;
  /// The robot's services not served here on this connection (a local server has them).
  std::set<std::string> refused_services_;
  /// Topics refused (or being asked for) on this connection: asked for again on the next.
  std::set<std::string> refused_;
  /// The latest listing's topics of actions' parts that this peer may read.
  std::map<std::string, TopicInfo> action_topics_;
  /// The actions whose send_goal server is watched on this connection.
  std::set<std::string> actions_;
  struct WatchErrors final : kj::TaskSet::ErrorHandler {
    void taskFailed(kj::Exception&& exception) override {
      say("watching the robot's action servers: %s", exception.getDescription().cStr());
    }
  } errors_;
  kj::TaskSet watches_;
};

class Client {
 public:
  Client(const ConnectOptions& options, EventLoop& loop, kj::Maybe<kj::TlsContext&> tls)
      : options_(options), loop_(loop), tls_(tls) {
    mirrors_.goals = std::make_unique<CallerGoals>(loop.io.provider->getTimer());
    if (!options.import_frames.empty() || !options.export_frames.empty()) {
      mirrors_.frames = std::make_unique<LaptopFrames>(
          options.namespace_name, options.import_frames, options.export_frames);
    }
  }

  /// Connects, and connects again with backoff whenever the connection ends (the backoff starts
  /// again once the robot admitted this peer); fails, ending the command, on a configuration
  /// the robot will never accept (the certificate's name or CA).
  kj::Promise<void> run() {
    linked_ = false;
    admitted_ = false;
    return attempt()
        .then([] { return std::string("the robot closed it"); },
              [this](kj::Exception&& failure) { return explain(failure); })
        .then([this](std::string reason) -> kj::Promise<void> {
          if (!fatal_.empty()) {
            return kj::Exception(kj::Exception::Type::FAILED, __FILE__, __LINE__,
                                 kj::heapString(fatal_));
          }
          const kj::Duration delay = backoff_;
          backoff_ = std::min(backoff_ * 2, kLongestBackoff);
          say("connection to %s ended (%s); trying again in %.1f s", options_.address.c_str(),
              reason.c_str(), seconds(delay));
          return loop_.io.provider->getTimer().afterDelay(delay).then([this] { return run(); });
        });
  }

 private:
  /// Why an attempt ended; sets fatal_ when trying again cannot help.
  std::string explain(const kj::Exception& failure) {
    if (linked_ && !admitted_ && failure.getType() == kj::Exception::Type::FAILED) {
      return "the robot refused this peer: " + text_of(failure);
    }
    const std::string text = text_of(failure);
    if (!linked_ && text.find("certificate verify failed") != std::string::npos) {
      fatal_ = certificate_problem(options_);
    }
    return text;
  }

  kj::Promise<void> attempt() {
    return loop_.io.provider->getNetwork()
        .parseAddress(options_.address)
        .then([](kj::Own<kj::NetworkAddress>&& address) { return address->connect(); })
        .then([this](kj::Own<kj::AsyncIoStream>&& stream) {
          KJ_IF_MAYBE (tls, tls_) {
            return tls->wrapClient(kj::mv(stream), options_.server_name);
          }
          return kj::Promise<kj::Own<kj::AsyncIoStream>>(kj::mv(stream));
        })
        .then([this](kj::Own<kj::AsyncIoStream>&& stream) {
          linked_ = true;
          auto link = kj::heap<Link>(options_, mirrors_, loop_.io.provider->getTimer(),
                                     kj::mv(stream), [this] {
                                       admitted_ = true;
                                       backoff_ = kFirstBackoff;
                                       std::printf("connected to %s\n", options_.address.c_str());
                                       std::fflush(stdout);
                                     });
          Link& running = *link;
          return running.run().attach(kj::mv(link));
        });
  }

  const ConnectOptions& options_;
  EventLoop& loop_;
  kj::Maybe<kj::TlsContext&> tls_;
  Mirrors mirrors_;
  kj::Duration backoff_ = kFirstBackoff;
  /// This attempt's: the connection (TLS included) was made; the robot admitted this peer.
  bool linked_ = false;
  bool admitted_ = false;
  /// Why the command ends instead of trying again.
  std::string fatal_;
};

}  // namespace

int connect(const ConnectOptions& options) {
  EventLoop loop;
  kj::Own<kj::TlsContext> tls;
  kj::Maybe<bridge::TlsCredentials> credentials;
  if (options.insecure) {
    say("WARNING: --insecure: plain TCP, no authentication, no encryption");
  } else {
    credentials = bridge::load_tls_credentials(options.certs, options.name);
    tls = bridge::tls_context(KJ_ASSERT_NONNULL(credentials), loop.io.provider->getTimer(),
                              kHandshakeTimeout);
  }
  say("%s", describe_topic_wait().c_str());
  Client client(options, loop,
                tls ? kj::Maybe<kj::TlsContext&>(*tls) : kj::Maybe<kj::TlsContext&>(nullptr));
  loop.run_until_stopped(client.run(), options.namespace_name, "connect");
  return 0;
}

}  // namespace horus::remote
