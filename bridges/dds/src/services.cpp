#include "horus/dds/services.hpp"

#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <thread>
#include <utility>

#include "horus/bridge/identity.hpp"
#include "horus/bridge/service_relay.hpp"
#include "horus/dds/cdr_plan.hpp"
#include "horus/dds/conversion.hpp"
#include "horus/dds/user_data.hpp"
#include "horus/dds/xtypes.hpp"
#include "horus/raw_service.hpp"
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

// -- the relays ---------------------------------------------------------------------------------

ServiceRelays::ServiceRelays(std::vector<std::string> exports, std::vector<std::string> imports,
                             std::chrono::duration<double> call_timeout, std::string namespace_name,
                             std::shared_ptr<Participant> participant, Qos qos, TypeLookup lookup)
    : policy_(std::move(exports), std::move(imports)),
      call_timeout_(call_timeout),
      namespace_(std::move(namespace_name)),
      participant_(std::move(participant)),
      qos_(qos),
      lookup_(std::move(lookup)) {}

ServiceRelays::~ServiceRelays() {
  exported_.clear();
  imported_.clear();
}

void ServiceRelays::scan() {
  scan_exports();
  scan_imports();
}

void ServiceRelays::scan_exports() {
  for (const ServiceInfo& entry : list_services(namespace_)) {
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
void ServiceRelays::export_service(const std::string& name, const std::string& request_type,
                                   const std::string& response_type, std::uint64_t fingerprint) {
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
    return;
  }
  auto exported =
      std::make_unique<Exported>(name, fingerprint, std::move(*request), std::move(*response),
                                 participant_, qos_, call_timeout_, namespace_);
  say(exported->said());
  exported_[name] = std::move(exported);
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
