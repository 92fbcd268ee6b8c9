#include "horus/dds/services.hpp"

#include <openssl/sha.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <thread>
#include <type_traits>
#include <utility>

#include "horus/bridge/identity.hpp"
#include "horus/bridge/service_relay.hpp"
#include "horus/dds/cdr_plan.hpp"
#include "horus/dds/conversion.hpp"
#include "horus/dds/user_data.hpp"
#include "horus/dds/xtypes.hpp"
#include "horus/raw_service.hpp"
#include "horus/raw_topic.hpp"
#include "horus/service_registry.hpp"
#include "horus/topic_registry.hpp"
#include "horus/type_description.hpp"

namespace horus::dds_bridge {
namespace {

constexpr std::size_t kEncapsulation = 4;
constexpr std::size_t kHeader = 16;  // caller id (u64), sequence number (i64)
constexpr auto kRetry = std::chrono::milliseconds(500);
// How long an importing bridge waits for a reply over DDS (its caller's own timeout, when
// shorter, ends the caller's wait sooner).
constexpr auto kReplyTimeout = std::chrono::seconds(30);
// How long a new import waits for its request writer to match the exporting side (a request
// written before would be lost).
constexpr auto kMatchWait = std::chrono::seconds(5);
constexpr const char* kRequestPrefix = "rq/";
constexpr const char* kReplyPrefix = "rr/";
constexpr const char* kReplySuffix = "Reply";

void line_to(int fd, const std::string& text) {
  const std::string line = text + "\n";
  [[maybe_unused]] const ssize_t written = ::write(fd, line.data(), line.size());
}
void say(const std::string& text) { line_to(STDOUT_FILENO, text); }
void complain(const std::string& text) { line_to(STDERR_FILENO, "horus bridge: " + text); }

// One line for a failure of a carried service, with its running count.
void failed(const std::string& what, std::atomic<std::uint64_t>& count, const std::string& why,
            const std::string& then) {
  complain(what + ": " + why + " (failure " + std::to_string(++count) + " of it); " + then);
}

std::vector<std::byte> with_header(std::span<const std::byte> cdr, std::uint64_t caller,
                                   std::int64_t sequence) {
  if (cdr.size() < kEncapsulation) {
    throw std::runtime_error("a CDR sample of " + std::to_string(cdr.size()) + " bytes");
  }
  std::vector<std::byte> out(cdr.size() + kHeader);
  std::memcpy(out.data(), cdr.data(), kEncapsulation);
  std::memcpy(out.data() + kEncapsulation, &caller, 8);
  std::memcpy(out.data() + kEncapsulation + 8, &sequence, 8);
  std::memcpy(out.data() + kEncapsulation + kHeader, cdr.data() + kEncapsulation,
              cdr.size() - kEncapsulation);
  return out;
}

struct Sample {
  std::uint64_t caller = 0;
  std::int64_t sequence = 0;
  std::vector<std::byte> cdr;  // the message's, with its encapsulation header
};

Sample split_header(const std::string& sample) {
  if (sample.size() < kEncapsulation + kHeader) {
    throw std::runtime_error("a service sample of " + std::to_string(sample.size()) +
                             " bytes has no request header");
  }
  Sample out;
  std::memcpy(&out.caller, sample.data() + kEncapsulation, 8);
  std::memcpy(&out.sequence, sample.data() + kEncapsulation + 8, 8);
  const auto* bytes = reinterpret_cast<const std::byte*>(sample.data());
  out.cdr.assign(bytes, bytes + kEncapsulation);
  out.cdr.insert(out.cdr.end(), bytes + kEncapsulation + kHeader, bytes + sample.size());
  return out;
}

// A failure reply's body: XCDR1 little-endian, one CDR string.
std::vector<std::byte> failure_body(const std::string& text) {
  std::vector<std::byte> out{std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0}};
  const auto length = static_cast<std::uint32_t>(text.size() + 1);
  out.resize(8);
  std::memcpy(out.data() + 4, &length, 4);
  const auto* first = reinterpret_cast<const std::byte*>(text.data());
  out.insert(out.end(), first, first + text.size());
  out.push_back(std::byte{0});
  return out;
}

std::string failure_text(std::span<const std::byte> cdr) {
  std::uint32_t length = 0;
  if (cdr.size() < 8) {
    return "a failure reply without its text";
  }
  std::memcpy(&length, cdr.data() + 4, 4);
  if (length == 0 || cdr.size() < 8 + std::size_t{length}) {
    return "a failure reply whose text is cut";
  }
  return {reinterpret_cast<const char*>(cdr.data() + 8), length - 1};
}

// The ServiceError of a failure reply's "<Kind>: <text>" (ServiceFailed for a kind this side
// does not know), said to come from the server's host.
ServiceError remote_error(const std::string& text) {
  const std::size_t colon = text.find(": ");
  const std::string kind = text.substr(0, colon);
  const std::string detail = "on the server's host: " +
                             (colon == std::string::npos ? std::string() : text.substr(colon + 2));
  using Kind = ServiceErrorKind;
  if (kind == to_string(Kind::NoServer)) return ServiceError::no_server(detail);
  if (kind == to_string(Kind::Timeout)) return ServiceError::timeout(detail);
  if (kind == to_string(Kind::Transport)) return ServiceError::transport(detail);
  if (kind == to_string(Kind::ServiceFailed)) return ServiceError::service_failed(detail);
  return ServiceError::service_failed("on the server's host: " + text);
}

// A payload type's CDR conversion and DDS type name, from its description.
struct Payload {
  TypeIdentity type;
  std::shared_ptr<const TypeDescription> description;
  const MessageType* message = nullptr;
  std::unique_ptr<Conversion> conversion;
  std::vector<std::byte> empty;  // its encoding with every field at its default

  explicit Payload(TypeIdentity identity) : type(std::move(identity)) {
    if (type.description.empty()) {
      throw std::runtime_error(type.name +
                               " carries no type description (made by a horus-gen before "
                               "descriptions): regenerate it");
    }
    description = std::make_shared<const TypeDescription>(
        TypeDescription::decode(std::string_view(type.description)));
    message = &description->root_message();
    if (message->name != type.name || message->fingerprint != type.fingerprint) {
      throw std::runtime_error("the type description of " + type.name + " is of " + message->name);
    }
    conversion = message->is_pod ? pod_conversion(pod_cdr_plan(*description, *message))
                                 : serialized_conversion(description, *message);
    if (message->is_pod) {
      empty.resize(message->size);
    } else {
      const std::vector<std::uint8_t> bytes = default_message(*description, *message);
      const auto* first = reinterpret_cast<const std::byte*>(bytes.data());
      empty.assign(first, first + bytes.size());
    }
  }

  // ROS 2's name of the service's request or response type: <pkg>::dds_::S_Request_.
  std::string dds_type(const std::string& service, const char* suffix) const {
    const std::string own = dds_type_name(*description, *message);
    return own.substr(0, own.rfind("::")) + "::" + service + "_" + suffix;
  }
};

RawServiceType raw_type(const std::string& service, std::uint64_t fingerprint,
                        const Payload& request, const Payload& response) {
  return RawServiceType{service,      service + ".request", service + ".response", fingerprint,
                        request.type, response.type,        request.empty,         response.empty};
}

TopicOptions in_namespace(const std::string& namespace_name) {
  TopicOptions options;
  options.namespace_name = namespace_name;
  return options;
}

// `kind`: "service" or "action", as the options name them.
std::string both_ways(const std::string& kind, const std::string& name) {
  return "refusing " + kind + " '" + name + "': it matches both --export-" + kind +
         " and --import-" + kind;
}

// Follows what DDS offers of one kind ("service" or "action"): the import of an offer that went
// away ends (its local callers then get NoServer, as from any server that stops); each new offer
// is imported by `start`, or refused once, with the reason, when the policy would carry it both
// ways or it cannot be carried.
template <class Offer, class Import, class Start>
void follow_offers(const std::string& kind, const std::map<std::string, Offer>& offered,
                   std::map<std::string, std::unique_ptr<Import>>& imported,
                   std::set<std::string>& refused, const bridge::TopicPolicy& policy,
                   const Start& start) {
  for (auto carried = imported.begin(); carried != imported.end();) {
    if (offered.contains(carried->first)) {
      ++carried;
      continue;
    }
    const std::string name = carried->first;
    carried = imported.erase(carried);
    say("no longer importing " + kind + " '" + name + "' (no server on DDS)");
  }
  for (const auto& [name, offer] : offered) {
    if (imported.contains(name) || refused.contains(name)) {
      continue;
    }
    if (policy.exported(name)) {
      refused.insert(name);
      complain(both_ways(kind, name));
      continue;
    }
    try {
      start(name, offer);
    } catch (const std::exception& error) {
      refused.insert(name);
      complain("cannot import " + kind + " '" + name + "': " + error.what());
    }
  }
}

}  // namespace

TypeIdentity described_type(std::string description) {
  const MessageType message = TypeDescription::decode(std::string_view(description)).root_message();
  TypeIdentity out;
  out.name = message.name;
  out.fingerprint = message.fingerprint;
  out.schema = message.schema;
  out.is_pod = message.is_pod;
  out.size = message.size;
  out.alignment = message.is_pod ? message.alignment : 1;
  out.description = std::move(description);
  return out;
}

