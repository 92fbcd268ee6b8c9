#include "horus/dds/services.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
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

std::string both_ways(const std::string& name) {
  return "refusing service '" + name + "': it matches both --export-service and --import-service";
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
constexpr std::uint8_t kCanceling = 3;
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
  GoalId goal_id() const {
    need(kGoalId);
    GoalId id{};
    std::memcpy(id.data(), body_.data(), kGoalId);
    return id;
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

/// The local types an exported action needs: its three services' payloads and its two topics.
struct ServiceRelays::ActionParts {
  std::uint64_t send_goal_fingerprint = 0;
  std::uint64_t cancel_goal_fingerprint = 0;
  std::uint64_t get_result_fingerprint = 0;
  std::optional<TypeIdentity> send_goal_request, send_goal_response, cancel_request,
      cancel_response, get_result_request, result_message;
  std::optional<TopicInfo> feedback, status;
};

// One thread per action: the three services' DDS requests, each answered by a call to the local
// server; A.status followed into the goal table whose whole GoalStatusArray goes out on each
// change; A.feedback written as it comes (its CDR is ROS 2's FeedbackMessage: the goal id's 16
// bytes, then the feedback).
class ServiceRelays::ExportedAction {
 public:
  ExportedAction(const std::string& name, const ActionParts& parts,
                 const std::shared_ptr<Participant>& participant, const Qos& qos,
                 std::chrono::duration<double> timeout, const std::string& namespace_name)
      : name_(name),
        send_goal_request_(*parts.send_goal_request),
        send_goal_response_(*parts.send_goal_response),
        cancel_request_(*parts.cancel_request),
        cancel_response_(*parts.cancel_response),
        get_result_request_(*parts.get_result_request),
        result_message_(*parts.result_message),
        feedback_(type_identity_of(*parts.feedback)),
        status_(type_identity_of(*parts.status)),
        result_plan_(result_plan(result_message_)),
        module_(action_module(send_goal_request_)),
        send_goal_reader_(participant, request_topic("send_goal"),
                          TypeOnWire{module_ + name + "_SendGoal_Request_", {}, {}}, qos, false),
        send_goal_writer_(participant, reply_topic("send_goal"),
                          TypeOnWire{module_ + name + "_SendGoal_Response_", {}, {}}, qos, ""),
        cancel_reader_(participant, request_topic("cancel_goal"),
                       TypeOnWire{"action_msgs::srv::dds_::CancelGoal_Request_", {}, {}}, qos,
                       false),
        cancel_writer_(participant, reply_topic("cancel_goal"),
                       TypeOnWire{"action_msgs::srv::dds_::CancelGoal_Response_", {}, {}}, qos, ""),
        get_result_reader_(participant, request_topic("get_result"),
                           TypeOnWire{module_ + name + "_GetResult_Request_", {}, {}}, qos, false),
        get_result_writer_(participant, reply_topic("get_result"),
                           TypeOnWire{module_ + name + "_GetResult_Response_", {}, {}}, qos, ""),
        feedback_writer_(participant, "rt/" + name + "/_action/feedback",
                         TypeOnWire{module_ + name + "_FeedbackMessage_", {}, {}}, qos, ""),
        // ROS 2's status QoS: reliable, transient local, the last array only.
        status_writer_(participant, "rt/" + name + "/_action/status",
                       TypeOnWire{"action_msgs::msg::dds_::GoalStatusArray_", {}, {}},
                       Qos{true, 1, true, 0}, ""),
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
        feedback_topic_(RawTopic::open_recorded(*parts.feedback, namespace_name)),
        status_topic_(RawTopic::open_recorded(*parts.status, namespace_name)),
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

  static std::string action_module(const Payload& request) {
    const std::string own = dds_type_name(*request.description, *request.message);
    return own.substr(0, own.rfind("::") + 2);
  }
  std::string request_topic(const char* service) const {
    return kRequestPrefix + name_ + "/_action/" + service + "Request";
  }
  std::string reply_topic(const char* service) const {
    return kReplyPrefix + name_ + "/_action/" + service + kReplySuffix;
  }

  // The plan of the result member of A.get_result's answer, which ROS 2's GetResult response
  // puts after its status byte (so its members align otherwise than in HORUS's message).
  static CdrPlan result_plan(const Payload& message) {
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
      const Goal* goal = find(waiting->id);
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

  const Goal* find(const GoalId& id) const {
    const auto found =
        std::find_if(goals_.begin(), goals_.end(), [&](const Goal& goal) { return goal.id == id; });
    return found == goals_.end() ? nullptr : &*found;
  }

  // A goal's state moves forward only (A.status may show Executing before send_goal's answer
  // came back here); a rejected goal never enters the table. True when it changed.
  bool update(const GoalId& id, std::uint8_t state, std::uint64_t stamp_ns) {
    if (state == kRejected || state == 0) {
      return false;
    }
    auto goal = std::find_if(goals_.begin(), goals_.end(),
                             [&](const Goal& known) { return known.id == id; });
    if (goal == goals_.end()) {
      goals_.push_back(Goal{id, stamp_ns, state});
      forget_ended();
      return true;
    }
    if (state <= goal->state) {
      return false;
    }
    goal->state = state;
    return true;
  }

  void forget_ended() {
    std::size_t ended = std::count_if(goals_.begin(), goals_.end(),
                                      [](const Goal& goal) { return !live(goal.state); });
    for (auto goal = goals_.begin(); ended > kEndedGoalsKept && goal != goals_.end();) {
      if (live(goal->state)) {
        ++goal;
      } else {
        goal = goals_.erase(goal);
        --ended;
      }
    }
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

// -- the relays ---------------------------------------------------------------------------------

ServiceRelays::ServiceRelays(std::vector<std::string> exports, std::vector<std::string> imports,
                             std::vector<std::string> export_actions,
                             std::chrono::duration<double> call_timeout, std::string namespace_name,
                             std::shared_ptr<Participant> participant, Qos qos, TypeLookup lookup)
    : policy_(std::move(exports), std::move(imports)),
      exporting_actions_(!export_actions.empty()),
      action_policy_(std::move(export_actions), {}),
      call_timeout_(call_timeout),
      namespace_(std::move(namespace_name)),
      participant_(std::move(participant)),
      qos_(qos),
      lookup_(std::move(lookup)) {}

ServiceRelays::~ServiceRelays() {
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
      complain(both_ways(name));
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
  auto sending = service_types(send_goal.name, send_goal.request_type, send_goal.response_type);
  auto canceling =
      service_types(cancel_goal.name, cancel_goal.request_type, cancel_goal.response_type);
  auto resulting =
      service_types(get_result.name, get_result.request_type, get_result.response_type);
  if (!sending || !canceling || !resulting) {
    return;  // a reply topic still to come
  }
  for (TopicInfo& topic : list_topics(namespace_)) {
    if (topic.description.empty() || !topic.error.empty()) {
      continue;
    }
    if (topic.name == name + ".feedback")
      parts.feedback = std::move(topic);
    else if (topic.name == name + ".status")
      parts.status = std::move(topic);
  }
  if (!parts.feedback || !parts.status) {
    return;
  }
  std::tie(parts.send_goal_request, parts.send_goal_response) = std::move(*sending);
  std::tie(parts.cancel_request, parts.cancel_response) = std::move(*canceling);
  std::tie(parts.get_result_request, parts.result_message) = std::move(*resulting);
  auto exported =
      std::make_unique<ExportedAction>(name, parts, participant_, qos_, call_timeout_, namespace_);
  say(exported->said());
  exported_actions_[name] = std::move(exported);
}

void ServiceRelays::scan_imports() {
  std::map<std::string, Publication> offered;
  for (Publication& publication : participant_->publications()) {
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
  for (auto carried = imported_.begin(); carried != imported_.end();) {
    if (offered.contains(carried->first)) {
      ++carried;
      continue;
    }
    const std::string name = carried->first;
    carried = imported_.erase(carried);  // no server on DDS: local callers get NoServer
    say("no longer importing service '" + name + "' (no server on DDS)");
  }
  for (const auto& [name, publication] : offered) {
    if (imported_.contains(name) || refused_.contains(name)) {
      continue;
    }
    if (policy_.exported(name)) {
      refused_.insert(name);
      complain(both_ways(name));
      continue;
    }
    try {
      import_service(name, publication);
    } catch (const std::exception& error) {
      refused_.insert(name);
      complain("cannot import service '" + name + "': " + error.what());
    }
  }
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