// -- export: a local server, called from DDS ----------------------------------------------------

class ServiceRelays::Exported {
 public:
  Exported(const std::string& name, std::uint64_t fingerprint, TypeIdentity request,
           TypeIdentity response, const std::shared_ptr<Participant>& participant, const Qos& qos,
           std::chrono::duration<double> timeout, const std::string& namespace_name)
      : name_(name),
        request_(std::move(request)),
        response_(std::move(response)),
        request_type_(request_.dds_type(name, "Request_")),
        response_type_(response_.dds_type(name, "Response_")),
        reader_(participant, kRequestPrefix + name + "Request", TypeOnWire{request_type_, {}, {}},
                qos, false),
        writer_(participant, kReplyPrefix + name + kReplySuffix, TypeOnWire{response_type_, {}, {}},
                qos, service_user_data({name, fingerprint, request_.type, response_.type})),
        timeout_(std::chrono::ceil<std::chrono::milliseconds>(timeout)),
        caller_(raw_type(name, fingerprint, request_, response_), namespace_name),
        thread_([this] { answer_calls(); }) {}

  ~Exported() {
    stopping_.store(true);
    thread_.join();
  }
  Exported(const Exported&) = delete;
  Exported& operator=(const Exported&) = delete;

  std::string said() const {
    return "exporting service '" + name_ + "' as " + reader_.topic() + " (" + request_type_ +
           ") and " + writer_.topic() + " (" + response_type_ + ")";
  }

 private:
  void answer_calls() {
    const std::string what = "service '" + name_ + "'";
    std::vector<std::byte> message;
    while (!stopping_.load()) {
      std::vector<std::pair<dds_instance_handle_t, std::string>> received;
      try {
        received = reader_.take(std::chrono::milliseconds(100));
      } catch (const std::exception& error) {
        failed(what, failures_, error.what(), "retrying");
        std::this_thread::sleep_for(kRetry);
        continue;
      }
      for (const auto& [writer, bytes] : received) {
        Sample request;
        try {
          request = split_header(bytes);
          if (std::string why = request_.conversion->to_local(request.cdr, message); !why.empty()) {
            throw std::runtime_error(why);
          }
        } catch (const std::exception& error) {
          failed(what, failures_, std::string("a request does not decode: ") + error.what(),
                 "dropped it");
          continue;
        }
        caller_.call(message, timeout_,
                     [this, caller = request.caller,
                      sequence = request.sequence](bridge::LocalServiceCaller::Outcome called) {
                       reply(called.answer, caller, sequence);
                     });
      }
    }
  }

  // On the caller's worker: the server's answer, or why there is none, to the DDS caller.
  void reply(const ServiceResult<std::vector<std::byte>>& answer, std::uint64_t caller,
             std::int64_t sequence) {
    try {
      std::vector<std::byte> sample;
      if (answer) {
        response_.conversion->to_dds(*answer, reply_cdr_);
        sample = with_header(reply_cdr_, caller, sequence);
      } else {
        sample = with_header(failure_body(answer.error().to_string()), caller, -sequence);
      }
      writer_.write(sample);
    } catch (const std::exception& error) {
      failed("service '" + name_ + "'", failures_, error.what(), "the caller gets no reply");
    }
  }

  std::string name_;
  Payload request_;
  Payload response_;
  std::string request_type_;
  std::string response_type_;
  Reader reader_;
  Writer writer_;
  std::chrono::milliseconds timeout_;
  std::atomic<std::uint64_t> failures_{0};
  std::vector<std::byte> reply_cdr_;  // the worker's
  // After what its worker's replies use, so it is stopped first.
  bridge::LocalServiceCaller caller_;
  std::atomic<bool> stopping_{false};
  std::thread thread_;  // last: started once everything it uses is there
};

// -- import: a local server, calling over DDS ---------------------------------------------------

class ServiceRelays::Imported {
 public:
  Imported(const ServiceIdentity& identity, const std::shared_ptr<Participant>& participant,
           const Qos& qos, const std::string& namespace_name)
      : name_(identity.service),
        request_(identity.request),
        response_(identity.response),
        request_type_(request_.dds_type(name_, "Request_")),
        response_type_(response_.dds_type(name_, "Response_")),
        writer_(participant, kRequestPrefix + name_ + "Request", TypeOnWire{request_type_, {}, {}},
                qos, ""),
        reader_(participant, kReplyPrefix + name_ + kReplySuffix,
                TypeOnWire{response_type_, {}, {}}, qos, false),
        caller_(new_service_endpoint_id()),
        server_(raw_type(name_, identity.fingerprint, request_, response_),
                in_namespace(namespace_name)),
        thread_([this] { serve(); }) {}

  ~Imported() {
    stopping_.store(true);
    server_.stop();
    thread_.join();
    server_.withdraw();  // local callers get NoServer
  }
  Imported(const Imported&) = delete;
  Imported& operator=(const Imported&) = delete;

 private:
  void serve() {
    while (!stopping_.load()) {
      if (std::optional<RawServiceServer::Request> request =
              server_.next(std::chrono::milliseconds(250))) {
        relay(*request);
      }
    }
  }

  // Whether the exporting side's request reader matches the request writer, waiting for it a
  // moment after the import started.
  bool server_matched() {
    const auto deadline =
        std::chrono::steady_clock::now() + (server_seen_ ? std::chrono::seconds(0) : kMatchWait);
    while (writer_.matched() == 0) {
      if (server_seen_ || stopping_.load() || std::chrono::steady_clock::now() >= deadline) {
        return false;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    server_seen_ = true;
    return true;
  }

  // Sends the call to DDS and answers the local caller with the reply, or fails it with the kind
  // the exporting side gave: when its request reader goes (its server left, so it withdrew the
  // service), a waiting call gets NoServer at once, as it would from that side a moment later.
  void relay(const RawServiceServer::Request& request) {
    const ServiceError left =
        ServiceError::no_server("the server of " + name_ + " left the DDS side");
    if (!server_matched()) {
      server_.fail(request.caller, left);
      return;
    }
    const std::int64_t sequence = ++sequence_;
    try {
      request_.conversion->to_dds(request.payload, cdr_);
      writer_.write(with_header(cdr_, caller_, sequence));
    } catch (const std::exception& error) {
      server_.fail(request.caller,
                   ServiceError::transport(std::string("the request did not go out on DDS: ") +
                                           error.what()));
      return;
    }
    const auto deadline = std::chrono::steady_clock::now() + kReplyTimeout;
    while (!stopping_.load() && std::chrono::steady_clock::now() < deadline) {
      if (writer_.matched() == 0) {
        server_.fail(request.caller, left);
        return;
      }
      std::vector<std::pair<dds_instance_handle_t, std::string>> received;
      try {
        received = reader_.take(std::chrono::milliseconds(50));
      } catch (const std::exception& error) {
        server_.fail(request.caller,
                     ServiceError::transport(std::string("the reply could not be read from DDS: ") +
                                             error.what()));
        return;
      }
      for (const auto& [writer, bytes] : received) {
        Sample reply;
        try {
          reply = split_header(bytes);
        } catch (const std::exception&) {
          continue;  // not a reply of this protocol
        }
        if (reply.caller != caller_ ||
            (reply.sequence != sequence && reply.sequence != -sequence)) {
          continue;  // another caller's reply, or a late one to a call that timed out
        }
        if (reply.sequence < 0) {
          server_.fail(request.caller, remote_error(failure_text(reply.cdr)));
          return;
        }
        std::string why;
        try {
          why = response_.conversion->to_local(reply.cdr, message_);
        } catch (const std::exception& error) {
          why = error.what();
        }
        if (!why.empty()) {
          server_.fail(request.caller,
                       ServiceError::transport("the reply does not decode: " + why));
          return;
        }
        server_.answer(request.caller, message_);
        return;
      }
    }
    server_.fail(request.caller,
                 ServiceError::timeout("no reply over DDS within " +
                                       std::to_string(kReplyTimeout.count()) + " s"));
  }

  std::string name_;
  Payload request_;
  Payload response_;
  std::string request_type_;
  std::string response_type_;
  Writer writer_;
  Reader reader_;
  std::uint64_t caller_;  // this import's id in the request header, unique on the machine
  std::int64_t sequence_ = 0;
  bool server_seen_ = false;  // whether the exporting side's request reader ever matched
  std::vector<std::byte> cdr_;
  std::vector<std::byte> message_;
  std::atomic<bool> stopping_{false};
  RawServiceServer server_;
  std::thread thread_;  // last: started once everything it uses is there
};

// -- actions: a local action server, served to ROS 2 action clients -----------------------------

namespace {

// ROS 2's GoalStatus values (HORUS's GoalState, runtime/src/action/README.md); Rejected is HORUS's
// own and never reaches ROS 2.
constexpr std::uint8_t kAccepted = 1;
constexpr std::uint8_t kExecuting = 2;
constexpr std::uint8_t kCanceling = 3;
constexpr std::uint8_t kSucceeded = 4;
constexpr std::uint8_t kCanceled = 5;
constexpr std::uint8_t kAborted = 6;
constexpr std::uint8_t kRejected = 7;
constexpr std::size_t kGoalId = 16;
// Ended goals the status array keeps, as many as a HORUS server keeps for get_result.
constexpr std::size_t kEndedGoalsKept = 64;
// get_result calls from DDS waiting for their goal to end; more are answered Unknown at once.
constexpr std::size_t kWaitingResultsMost = 1024;
// How often a waiting get_result asks the local server again when no status said the goal ended.
constexpr auto kResultRecheck = std::chrono::milliseconds(250);
constexpr auto kActionPoll = std::chrono::milliseconds(2);

using GoalId = std::array<std::byte, kGoalId>;

bool live(std::uint8_t state) { return state >= kAccepted && state <= kCanceling; }

// Keeps the live goals of a table and the last kEndedGoalsKept ended ones.
template <class Goal>
void forget_ended(std::vector<Goal>& goals) {
  std::size_t ended =
      std::count_if(goals.begin(), goals.end(), [](const Goal& goal) { return !live(goal.state); });
  for (auto goal = goals.begin(); ended > kEndedGoalsKept && goal != goals.end();) {
    if (live(goal->state)) {
      ++goal;
    } else {
      goal = goals.erase(goal);
      --ended;
    }
  }
}

template <class Goal>
Goal* find_goal(std::vector<Goal>& goals, const GoalId& id) {
  const auto found =
      std::find_if(goals.begin(), goals.end(), [&](const Goal& goal) { return goal.id == id; });
  return found == goals.end() ? nullptr : &*found;
}

std::uint64_t now_ns() {
  return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                        std::chrono::system_clock::now().time_since_epoch())
                                        .count());
}

// The first 8 bytes (big-endian) of the SHA-256 of `text`: horus-gen's fingerprint of a canonical
// text (generator/horus_gen/identity.py), which an imported action's service registrations carry
// as a generated server's do.
std::uint64_t sha256_fingerprint(const std::string& text) {
  std::array<unsigned char, SHA256_DIGEST_LENGTH> digest{};
  SHA256(reinterpret_cast<const unsigned char*>(text.data()), text.size(), digest.data());
  std::uint64_t fingerprint = 0;
  for (std::size_t i = 0; i < sizeof fingerprint; ++i) {
    fingerprint = (fingerprint << 8) | digest[i];
  }
  return fingerprint;
}

// CDR (XCDR1, little-endian) written member by member, aligned from the body's start: the
// members of ROS 2's action messages that HORUS's have in another shape.
class CdrWriter {
 public:
  CdrWriter() : sample_{std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0}} {}
  template <class T>
  requires std::is_arithmetic_v<T>
  void put(T value) {
    sample_.resize(kEncapsulation + aligned(sample_.size() - kEncapsulation, sizeof(T)));
    const auto* bytes = reinterpret_cast<const std::byte*>(&value);
    sample_.insert(sample_.end(), bytes, bytes + sizeof(T));
  }
  void put(const GoalId& id) { sample_.insert(sample_.end(), id.begin(), id.end()); }
  // builtin_interfaces/Time of nanoseconds since the epoch.
  void put_time(std::uint64_t stamp_ns) {
    put(static_cast<std::int32_t>(stamp_ns / 1'000'000'000));
    put(static_cast<std::uint32_t>(stamp_ns % 1'000'000'000));
  }
  void put(const std::string& text) {
    put(static_cast<std::uint32_t>(text.size() + 1));
    const auto* first = reinterpret_cast<const std::byte*>(text.data());
    sample_.insert(sample_.end(), first, first + text.size());
    sample_.push_back(std::byte{0});
  }
  // The members written so far, unpadded: the body_prefix of a CdrPlan that encodes what follows.
  std::span<const std::byte> body() const { return std::span(sample_).subspan(kEncapsulation); }
  std::vector<std::byte> done() {
    const std::size_t padding = (4 - (sample_.size() - kEncapsulation) % 4) % 4;
    sample_.resize(sample_.size() + padding);
    sample_[3] = static_cast<std::byte>(padding);
    return std::move(sample_);
  }

 private:
  static std::size_t aligned(std::size_t position, std::size_t size) {
    return (position + size - 1) / size * size;
  }
  std::vector<std::byte> sample_;
};

// The fixed members at the start of a HORUS action message's CDR body (the action wire's types:
// goal_id [u8; 16], state u8, stamp_ns u64, reason string<192>; or accepted bool, stamp_ns u64,
// reason; or return_code u8, goals_canceling u32), read at their CDR offsets.
class CdrBody {
 public:
  CdrBody(std::span<const std::byte> sample, std::string type)
      : body_(sample.subspan(std::min(sample.size(), kEncapsulation))), type_(std::move(type)) {
    if (sample.size() < kEncapsulation || sample[1] != std::byte{1}) {
      throw std::runtime_error("a " + type + " sample that is not little-endian CDR");
    }
  }
  template <class T>
  T at(std::size_t offset) const {
    need(offset + sizeof(T));
    T value{};
    std::memcpy(&value, body_.data() + offset, sizeof(T));
    return value;
  }
  GoalId goal_id(std::size_t offset = 0) const {
    need(offset + kGoalId);
    GoalId id{};
    std::memcpy(id.data(), body_.data() + offset, kGoalId);
    return id;
  }
  // builtin_interfaces/Time as nanoseconds since the epoch (a time before it: 0).
  std::uint64_t time_at(std::size_t offset) const {
    const auto sec = at<std::int32_t>(offset);
    return sec < 0
               ? 0
               : static_cast<std::uint64_t>(sec) * 1'000'000'000 + at<std::uint32_t>(offset + 4);
  }
  std::string string_at(std::size_t offset) const {
    const auto length = at<std::uint32_t>(offset);
    need(offset + 4 + length);
    return length == 0
               ? std::string()
               : std::string(reinterpret_cast<const char*>(body_.data() + offset + 4), length - 1);
  }

 private:
  void need(std::size_t size) const {
    if (body_.size() < size) {
      throw std::runtime_error("a " + type_ + " sample of " + std::to_string(body_.size()) +
                               " bytes is cut short");
    }
  }
  std::span<const std::byte> body_;
  std::string type_;
};

std::string hex(const GoalId& id) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  for (const std::byte byte : id) {
    out += kDigits[std::to_integer<unsigned>(byte) >> 4];
    out += kDigits[std::to_integer<unsigned>(byte) & 15];
  }
  return out;
}

}  // namespace

/// An action's three services: their fingerprints and payload types (get_result's response is
/// also what A.result carries).
struct ServiceRelays::ActionParts {
  std::uint64_t send_goal_fingerprint = 0;
  std::uint64_t cancel_goal_fingerprint = 0;
  std::uint64_t get_result_fingerprint = 0;
  std::optional<TypeIdentity> send_goal_request, send_goal_response, cancel_request,
      cancel_response, get_result_request, result_message;
};

namespace {

// ROS 2's GetResult response puts the result after its status byte (so its members align
// otherwise than in HORUS's message): the plan of the result member of A.get_result's answer.
CdrPlan result_plan(const Payload& message) {
  const MessageField* result = message.message->find_field("result");
  const MessageType* type =
      result == nullptr ? nullptr : message.description->find_message(result->type.name);
  if (type == nullptr || !result->offset) {
    throw std::runtime_error(message.type.name + " has no result member");
  }
  if (!message.message->is_pod || !type->is_pod) {
    throw std::runtime_error("its result " + type->name +
                             " is a serialized type, which the bridge does not carry as ROS 2's "
                             "GetResult yet (POD results only)");
  }
  return pod_cdr_plan(*message.description, *type);
}

// <pkg>::dds_::, the IDL module of an action whose send_goal request is `request`.
std::string action_module(const Payload& request) {
  const std::string own = dds_type_name(*request.description, *request.message);
  return own.substr(0, own.rfind("::") + 2);
}

// action_msgs' DDS types (bridges/dds/ros2_idl/), the same for every action.
constexpr const char* kCancelRequestType = "action_msgs::srv::dds_::CancelGoal_Request_";
constexpr const char* kCancelResponseType = "action_msgs::srv::dds_::CancelGoal_Response_";
constexpr const char* kStatusArrayType = "action_msgs::msg::dds_::GoalStatusArray_";

// rq/A/_action/send_goalRequest and the rest: ROS 2's DDS names of an action's service topics.
std::string action_request_topic(const std::string& action, const char* service) {
  return kRequestPrefix + action + "/_action/" + service + "Request";
}
std::string action_reply_topic(const std::string& action, const char* service) {
  return kReplyPrefix + action + "/_action/" + service + kReplySuffix;
}

}  // namespace

// One thread per action: the three services' DDS requests, each answered by a call to the local
// server; A.status followed into the goal table whose whole GoalStatusArray goes out on each
// change; A.feedback written as it comes (its CDR is ROS 2's FeedbackMessage: the goal id's 16
// bytes, then the feedback).
class ServiceRelays::ExportedAction {
 public:
  ExportedAction(const std::string& name, const ActionParts& parts, const TopicInfo& feedback,
                 const TopicInfo& status, const std::shared_ptr<Participant>& participant,
                 const Qos& qos, std::chrono::duration<double> timeout,
                 const std::string& namespace_name)
      : name_(name),
        send_goal_request_(*parts.send_goal_request),
        send_goal_response_(*parts.send_goal_response),
        cancel_request_(*parts.cancel_request),
        cancel_response_(*parts.cancel_response),
        get_result_request_(*parts.get_result_request),
        result_message_(*parts.result_message),
        feedback_(type_identity_of(feedback)),
        status_(type_identity_of(status)),
        result_plan_(result_plan(result_message_)),
        module_(action_module(send_goal_request_)),
        send_goal_reader_(participant, request_topic("send_goal"),
                          TypeOnWire{module_ + name + "_SendGoal_Request_", {}, {}}, qos, false),
        send_goal_writer_(participant, reply_topic("send_goal"),
                          TypeOnWire{module_ + name + "_SendGoal_Response_", {}, {}}, qos, ""),
        cancel_reader_(participant, request_topic("cancel_goal"),
                       TypeOnWire{kCancelRequestType, {}, {}}, qos, false),
        cancel_writer_(participant, reply_topic("cancel_goal"),
                       TypeOnWire{kCancelResponseType, {}, {}}, qos, ""),
        get_result_reader_(participant, request_topic("get_result"),
                           TypeOnWire{module_ + name + "_GetResult_Request_", {}, {}}, qos, false),
        get_result_writer_(participant, reply_topic("get_result"),
                           TypeOnWire{module_ + name + "_GetResult_Response_", {}, {}}, qos, ""),
        feedback_writer_(participant, "rt/" + name + "/_action/feedback",
                         TypeOnWire{module_ + name + "_FeedbackMessage_", {}, {}}, qos, ""),
        // ROS 2's status QoS: reliable, transient local, the last array only.
        status_writer_(participant, "rt/" + name + "/_action/status",
                       TypeOnWire{kStatusArrayType, {}, {}}, Qos{true, 1, true, 0}, ""),
        timeout_(std::chrono::ceil<std::chrono::milliseconds>(timeout)),
        send_goal_(raw_type(name + ".send_goal", parts.send_goal_fingerprint, send_goal_request_,
                            send_goal_response_),
                   in_namespace(namespace_name)),
        cancel_goal_(raw_type(name + ".cancel_goal", parts.cancel_goal_fingerprint, cancel_request_,
                              cancel_response_),
                     in_namespace(namespace_name)),
        get_result_(raw_type(name + ".get_result", parts.get_result_fingerprint,
                             get_result_request_, result_message_),
                    in_namespace(namespace_name)),
        feedback_topic_(RawTopic::open_recorded(feedback, namespace_name)),
        status_topic_(RawTopic::open_recorded(status, namespace_name)),
        thread_([this] { run(); }) {}

  ~ExportedAction() {
    stopping_.store(true);
    thread_.join();
  }
  ExportedAction(const ExportedAction&) = delete;
  ExportedAction& operator=(const ExportedAction&) = delete;

  std::string said() const {
    return "exporting action '" + name_ + "' as rq/" + name_ + "/_action/{send_goal,cancel_goal," +
           "get_result}Request, rt/" + name_ + "/_action/{feedback,status} (" + module_ + name_ +
           "_*)";
  }

 private:
  struct Goal {
    GoalId id;
    std::uint64_t accepted_ns = 0;
    std::uint8_t state = 0;
  };
  struct WaitingResult {
    std::uint64_t caller = 0;
    std::int64_t sequence = 0;
    GoalId id;
    std::chrono::steady_clock::time_point asked;
  };

  std::string request_topic(const char* service) const {
    return action_request_topic(name_, service);
  }
  std::string reply_topic(const char* service) const { return action_reply_topic(name_, service); }

  void run() {
    while (!stopping_.load()) {
      try {
        follow_status();
        forward_feedback();
        answer_send_goal();
        answer_cancel_goal();
        take_get_result();
        answer_results();
      } catch (const std::exception& error) {
        failed("action '" + name_ + "'", failures_, error.what(), "carrying on");
        std::this_thread::sleep_for(kRetry);
      }
      std::this_thread::sleep_for(kActionPoll);
    }
  }

  // The local server's answer to `request` (a HORUS CDR sample), or why there is none.
  ServiceResult<std::vector<std::byte>> call(RawServiceClient& client, Payload& request,
                                             std::span<const std::byte> cdr) {
    if (std::string why = request.conversion->to_local(cdr, local_); !why.empty()) {
      throw std::runtime_error("a request does not decode: " + why);
    }
    return client.call(local_, timeout_);
  }

  // A reply that says why the call failed, as an exported service's does.
  void fail(Writer& writer, const Sample& request, const ServiceError& error) {
    writer.write(with_header(failure_body(error.to_string()), request.caller, -request.sequence));
  }

  void answer_send_goal() {
    for (const auto& [writer, bytes] : send_goal_reader_.take(std::chrono::nanoseconds(0))) {
      const Sample request = split_header(bytes);
      const ServiceResult<std::vector<std::byte>> answer =
          call(send_goal_, send_goal_request_, request.cdr);  // the same CDR as HORUS's request
      if (!answer) {
        fail(send_goal_writer_, request, answer.error());
        continue;
      }
      send_goal_response_.conversion->to_dds(*answer, cdr_);
      const CdrBody response(cdr_, send_goal_response_.type.name);
      const bool accepted = response.at<std::uint8_t>(0) != 0;
      const auto stamp_ns = response.at<std::uint64_t>(8);
      const GoalId id = CdrBody(request.cdr, send_goal_request_.type.name).goal_id();
      if (accepted) {
        if (update(id, kAccepted, stamp_ns)) publish_status();
      } else {  // ROS 2's response has no slot for why
        say("action '" + name_ + "': goal " + hex(id) +
            " from DDS rejected: " + response.string_at(16));
      }
      CdrWriter reply;
      reply.put(static_cast<std::uint8_t>(accepted));
      reply.put_time(stamp_ns);
      send_goal_writer_.write(with_header(reply.done(), request.caller, request.sequence));
    }
  }

  // ROS 2 cancels by id and stamp; HORUS by id alone (all zero: every live goal), so the stamp
  // is not used.
  void answer_cancel_goal() {
    for (const auto& [writer, bytes] : cancel_reader_.take(std::chrono::nanoseconds(0))) {
      const Sample request = split_header(bytes);
      const GoalId id = CdrBody(request.cdr, "CancelGoal_Request").goal_id();
      std::vector<std::byte> horus_request(request.cdr.begin(),
                                           request.cdr.begin() + kEncapsulation);
      horus_request.insert(horus_request.end(), id.begin(), id.end());
      const ServiceResult<std::vector<std::byte>> answer =
          call(cancel_goal_, cancel_request_, horus_request);
      if (!answer) {
        fail(cancel_writer_, request, answer.error());
        continue;
      }
      cancel_response_.conversion->to_dds(*answer, cdr_);
      const CdrBody response(cdr_, cancel_response_.type.name);
      const auto code = response.at<std::uint8_t>(0);
      const auto canceling = response.at<std::uint32_t>(4);
      // HORUS answers how many goals it is canceling; ROS 2 lists them: the goal asked for, or
      // for all, the live goals the status showed.
      std::vector<const Goal*> listed;
      const bool all =
          std::all_of(id.begin(), id.end(), [](std::byte b) { return b == std::byte{0}; });
      for (const Goal& goal : goals_) {
        if (listed.size() < canceling && (all ? live(goal.state) : goal.id == id)) {
          listed.push_back(&goal);
        }
      }
      CdrWriter reply;
      reply.put(static_cast<std::int8_t>(code));
      reply.put(static_cast<std::uint32_t>(listed.size()));
      for (const Goal* goal : listed) {
        reply.put(goal->id);
        reply.put_time(goal->accepted_ns);
      }
      cancel_writer_.write(with_header(reply.done(), request.caller, request.sequence));
    }
  }

  // ROS 2's get_result answers once the goal has ended; HORUS's at once: a call for a live goal
  // waits here until A.status says it ended (or, failing that, asking again now and then).
  void take_get_result() {
    for (const auto& [writer, bytes] : get_result_reader_.take(std::chrono::nanoseconds(0))) {
      const Sample request = split_header(bytes);
      WaitingResult waiting{request.caller,
                            request.sequence,
                            CdrBody(request.cdr, "GetResult_Request").goal_id(),
                            {}};
      if (waiting_.size() >= kWaitingResultsMost) {
        fail(get_result_writer_, request,
             ServiceError::service_failed("too many get_result calls waiting"));
        continue;
      }
      waiting_.push_back(waiting);
    }
  }

  void answer_results() {
    const auto now = std::chrono::steady_clock::now();
    for (auto waiting = waiting_.begin(); waiting != waiting_.end();) {
      const Goal* goal = find_goal(goals_, waiting->id);
      const bool ended = goal != nullptr && !live(goal->state);
      if (!ended && now - waiting->asked < kResultRecheck) {
        ++waiting;
        continue;
      }
      waiting->asked = now;
      std::vector<std::byte> horus_request{std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0}};
      horus_request.insert(horus_request.end(), waiting->id.begin(), waiting->id.end());
      const ServiceResult<std::vector<std::byte>> answer =
          call(get_result_, get_result_request_, horus_request);
      const Sample request{waiting->caller, waiting->sequence, {}};
      if (!answer) {
        fail(get_result_writer_, request, answer.error());
        waiting = waiting_.erase(waiting);
        continue;
      }
      result_message_.conversion->to_dds(*answer, cdr_);
      const auto state = CdrBody(cdr_, result_message_.type.name).at<std::uint8_t>(kGoalId);
      if (live(state)) {
        ++waiting;
        continue;
      }
      const std::byte status{state == kRejected ? std::uint8_t{0} : state};
      const std::size_t offset = *result_message_.message->find_field("result")->offset;
      result_plan_.encode(answer->data() + offset, reply_cdr_, {}, std::span(&status, 1));
      get_result_writer_.write(with_header(reply_cdr_, waiting->caller, waiting->sequence));
      waiting = waiting_.erase(waiting);
    }
  }

  void forward_feedback() {
    for (std::ptrdiff_t size; (size = feedback_topic_->try_recv()) >= 0;) {
      feedback_.conversion->to_dds(feedback_topic_->received(static_cast<std::size_t>(size)), cdr_);
      feedback_writer_.write(cdr_);
    }
  }

  void follow_status() {
    bool changed = false;
    for (std::ptrdiff_t size; (size = status_topic_->try_recv()) >= 0;) {
      status_.conversion->to_dds(status_topic_->received(static_cast<std::size_t>(size)), cdr_);
      const CdrBody status(cdr_, status_.type.name);
      changed |=
          update(status.goal_id(), status.at<std::uint8_t>(kGoalId), status.at<std::uint64_t>(24));
    }
    if (changed) {
      publish_status();
    }
  }

  // A goal's state moves forward only (A.status may show Executing before send_goal's answer
  // came back here); a rejected goal never enters the table. True when it changed.
  bool update(const GoalId& id, std::uint8_t state, std::uint64_t stamp_ns) {
    if (state == kRejected || state == 0) {
      return false;
    }
    Goal* goal = find_goal(goals_, id);
    if (goal == nullptr) {
      goals_.push_back(Goal{id, stamp_ns, state});
      forget_ended(goals_);
      return true;
    }
    if (state <= goal->state) {
      return false;
    }
    goal->state = state;
    return true;
  }

  void publish_status() {
    CdrWriter array;
    array.put(static_cast<std::uint32_t>(goals_.size()));
    for (const Goal& goal : goals_) {
      array.put(goal.id);
      array.put_time(goal.accepted_ns);
      array.put(static_cast<std::int8_t>(goal.state));
    }
    status_writer_.write(array.done());
  }

  std::string name_;
  Payload send_goal_request_;
  Payload send_goal_response_;
  Payload cancel_request_;
  Payload cancel_response_;
  Payload get_result_request_;
  Payload result_message_;
  Payload feedback_;
  Payload status_;
  CdrPlan result_plan_;
  std::string module_;  // <pkg>::dds_::, the action's IDL module
  Reader send_goal_reader_;
  Writer send_goal_writer_;
  Reader cancel_reader_;
  Writer cancel_writer_;
  Reader get_result_reader_;
  Writer get_result_writer_;
  Writer feedback_writer_;
  Writer status_writer_;
  std::chrono::milliseconds timeout_;
  RawServiceClient send_goal_;
  RawServiceClient cancel_goal_;
  RawServiceClient get_result_;
  std::unique_ptr<RawTopic> feedback_topic_;
  std::unique_ptr<RawTopic> status_topic_;
  std::vector<Goal> goals_;  // in the order they came
  std::vector<WaitingResult> waiting_;
  std::vector<std::byte> local_;
  std::vector<std::byte> cdr_;
  std::vector<std::byte> reply_cdr_;
  std::atomic<std::uint64_t> failures_{0};
  std::atomic<bool> stopping_{false};
  std::thread thread_;  // last: started once everything it uses is there
};

// -- actions: a ROS 2 action server, served to local action clients -----------------------------

namespace {

// How long each of the three local servers' next() waits in turn (next(0) never receives).
constexpr auto kCallPoll = std::chrono::milliseconds(1);
constexpr const char* kRosRejected = "rejected by the ROS 2 action server (ROS 2 gives no reason)";

}  // namespace

// One thread per action. Local calls go out on DDS and are answered when their replies come
// back, so a call waiting on DDS holds up no other; each accepted goal's result is asked of ROS 2
// at once (ROS 2's get_result answers when the goal ends), and its answer is published as
// A.result, then the terminal A.status. The GoalStatusArray's Executing and Canceling become
// A.status of the goals sent from here; their feedback is A.feedback (the same CDR).
class ServiceRelays::ImportedAction {
 public:
  ImportedAction(const std::string& name, const std::string& module, const ActionParts& parts,
                 const TypeIdentity& feedback, const TypeIdentity& status,
                 const std::shared_ptr<Participant>& participant, const Qos& qos,
                 const std::string& namespace_name)
      : name_(name),
        module_(module),
        parts_(parts),
        send_goal_request_(*parts.send_goal_request),
        send_goal_response_(*parts.send_goal_response),
        cancel_request_(*parts.cancel_request),
        cancel_response_(*parts.cancel_response),
        get_result_request_(*parts.get_result_request),
        result_message_(*parts.result_message),
        feedback_(feedback),
        status_(status),
        result_plan_(result_plan(result_message_)),
        result_offset_(*result_message_.message->find_field("result")->offset),
        send_goal_writer_(participant, action_request_topic(name, "send_goal"),
                          TypeOnWire{module + name + "_SendGoal_Request_", {}, {}}, qos, ""),
        send_goal_reader_(participant, action_reply_topic(name, "send_goal"),
                          TypeOnWire{module + name + "_SendGoal_Response_", {}, {}}, qos, false),
        cancel_writer_(participant, action_request_topic(name, "cancel_goal"),
                       TypeOnWire{kCancelRequestType, {}, {}}, qos, ""),
        cancel_reader_(participant, action_reply_topic(name, "cancel_goal"),
                       TypeOnWire{kCancelResponseType, {}, {}}, qos, false),
        get_result_writer_(participant, action_request_topic(name, "get_result"),
                           TypeOnWire{module + name + "_GetResult_Request_", {}, {}}, qos, ""),
        get_result_reader_(participant, action_reply_topic(name, "get_result"),
                           TypeOnWire{module + name + "_GetResult_Response_", {}, {}}, qos, false),
        feedback_reader_(participant, "rt/" + name + "/_action/feedback",
                         TypeOnWire{module + name + "_FeedbackMessage_", {}, {}}, qos, false),
        // ROS 2's status writer is transient local: the array of now comes at once.
        status_reader_(participant, "rt/" + name + "/_action/status",
                       TypeOnWire{kStatusArrayType, {}, {}}, Qos{true, qos.depth, true, 0}, false),
        feedback_topic_(name + ".feedback", feedback, in_namespace(namespace_name)),
        status_topic_(name + ".status", status, in_namespace(namespace_name)),
        result_topic_(name + ".result", *parts.result_message, in_namespace(namespace_name)),
        namespace_(namespace_name),
        caller_(new_service_endpoint_id()),
        thread_([this] { run(); }) {}

  ~ImportedAction() {
    stopping_.store(true);
    thread_.join();
  }
  ImportedAction(const ImportedAction&) = delete;
  ImportedAction& operator=(const ImportedAction&) = delete;

 private:
  enum class Kind : std::uint8_t { kSendGoal, kCancelGoal, kGetResult };
  // A request written to DDS whose reply is awaited. kGetResult ones are the bridge's own (no
  // local caller) and wait as long as their goal runs.
  struct Call {
    Kind kind;
    std::int64_t sequence = 0;
    ServiceCaller caller;
    GoalId id;
    std::chrono::steady_clock::time_point deadline;
    // A send_goal's: the state a status array showed before the reply came (it may come first).
    std::uint8_t early_state = 0;
  };
  struct Goal {
    GoalId id;
    std::uint8_t state = 0;
    std::uint64_t stamp_ns = 0;
    std::vector<std::byte> result;  // the A.result message once it ended
  };

  void run() {
    while (!stopping_.load() && !serving()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    while (!stopping_.load()) {
      try {
        take_calls();
        take_replies();
        forward_feedback();
        follow_status();
        expire_calls();
      } catch (const std::exception& error) {
        failed("action '" + name_ + "'", failures_, error.what(), "carrying on");
        std::this_thread::sleep_for(kRetry);
      }
    }
    for (const Call& call : calls_) {
      fail(call, ServiceError::no_server("the import of the action ended (its ROS 2 server left "
                                         "DDS, or the bridge stopped)"));
    }
  }

  // The local services are registered once the ROS 2 server's request readers match this
  // side's writers, as a request written before would be lost.
  bool serving() {
    if (send_goal_writer_.matched() == 0 || cancel_writer_.matched() == 0 ||
        get_result_writer_.matched() == 0) {
      return false;
    }
    const TopicOptions options = in_namespace(namespace_);
    send_goal_.emplace(raw_type(name_ + ".send_goal", parts_.send_goal_fingerprint,
                                send_goal_request_, send_goal_response_),
                       options);
    cancel_goal_.emplace(raw_type(name_ + ".cancel_goal", parts_.cancel_goal_fingerprint,
                                  cancel_request_, cancel_response_),
                         options);
    get_result_.emplace(raw_type(name_ + ".get_result", parts_.get_result_fingerprint,
                                 get_result_request_, result_message_),
                        options);
    say("importing action '" + name_ + "' from rr/" + name_ + "/_action/{send_goal,cancel_goal," +
        "get_result}Reply, rt/" + name_ + "/_action/{feedback,status} (" + module_ + name_ + "_*)");
    return true;
  }

  void take_calls() {
    if (auto request = send_goal_->next(kCallPoll)) {
      send_goal_request_.conversion->to_dds(request->payload, cdr_);  // ROS 2's request's CDR
      relay(send_goal_writer_, Kind::kSendGoal, request->caller,
            CdrBody(cdr_, send_goal_request_.type.name).goal_id(), cdr_);
    }
    if (auto request = cancel_goal_->next(kCallPoll)) {
      cancel_request_.conversion->to_dds(request->payload, cdr_);
      const GoalId id = CdrBody(cdr_, cancel_request_.type.name).goal_id();
      // HORUS cancels by id alone (all zero: every live goal), ROS 2 by id and stamp, where a
      // zero stamp adds no goal.
      CdrWriter cancel;
      cancel.put(id);
      cancel.put_time(0);
      relay(cancel_writer_, Kind::kCancelGoal, request->caller, id, cancel.done());
    }
    if (auto request = get_result_->next(kCallPoll)) {
      answer_get_result(*request);
    }
  }

  // Writes a call to DDS, its reply awaited in calls_; with no ROS 2 server matched, the caller
  // gets NoServer at once.
  void relay(Writer& writer, Kind kind, const ServiceCaller& caller, const GoalId& id,
             std::span<const std::byte> cdr) {
    if (writer.matched() == 0) {
      fail(Call{kind, 0, caller, id, {}},
           ServiceError::no_server("no ROS 2 action server of " + name_ + " on DDS"));
      return;
    }
    const std::int64_t sequence = ++sequence_;
    try {
      writer.write(with_header(cdr, caller_, sequence));
    } catch (const std::exception& error) {
      fail(Call{kind, 0, caller, id, {}},
           ServiceError::transport(std::string("the request did not go out on DDS: ") +
                                   error.what()));
      return;
    }
    calls_.push_back(
        Call{kind, sequence, caller, id, std::chrono::steady_clock::now() + kReplyTimeout});
  }

  void fail(const Call& call, const ServiceError& error) {
    switch (call.kind) {
      case Kind::kSendGoal:
        send_goal_->fail(call.caller, error);
        break;
      case Kind::kCancelGoal:
        cancel_goal_->fail(call.caller, error);
        break;
      case Kind::kGetResult:
        end(call.id, kAborted,
            "the ROS 2 action server's result did not come: " + error.to_string(),
            default_result());
        break;
    }
  }

  void take_replies() {
    const std::array<std::pair<Reader*, Kind>, 3> readers = {
        std::pair{&send_goal_reader_, Kind::kSendGoal},
        std::pair{&cancel_reader_, Kind::kCancelGoal},
        std::pair{&get_result_reader_, Kind::kGetResult}};
    for (const auto& [reader, kind] : readers) {
      for (const auto& [writer, bytes] : reader->take(std::chrono::nanoseconds(0))) {
        Sample reply;
        try {
          reply = split_header(bytes);
        } catch (const std::exception&) {
          continue;  // not a reply of this protocol
        }
        const auto call = std::find_if(calls_.begin(), calls_.end(), [&](const Call& waiting) {
          return waiting.kind == kind && reply.caller == caller_ &&
                 (reply.sequence == waiting.sequence || reply.sequence == -waiting.sequence);
        });
        if (call == calls_.end()) {
          continue;  // another caller's reply, or a late one to a call that timed out
        }
        const Call answered = *call;
        calls_.erase(call);
        if (reply.sequence < 0) {  // a HORUS bridge exporting the action could not answer
          fail(answered, remote_error(failure_text(reply.cdr)));
        } else if (kind == Kind::kSendGoal) {
          answered_send_goal(answered, reply.cdr);
        } else if (kind == Kind::kCancelGoal) {
          answered_cancel_goal(answered, reply.cdr);
        } else {
          answered_get_result(answered, reply.cdr);
        }
      }
    }
  }

  void answered_send_goal(const Call& call, std::span<const std::byte> cdr) {
    const CdrBody response(cdr, "SendGoal_Response");
    const bool accepted = response.at<std::uint8_t>(0) != 0;
    const std::uint64_t stamp_ns = response.time_at(4);
    const std::string reason = accepted ? std::string() : kRosRejected;
    CdrWriter answer;
    answer.put(static_cast<std::uint8_t>(accepted));
    answer.put(stamp_ns);
    answer.put(reason);
    answer_local(*send_goal_, send_goal_response_, call.caller, answer.done());
    publish_status(call.id, accepted ? kAccepted : kRejected, stamp_ns, reason);
    if (!accepted) {
      return;
    }
    goals_.push_back(Goal{call.id, kAccepted, stamp_ns, {}});
    advance(goals_.back(), call.early_state);
    forget_ended(goals_);
    CdrWriter ask;
    ask.put(call.id);
    const std::int64_t sequence = ++sequence_;
    try {
      get_result_writer_.write(with_header(ask.done(), caller_, sequence));
    } catch (const std::exception& error) {
      end(call.id, kAborted, std::string("its get_result did not go out on DDS: ") + error.what(),
          default_result());
      return;
    }
    calls_.push_back(Call{
        Kind::kGetResult, sequence, {}, call.id, std::chrono::steady_clock::time_point::max()});
  }

  // ROS 2 lists the goals it is canceling, HORUS answers how many.
  void answered_cancel_goal(const Call& call, std::span<const std::byte> cdr) {
    const CdrBody response(cdr, "CancelGoal_Response");
    CdrWriter answer;
    answer.put(static_cast<std::uint8_t>(response.at<std::int8_t>(0)));
    answer.put(response.at<std::uint32_t>(4));
    answer_local(*cancel_goal_, cancel_response_, call.caller, answer.done());
  }

  void answered_get_result(const Call& call, std::span<const std::byte> cdr) {
    const auto status =
        static_cast<std::uint8_t>(CdrBody(cdr, "GetResult_Response").at<std::int8_t>(0));
    std::vector<std::byte> result(result_plan_.pod_size());
    if (std::string why = result_plan_.decode(cdr, result.data(), nullptr, 1); !why.empty()) {
      end(call.id, kAborted, "the ROS 2 action server's result does not decode: " + why,
          default_result());
      return;
    }
    switch (status) {
      case kSucceeded:
        end(call.id, status, "", result.data());
        break;
      case kCanceled:
        end(call.id, status, "canceled on the ROS 2 action server", result.data());
        break;
      case kAborted:
        end(call.id, status, "aborted by the ROS 2 action server (ROS 2 gives no reason)",
            result.data());
        break;
      default:
        end(call.id, kAborted,
            "the ROS 2 action server answered get_result with status " + std::to_string(status),
            result.data());
    }
  }

  // A.result, then the terminal A.status, as a HORUS server ends a goal.
  void end(const GoalId& id, std::uint8_t state, const std::string& reason,
           const std::byte* result) {
    const std::uint64_t stamp_ns = now_ns();
    std::vector<std::byte> message = result_message(id, state, stamp_ns, reason, result);
    result_topic_.send(message);
    publish_status(id, state, stamp_ns, reason);
    if (Goal* goal = find_goal(goals_, id)) {
      goal->state = state;
      goal->stamp_ns = stamp_ns;
      goal->result = std::move(message);
      forget_ended(goals_);
    }
  }

  // HORUS's get_result answers at once: an ended goal's outcome, a live one's state, else Unknown.
  void answer_get_result(const RawServiceServer::Request& request) {
    get_result_request_.conversion->to_dds(request.payload, cdr_);
    const GoalId id = CdrBody(cdr_, get_result_request_.type.name).goal_id();
    const Goal* goal = find_goal(goals_, id);
    if (goal != nullptr && !goal->result.empty()) {
      get_result_->answer(request.caller, goal->result);
      return;
    }
    get_result_->answer(
        request.caller,
        goal == nullptr
            ? result_message(id, 0, now_ns(), "no such goal on this server", default_result())
            : result_message(id, goal->state, goal->stamp_ns, "", default_result()));
  }

  void forward_feedback() {
    for (const auto& [writer, bytes] : feedback_reader_.take(std::chrono::nanoseconds(0))) {
      const auto sample = std::as_bytes(std::span(bytes));
      if (!ours(CdrBody(sample, feedback_.type.name).goal_id())) {
        continue;  // another ROS 2 client's goal
      }
      if (std::string why = feedback_.conversion->to_local(sample, local_); !why.empty()) {
        throw std::runtime_error("a feedback message does not decode: " + why);
      }
      feedback_topic_.send(local_);
    }
  }

  // GoalStatusArray {GoalStatus[] {GoalInfo {UUID goal_id; Time stamp}; int8 status}}: the states
  // a goal passes through that no reply tells (the end comes from get_result).
  void follow_status() {
    for (const auto& [writer, bytes] : status_reader_.take(std::chrono::nanoseconds(0))) {
      const CdrBody array(std::as_bytes(std::span(bytes)), "GoalStatusArray");
      const auto count = array.at<std::uint32_t>(0);
      std::size_t offset = 4;
      for (std::uint32_t i = 0; i < count; ++i) {
        const GoalId id = array.goal_id(offset);
        offset = (offset + kGoalId + 3) / 4 * 4;  // the stamp's int32 aligns to 4
        const auto state = static_cast<std::uint8_t>(array.at<std::int8_t>(offset + 8));
        offset += 9;
        if (Goal* goal = find_goal(goals_, id)) {
          advance(*goal, state);
          continue;
        }
        for (Call& call : calls_) {
          if (call.kind == Kind::kSendGoal && call.id == id) {
            call.early_state = std::max(call.early_state, state);
          }
        }
      }
    }
  }

  void advance(Goal& goal, std::uint8_t state) {
    if (live(goal.state) && (state == kExecuting || state == kCanceling) && state > goal.state) {
      goal.state = state;
      publish_status(goal.id, state, now_ns(), "");
    }
  }

  void expire_calls() {
    const auto now = std::chrono::steady_clock::now();
    for (auto call = calls_.begin(); call != calls_.end();) {
      if (now < call->deadline) {
        ++call;
        continue;
      }
      const Call late = *call;
      call = calls_.erase(call);
      fail(late, ServiceError::timeout("no reply over DDS within " +
                                       std::to_string(kReplyTimeout.count()) + " s"));
    }
  }

  // A goal sent from here: accepted, or its send_goal reply still to come (feedback may beat it).
  bool ours(const GoalId& id) {
    return find_goal(goals_, id) != nullptr ||
           std::any_of(calls_.begin(), calls_.end(), [&](const Call& call) {
             return call.kind == Kind::kSendGoal && call.id == id;
           });
  }

  void answer_local(RawServiceServer& server, Payload& response, const ServiceCaller& caller,
                    std::span<const std::byte> cdr) {
    if (std::string why = response.conversion->to_local(cdr, local_); !why.empty()) {
      server.fail(caller, ServiceError::transport("the answer does not convert: " + why));
      return;
    }
    server.answer(caller, local_);
  }

  void publish_status(const GoalId& id, std::uint8_t state, std::uint64_t stamp_ns,
                      const std::string& reason) {
    CdrWriter status;
    status.put(id);
    status.put(state);
    status.put(stamp_ns);
    status.put(reason);
    if (std::string why = status_.conversion->to_local(status.done(), local_); !why.empty()) {
      throw std::runtime_error("a status does not convert: " + why);
    }
    status_topic_.send(local_);
  }

  // The local A.result message (get_result's answer) of a result in its POD layout.
  std::vector<std::byte> result_message(const GoalId& id, std::uint8_t state,
                                        std::uint64_t stamp_ns, const std::string& reason,
                                        const std::byte* result) {
    CdrWriter members;
    members.put(id);
    members.put(state);
    members.put(stamp_ns);
    members.put(reason);
    result_plan_.encode(result, cdr_, {}, members.body());
    std::vector<std::byte> message;
    if (std::string why = result_message_.conversion->to_local(cdr_, message); !why.empty()) {
      throw std::runtime_error("a result message does not convert: " + why);
    }
    return message;
  }

  // The result type's defaults (in the defaults of the whole result message).
  const std::byte* default_result() const { return result_message_.empty.data() + result_offset_; }

  std::string name_;
  std::string module_;  // <pkg>::dds_::, the action's IDL module
  ActionParts parts_;
  Payload send_goal_request_;
  Payload send_goal_response_;
  Payload cancel_request_;
  Payload cancel_response_;
  Payload get_result_request_;
  Payload result_message_;
  Payload feedback_;
  Payload status_;
  CdrPlan result_plan_;
  std::size_t result_offset_;
  Writer send_goal_writer_;
  Reader send_goal_reader_;
  Writer cancel_writer_;
  Reader cancel_reader_;
  Writer get_result_writer_;
  Reader get_result_reader_;
  Reader feedback_reader_;
  Reader status_reader_;
  RawTopic feedback_topic_;
  RawTopic status_topic_;
  RawTopic result_topic_;
  std::string namespace_;
  std::uint64_t caller_;  // this import's id in the request header, unique on the machine
  std::int64_t sequence_ = 0;
  std::optional<RawServiceServer> send_goal_;  // registered once serving()
  std::optional<RawServiceServer> cancel_goal_;
  std::optional<RawServiceServer> get_result_;
  std::vector<Call> calls_;
  std::vector<Goal> goals_;  // in the order they were accepted
  std::vector<std::byte> cdr_;
  std::vector<std::byte> local_;
  std::atomic<std::uint64_t> failures_{0};
  std::atomic<bool> stopping_{false};
  std::thread thread_;  // last: started once everything it uses is there
};

// -- the relays ---------------------------------------------------------------------------------

ServiceRelays::ServiceRelays(std::vector<std::string> exports, std::vector<std::string> imports,
                             std::vector<std::string> export_actions,
                             std::vector<std::string> import_actions,
                             std::chrono::duration<double> call_timeout, std::string namespace_name,
                             std::shared_ptr<Participant> participant, Qos qos, TypeLookup lookup)
    : policy_(std::move(exports), std::move(imports)),
      exporting_actions_(!export_actions.empty()),
      importing_actions_(!import_actions.empty()),
      action_policy_(std::move(export_actions), std::move(import_actions)),
      call_timeout_(call_timeout),
      namespace_(std::move(namespace_name)),
      participant_(std::move(participant)),
      qos_(qos),
      lookup_(std::move(lookup)) {}

ServiceRelays::~ServiceRelays() {
  imported_actions_.clear();
  exported_actions_.clear();
  exported_.clear();
  imported_.clear();
}

void ServiceRelays::scan() {
  scan_exports();
  scan_imports();
}

void ServiceRelays::scan_exports() {
  const std::vector<ServiceInfo> services = list_services(namespace_);
  if (exporting_actions_) {
    scan_actions(services);
  }
  for (const ServiceInfo& entry : services) {
    const std::string& name = entry.name;
    if (!policy_.exported(name) || refused_.contains(name)) {
      continue;
    }
    if (const auto running = exported_.find(name); running != exported_.end()) {
      if (entry.servers == 0) {  // the server left: so does the service, from DDS
        exported_.erase(running);
        say("no longer exporting service '" + name + "' (its server stopped)");
      }
      continue;
    }
    if (entry.servers == 0) {
      continue;
    }
    if (policy_.imported(name)) {
      refused_.insert(name);
      complain(both_ways("service", name));
      continue;
    }
    try {
      export_service(name, entry.request_type, entry.response_type, entry.fingerprint);
    } catch (const std::exception& error) {
      refused_.insert(name);
      complain("cannot export service '" + name + "': " + error.what());
    }
  }
}

// The payload types come from the service's request topic and a reply topic (their frames'
// descriptions), else from the lookup; while neither gives the response type, the service waits
// (the first reply topic shows it).
std::optional<std::pair<TypeIdentity, TypeIdentity>> ServiceRelays::service_types(
    const std::string& name, const std::string& request_type, const std::string& response_type) {
  std::optional<TypeIdentity> request;
  std::optional<TypeIdentity> response;
  std::string undescribed;  // a frame topic that carries no description (a Python program's)
  const std::string replies = name + ".response.";
  for (const TopicInfo& topic : list_topics(namespace_)) {
    if (topic.type_name.empty() || !topic.error.empty()) {
      continue;
    }
    const bool requests = topic.name == name + ".request";
    if ((requests && request) || (!requests && (response || !topic.name.starts_with(replies)))) {
      continue;
    }
    if (topic.description.empty()) {
      undescribed = topic.name;
      continue;
    }
    TypeIdentity payload = service_payload_type(type_identity_of(topic), !requests);
    const std::string& registered = requests ? request_type : response_type;
    if (payload.name != registered) {
      throw std::runtime_error("its topic " + topic.name + " carries frames of " + payload.name +
                               ", not of " + registered);
    }
    (requests ? request : response) = std::move(payload);
  }
  if (!request && lookup_) {
    request = lookup_(request_type);
  }
  if (!response && lookup_) {
    response = lookup_(response_type);
  }
  if (!request && !undescribed.empty()) {
    throw std::runtime_error("its topic " + undescribed +
                             " carries no type description, and this process knows no " +
                             request_type);
  }
  if (!request || !response) {
    return std::nullopt;
  }
  return std::pair{std::move(*request), std::move(*response)};
}

// The payload types come from the service's request topic and a reply topic (their frames'
// descriptions), else from the lookup; while neither gives the response type, the service waits
// (the first reply topic shows it).
void ServiceRelays::export_service(const std::string& name, const std::string& request_type,
                                   const std::string& response_type, std::uint64_t fingerprint) {
  auto types = service_types(name, request_type, response_type);
  if (!types) {
    return;
  }
  auto exported = std::make_unique<Exported>(name, fingerprint, std::move(types->first),
                                             std::move(types->second), participant_, qos_,
                                             call_timeout_, namespace_);
  say(exported->said());
  exported_[name] = std::move(exported);
}

// An action A is its services A.send_goal, A.cancel_goal, A.get_result and its topics A.feedback
// and A.status (runtime/src/action/README.md): exported once all five are there with a live
// server, and no longer once A.send_goal's server is gone.
void ServiceRelays::scan_actions(const std::vector<ServiceInfo>& services) {
  std::map<std::string, const ServiceInfo*> served;
  for (const ServiceInfo& entry : services) {
    if (entry.servers > 0) {
      served[entry.name] = &entry;
    }
  }
  constexpr std::string_view kSendGoal = ".send_goal";
  for (auto carried = exported_actions_.begin(); carried != exported_actions_.end();) {
    if (served.contains(carried->first + std::string(kSendGoal))) {
      ++carried;
      continue;
    }
    const std::string name = carried->first;
    carried = exported_actions_.erase(carried);
    say("no longer exporting action '" + name + "' (its server stopped)");
  }
  for (const auto& [service, entry] : served) {
    if (!service.ends_with(kSendGoal)) {
      continue;
    }
    const std::string name = service.substr(0, service.size() - kSendGoal.size());
    if (!action_policy_.exported(name) || exported_actions_.contains(name) ||
        refused_actions_.contains(name)) {
      continue;
    }
    const auto cancel = served.find(name + ".cancel_goal");
    const auto result = served.find(name + ".get_result");
    if (cancel == served.end() || result == served.end()) {
      continue;
    }
    if (action_policy_.imported(name)) {
      refused_actions_.insert(name);
      complain(both_ways("action", name));
      continue;
    }
    try {
      export_action(name, *entry, *cancel->second, *result->second);
    } catch (const std::exception& error) {
      refused_actions_.insert(name);
      complain("cannot export action '" + name + "': " + error.what());
    }
  }
}

void ServiceRelays::export_action(const std::string& name, const ServiceInfo& send_goal,
                                  const ServiceInfo& cancel_goal, const ServiceInfo& get_result) {
  ActionParts parts;
  parts.send_goal_fingerprint = send_goal.fingerprint;
  parts.cancel_goal_fingerprint = cancel_goal.fingerprint;
  parts.get_result_fingerprint = get_result.fingerprint;
  if (!action_service_types(
          name,
          {send_goal.request_type, send_goal.response_type, cancel_goal.request_type,
           cancel_goal.response_type, get_result.request_type, get_result.response_type},
          parts)) {
    return;  // a reply topic still to come
  }
  std::optional<TopicInfo> feedback;
  std::optional<TopicInfo> status;
  for (TopicInfo& topic : list_topics(namespace_)) {
    if (topic.description.empty() || !topic.error.empty()) {
      continue;
    }
    if (topic.name == name + ".feedback")
      feedback = std::move(topic);
    else if (topic.name == name + ".status")
      status = std::move(topic);
  }
  if (!feedback || !status) {
    return;
  }
  auto exported = std::make_unique<ExportedAction>(name, parts, *feedback, *status, participant_,
                                                   qos_, call_timeout_, namespace_);
  say(exported->said());
  exported_actions_[name] = std::move(exported);
}

// `types`: the request and response type names of send_goal, cancel_goal and get_result.
bool ServiceRelays::action_service_types(const std::string& name,
                                         const std::array<std::string, 6>& types,
                                         ActionParts& parts) {
  auto sending = service_types(name + ".send_goal", types[0], types[1]);
  auto canceling = service_types(name + ".cancel_goal", types[2], types[3]);
  auto resulting = service_types(name + ".get_result", types[4], types[5]);
  if (!sending || !canceling || !resulting) {
    return false;
  }
  std::tie(parts.send_goal_request, parts.send_goal_response) = std::move(*sending);
  std::tie(parts.cancel_request, parts.cancel_response) = std::move(*canceling);
  std::tie(parts.get_result_request, parts.result_message) = std::move(*resulting);
  return true;
}

void ServiceRelays::scan_imports() {
  std::vector<Publication> publications = participant_->publications();
  if (importing_actions_) {
    scan_action_imports(publications);
  }
  std::map<std::string, Publication> offered;
  for (Publication& publication : publications) {
    const std::string& topic = publication.topic;
    if (!topic.starts_with(kReplyPrefix) || !topic.ends_with(kReplySuffix) ||
        topic.size() <= std::strlen(kReplyPrefix) + std::strlen(kReplySuffix)) {
      continue;
    }
    std::string name =
        topic.substr(std::strlen(kReplyPrefix),
                     topic.size() - std::strlen(kReplyPrefix) - std::strlen(kReplySuffix));
    if (policy_.imported(name) && !publication.user_data.empty()) {
      offered.emplace(std::move(name), std::move(publication));
    }
  }
  follow_offers("service", offered, imported_, refused_, policy_,
                [this](const std::string& name, const Publication& publication) {
                  import_service(name, publication);
                });
}

// A ROS 2 action server of A is there while its rr/A/_action/send_goalReply writer is; the
// import ends when it goes (local clients' goals then end as with any server that stops).
void ServiceRelays::scan_action_imports(const std::vector<Publication>& publications) {
  constexpr std::string_view kSendGoalReply = "/_action/send_goalReply";
  std::map<std::string, std::string> offered;  // each action's send_goal response type
  for (const Publication& publication : publications) {
    const std::string& topic = publication.topic;
    if (!topic.starts_with(kReplyPrefix) || !topic.ends_with(kSendGoalReply) ||
        topic.size() <= std::strlen(kReplyPrefix) + kSendGoalReply.size()) {
      continue;
    }
    std::string name =
        topic.substr(std::strlen(kReplyPrefix),
                     topic.size() - std::strlen(kReplyPrefix) - kSendGoalReply.size());
    if (action_policy_.imported(name)) {
      offered.emplace(std::move(name), publication.type);
    }
  }
  follow_offers("action", offered, imported_actions_, refused_actions_, action_policy_,
                [this](const std::string& name, const std::string& response_type) {
                  import_action(name, response_type);
                });
}

// The HORUS types are the ones horus-gen makes of the action's .haction, named after its DDS
// module (<pkg>::dds_::A_SendGoal_Response_ is pkg.ASendGoalResponse), found as an exported
// service's are (local topics, else the lookup); the import waits while they cannot be known.
void ServiceRelays::import_action(const std::string& name, const std::string& response_type) {
  const std::string suffix = name + "_SendGoal_Response_";
  constexpr std::string_view kModule = "::dds_::";
  if (!response_type.ends_with(std::string(kModule) + suffix)) {
    throw std::runtime_error("its send_goal replies are of the DDS type " + response_type +
                             ", not <pkg>::dds_::" + suffix);
  }
  const std::string module = response_type.substr(0, response_type.size() - suffix.size());
  std::string package = module.substr(0, module.size() - kModule.size());
  for (std::size_t at; (at = package.find("::")) != std::string::npos;) {
    package.replace(at, 2, ".");
  }
  const std::string action = package + "." + name;
  const std::array<std::string, 6> types = {
      action + "SendGoalRequest",    action + "SendGoalResponse", action + "CancelGoalRequest",
      action + "CancelGoalResponse", action + "GetResultRequest", action + "ResultMessage"};
  ActionParts parts;
  if (!action_service_types(name, types, parts)) {
    return;
  }
  // A generated server registers each service with its fingerprint over both payload types.
  const auto fingerprint = [&](const char* service, const TypeIdentity& request,
                               const TypeIdentity& response) {
    const auto hex = [](std::uint64_t value) {
      char digits[17];
      std::snprintf(digits, sizeof digits, "%016llx", static_cast<unsigned long long>(value));
      return std::string(digits);
    };
    return sha256_fingerprint("service " + action + service + " {\n  request: " + request.name +
                              "#" + hex(request.fingerprint) + ",\n  response: " + response.name +
                              "#" + hex(response.fingerprint) + ",\n}\n");
  };
  parts.send_goal_fingerprint =
      fingerprint("SendGoal", *parts.send_goal_request, *parts.send_goal_response);
  parts.cancel_goal_fingerprint =
      fingerprint("CancelGoal", *parts.cancel_request, *parts.cancel_response);
  parts.get_result_fingerprint =
      fingerprint("GetResult", *parts.get_result_request, *parts.result_message);
  const std::optional<TypeIdentity> feedback =
      topic_type(name + ".feedback", action + "FeedbackMessage");
  const std::optional<TypeIdentity> status = topic_type(name + ".status", action + "Status");
  if (!feedback || !status) {
    return;
  }
  if (const std::string own = action_module(Payload(*parts.send_goal_request)); own != module) {
    throw std::runtime_error("its HORUS types are of the DDS module " + own + ", not " + module);
  }
  imported_actions_[name] = std::make_unique<ImportedAction>(
      name, module, parts, *feedback, *status, participant_, qos_, namespace_);
}

// A topic's type from its segment (when it carries a description), else from the lookup.
std::optional<TypeIdentity> ServiceRelays::topic_type(const std::string& topic,
                                                      const std::string& type) {
  for (const TopicInfo& info : list_topics(namespace_)) {
    if (info.name == topic && !info.description.empty() && info.error.empty()) {
      TypeIdentity found = type_identity_of(info);
      if (found.name != type) {
        throw std::runtime_error("its topic " + topic + " carries " + found.name + ", not " + type);
      }
      return found;
    }
  }
  return lookup_ ? lookup_(type) : std::nullopt;
}

void ServiceRelays::import_service(const std::string& name, const Publication& publication) {
  const ServiceIdentity identity = parse_service_user_data(publication.user_data);
  if (identity.service != name) {
    throw std::runtime_error("its DDS replies name the service " + identity.service);
  }
  const std::string response_type = Payload(identity.response).dds_type(name, "Response_");
  if (response_type != publication.type) {
    throw std::runtime_error("DDS carries its replies as " + publication.type +
                             ", its HORUS types make " + response_type);
  }
  imported_[name] = std::make_unique<Imported>(identity, participant_, qos_, namespace_);
  say("importing service '" + name + "' from " + publication.topic + " (" + response_type + ")");
}

}  // namespace horus::dds_bridge
