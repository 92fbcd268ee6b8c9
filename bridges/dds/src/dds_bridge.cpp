// The DDS bridge's discovery and policy (docs/dds-bridge.md): which topics cross, with which QoS,
// and the one-line refusals of what does not.
#include "horus/dds_bridge.hpp"

#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "horus/bridge/identity.hpp"
#include "horus/bridge/topic_policy.hpp"
#include "horus/dds/cdr_plan.hpp"
#include "horus/dds/conversion.hpp"
#include "horus/dds/endpoints.hpp"
#include "horus/dds/frames.hpp"
#include "horus/dds/names.hpp"
#include "horus/dds/pump.hpp"
#include "horus/dds/ros2_twins.hpp"
#include "horus/dds/services.hpp"
#include "horus/dds/user_data.hpp"
#include "horus/dds/xtypes.hpp"
#include "horus/error.hpp"
#include "horus/pool_frames.hpp"
#include "horus/topic_registry.hpp"
#include "horus/type_description.hpp"

namespace horus::dds {
namespace {

using namespace horus::dds_bridge;
using bridge::Claim;
using bridge::TopicIdentity;

constexpr std::chrono::milliseconds kRescan{500};
constexpr std::size_t kLocalCapacity = 64;  // a topic the bridge creates (as `horus topic pub`'s)
constexpr std::size_t kLocalMaxMessage = 16 * 1024;
// A pool topic the bridge creates: as a Topic<Image>'s, each slot a block held.
constexpr std::size_t kPoolCapacity = 4;

// One whole line on stdout or stderr (a single write: it stays whole beside other threads').
void line_to(int fd, const std::string& text) {
  const std::string line = text + "\n";
  [[maybe_unused]] const ssize_t written = ::write(fd, line.data(), line.size());
}
void say(const std::string& text) { line_to(STDOUT_FILENO, text); }
void complain(const std::string& text) { line_to(STDERR_FILENO, "horus bridge: " + text); }

// HORUS_BRIDGE_DROP_REPORT_CAP, else DropReport's.
std::size_t drop_report_cap() {
  const char* given = std::getenv("HORUS_BRIDGE_DROP_REPORT_CAP");  // NOLINT(concurrency-mt-unsafe)
  if (given == nullptr) {
    return DropReport::kCap;
  }
  const std::string text = given;
  const bool digits = !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
  if (!digits || text.size() > 9 || std::stoul(text) < 1) {
    throw Error("HORUS_BRIDGE_DROP_REPORT_CAP wants a whole number, at least 1, not '" + text +
                "'");
  }
  return std::stoul(text);
}

// A type the bridge carries: its description, the root message and its DDS type.
struct CarriedType {
  std::string description_bytes;
  std::shared_ptr<const TypeDescription> description;
  const MessageType* message = nullptr;
  TypeOnWire wire;

  bool pool_backed = false;

  // `keep`: how many frames an importing conversion holds (the local ring's capacity).
  std::unique_ptr<Conversion> conversion(const std::string& namespace_name,
                                         std::size_t keep) const {
    if (pool_backed) {
      return pool_conversion(
          pod_cdr_plan(*description, *message, true),
          make_pool_frames(message->name, message->fingerprint, namespace_name, keep));
    }
    return message->is_pod ? pod_conversion(pod_cdr_plan(*description, *message))
                           : serialized_conversion(description, *message);
  }
};

}  // namespace

class DdsBridge::Running {
 public:
  Running(Network options, std::string namespace_name,
          std::function<void(const std::string&)> on_failure, TypeLookup find_type)
      : options_(std::move(options)),
        namespace_(std::move(namespace_name)),
        on_failure_(std::move(on_failure)),
        policy_(options_.export_, options_.import_, options_.transient_local, options_.deadlines),
        drop_cap_(drop_report_cap()) {
    // Pool-backed topics cross as frames (horus::PoolFrames), which a program that uses no pool
    // itself would otherwise not have registered.
    enable_pool_frames();
    try {
      participant_ = std::make_shared<Participant>(static_cast<std::uint32_t>(options_.domain));
    } catch (const std::runtime_error& error) {
      throw Error(error.what());
    }
    if (!options_.export_services.empty() || !options_.import_services.empty() ||
        !options_.export_actions.empty() || !options_.import_actions.empty()) {
      services_ = std::make_unique<ServiceRelays>(
          options_.export_services, options_.import_services, options_.export_actions,
          options_.import_actions, options_.service_timeout, namespace_, participant_,
          Qos{options_.reliable, options_.depth, false, 0}, std::move(find_type));
    }
    if (!options_.export_frames.empty() || !options_.import_frames.empty()) {
      start_frames();
    }
    thread_ = std::thread([this] { serve(); });
  }

  ~Running() { stop(); }
  Running(const Running&) = delete;
  Running& operator=(const Running&) = delete;

  void stop() {
    {
      const std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    woken_.notify_all();
    if (thread_.joinable()) {
      thread_.join();
    }
  }

 private:
  struct Watch {
    std::function<std::uint32_t()> missed;
    std::chrono::milliseconds deadline;
    std::uint32_t said = 0;
  };

  void serve() {
    std::string broken;
    for (;;) {
      try {
        scan();
      } catch (const std::exception& error) {
        complain(std::string("looking for topics failed: ") + error.what() + "; looking again");
      }
      if (services_) {
        try {
          services_->scan();
        } catch (const std::exception& error) {
          complain(std::string("looking for services failed: ") + error.what() + "; looking again");
        }
      }
      for (const auto& [name, pump] : pumps_) {
        if (std::string why = pump->broken(); !why.empty() && broken.empty()) {
          broken = "topic '" + name + "': " + why;
        }
      }
      if (frames_ && broken.empty()) {
        if (std::string why = frames_->broken(); !why.empty()) broken = "frames: " + why;
      }
      if (!faulted_.empty() && broken.empty()) {
        broken = "topic '" + faulted_ +
                 "': a fault injected by HORUS_BRIDGE_FAULT (a test of the failure path)";
      }
      say_missed_deadlines();
      std::unique_lock lock(mutex_);
      if (!broken.empty() || woken_.wait_for(lock, kRescan, [this] { return stopping_; })) {
        break;
      }
    }
    // Pumps first (they use the endpoints), then the endpoints with the participant: peers see
    // the writers go.
    pumps_.clear();
    watched_.clear();
    services_.reset();
    frames_.reset();
    participant_.reset();
    if (!broken.empty()) {
      complain("stopping: " + broken);
      on_failure_("network: the bridge stopped: " + broken);
    }
  }

  void scan() {
    if (!options_.export_.empty()) {
      scan_exports();
    }
    if (!options_.import_.empty()) {
      scan_imports();
    }
  }

  // -- frames: the tree <-> rt/tf, rt/tf_static -------------------------------------------------

  void start_frames() {
    try {
      frames_ =
          std::make_unique<FrameRelay>(options_.export_frames, options_.import_frames, namespace_,
                                       participant_, !options_.accept_untyped_writers, drop_cap_);
    } catch (const std::runtime_error& error) {
      throw Error(std::string("cannot carry frames: ") + error.what());
    }
    const std::string topics =
        std::string(kTfTopic) + ", " + kTfStaticTopic + " (" + kTfMessageDdsType + ")";
    if (!options_.export_frames.empty()) {
      say("exporting frames " + listed(options_.export_frames) + " as " + topics);
    }
    if (!options_.import_frames.empty()) {
      say("importing frames " + listed(options_.import_frames) + " from " + topics);
    }
  }

  static std::string listed(const std::vector<std::string>& patterns) {
    std::string out;
    for (const std::string& pattern : patterns) out += (out.empty() ? "'" : ", '") + pattern + "'";
    return out;
  }

  // Whether the local topic `name` would cross as a topic rt/tf or rt/tf_static carries frames
  // on (a second type on one DDS topic): refused, said once.
  bool refuse_frame_topic(const std::string& name) {
    if (!frames_ || (name != "tf" && name != "tf_static")) return false;
    if (frame_topics_said_.insert(name).second) {
      complain("cannot export topic '" + name + "': " + dds_topic_name(name) +
               " carries the frames (--export-frames, --import-frames)");
    }
    return true;
  }

  // -- export: local -> DDS ---------------------------------------------------------------------

  void scan_exports() {
    for (const TopicInfo& topic : list_topics(namespace_)) {
      if (!policy_.exported(topic.name) || topic.type_name.empty() || !topic.error.empty() ||
          refuse_frame_topic(topic.name)) {
        continue;
      }
      const Claim claim = policy_.claim(topic.name);
      if (claim == Claim::BothWays) {
        complain(bridge::TopicPolicy::both_ways_refusal(topic.name));
      }
      if (claim != Claim::New) {
        continue;
      }
      try {
        export_topic(topic);
      } catch (const std::exception& error) {
        complain("cannot export topic '" + topic.name + "': " + error.what());
      }
    }
  }

  Qos topic_qos(const std::string& name, const Publication* publication) const {
    Qos qos{options_.reliable, options_.depth, policy_.transient_local(name), 0};
    const std::optional<std::chrono::milliseconds> deadline = policy_.deadline(name);
    qos.deadline_ms = deadline ? deadline->count() : 0;
    if (publication != nullptr) {
      qos.transient_local = qos.transient_local || publication->transient_local;
      if (!deadline) {
        qos.deadline_ms = publication->deadline_ms;
      }
    }
    return qos;
  }

  // The type of a topic from its description's bytes; its DDS type and type information made
  // once per type.
  const CarriedType& carried_type(const TopicIdentity& identity, const std::string& bytes) {
    const std::string key =
        identity.type_name + "/" + bridge::fingerprint_hex(identity.fingerprint);
    if (const auto found = types_.find(key); found != types_.end()) {
      return *found->second;
    }
    if (bytes.empty()) {
      throw std::runtime_error(identity.type_name +
                               " carries no type description (made by a horus-gen before "
                               "descriptions): regenerate it");
    }
    auto type = std::make_unique<CarriedType>();
    type->description_bytes = bytes;
    type->description =
        std::make_shared<const TypeDescription>(TypeDescription::decode(std::string_view(bytes)));
    type->message = &type->description->root_message();
    if (type->message->name != identity.type_name ||
        type->message->fingerprint != identity.fingerprint) {
      throw std::runtime_error("its type description is of " + type->message->name + ", not " +
                               identity.type_name);
    }
    type->pool_backed =
        make_pool_frames(identity.type_name, identity.fingerprint, namespace_, 1) != nullptr;
    type->wire = type_on_wire(*type->description, *type->message);
    return *types_.emplace(key, std::move(type)).first->second;
  }

  LocalTopic local_topic(const std::string& name, const CarriedType& type, std::size_t capacity,
                         std::size_t max_message_size, bool single_publisher) const {
    LocalTopic local;
    local.name = name;
    local.type_name = type.message->name;
    local.fingerprint = type.message->fingerprint;
    local.schema = type.message->schema;
    local.description = type.description_bytes;
    local.is_pod = type.message->is_pod;
    local.size = type.message->size;
    local.alignment = type.message->is_pod ? type.message->alignment : 1;
    local.capacity = capacity;
    local.max_message_size = max_message_size;
    local.single_publisher = single_publisher;
    local.namespace_name = namespace_;
    return local;
  }

  // The ROS 2 twin a topic crosses as: ros2_types names it (and its type has one).
  const Ros2Twin* twin_for(const std::string& name, const std::string& type_name) const {
    if (!bridge::any_matches(name, options_.ros2_types)) {
      return nullptr;
    }
    const Ros2Twin* twin = ros2_twin_of(type_name);
    if (twin == nullptr) {
      std::string those;
      for (const Ros2Twin& each : ros2_twins()) {
        those += (those.empty() ? "" : ", ") + std::string(each.horus);
      }
      throw std::runtime_error("--ros2-types names it, but " + type_name +
                               " has no ROS 2 twin (those with one: " + those + ")");
    }
    return twin;
  }

  // A twin's DDS type with its type information, made once per ROS 2 type.
  const TypeOnWire& twin_wire(const Ros2Twin& twin) {
    const std::string key(twin.ros2);
    if (const auto found = twin_wires_.find(key); found != twin_wires_.end()) {
      return found->second;
    }
    return twin_wires_.emplace(key, ros2_type_on_wire(twin.ros2)).first->second;
  }

  void export_topic(const TopicInfo& topic) {
    const std::string dds_name = dds_topic_name(topic.name);
    const TopicIdentity identity{topic.type_name, topic.fingerprint, topic.schema};
    const Ros2Twin* twin = twin_for(topic.name, topic.type_name);
    const CarriedType& type = carried_type(identity, topic.description);
    const TypeOnWire& wire = twin != nullptr ? twin_wire(*twin) : type.wire;
    const Qos qos = topic_qos(topic.name, nullptr);
    auto writer = std::make_shared<Writer>(
        participant_, dds_name, wire, qos,
        identity_user_data(WriterIdentity{identity, type.description_bytes}));
    const LocalTopic local = local_topic(topic.name, type, topic.capacity, topic.max_message_size,
                                         topic.single_publisher);
    pumps_[topic.name] = std::make_unique<ExportPump>(
        local,
        twin != nullptr ? twin_conversion(*twin) : type.conversion(namespace_, topic.capacity),
        writer->entity(), writer->type(), dds_name, qos.transient_local,
        "horus bridge: topic '" + topic.name + "'", writer);
    watch(topic.name, qos, [writer] { return writer->deadlines_missed(); });
    // The tests' way to make the bridge fail as a bug of its own would (the path a broken pump
    // takes): the topic HORUS_BRIDGE_FAULT names breaks once it is carried.
    const char* fault = std::getenv("HORUS_BRIDGE_FAULT");  // NOLINT(concurrency-mt-unsafe)
    if (fault != nullptr && topic.name == fault) {
      faulted_ = topic.name;
    }
    say("exporting '" + topic.name + "' (" + topic.type_name + ") as " + dds_name + " (" +
        wire.name + ")");
  }

  // -- import: DDS -> local ---------------------------------------------------------------------

  void scan_imports() {
    for (const Publication& publication : participant_->publications()) {
      const std::string& topic = publication.topic;
      if (!topic.starts_with(kTopicPrefix) || refused_.contains(topic) ||
          !policy_.imported(dotted(topic)) ||
          (frames_ && (topic == kTfTopic || topic == kTfStaticTopic))) {
        continue;
      }
      std::string name;
      try {
        name = horus_topic_name(topic);
      } catch (const std::invalid_argument& error) {
        refused_.insert(topic);
        complain("cannot import DDS topic " + topic + ": " + error.what());
        continue;
      }
      if (refuse_representation(name, publication) || refuse_untyped(name, publication) ||
          policy_.decided(name)) {
        continue;
      }
      if (policy_.exported(name)) {
        if (policy_.claim(name) == Claim::BothWays) {
          complain(bridge::TopicPolicy::both_ways_refusal(name));
        }
        continue;
      }
      try {
        if (import_topic(name, publication)) {
          policy_.settle(name);
        }
      } catch (const std::exception& error) {
        policy_.settle(name);
        complain("cannot import topic '" + name + "': " + error.what());
      }
    }
  }

  // Says `line` the first time `writer` is refused or taken on trust; past the cap, says once
  // that further ones are not, and counts them.
  void say_writer_once(const std::string& writer, const std::function<std::string()>& line) {
    if (writers_said_.contains(writer)) {
      return;
    }
    if (writers_said_.size() < drop_cap_) {
      writers_said_.insert(writer);
      complain(line());
      return;
    }
    if (++writers_unsaid_ == 1) {
      complain(std::to_string(writers_said_.size()) +
               " DDS writers refused or taken on trust were said, the most the bridge keeps "
               "(HORUS_BRIDGE_DROP_REPORT_CAP): further ones are not");
    }
  }

  bool refuse_representation(const std::string& name, const Publication& publication) {
    const std::int32_t representation = publication.data_representation;
    if (representation == DDS_DATA_REPRESENTATION_XCDR1) {
      return false;
    }
    const std::string encoding = representation == DDS_DATA_REPRESENTATION_XCDR2 ? "XCDR2"
                                 : representation == DDS_DATA_REPRESENTATION_XML
                                     ? "XML"
                                     : "data representation " + std::to_string(representation);
    say_writer_once(publication.writer, [&] {
      return "cannot import topic '" + name + "' from DDS writer " + publication.writer +
             ": it writes " + encoding + ", the bridge reads XCDR1 only (DDS does not match them)";
    });
    return true;
  }

  bool refuse_untyped(const std::string& name, const Publication& publication) {
    if (publication.typed) {
      return false;
    }
    const std::string& writer = publication.writer;
    if (options_.accept_untyped_writers) {
      say_writer_once(writer, [&] {
        return "topic '" + name + "': DDS writer " + writer +
               " announces no type information: taking its " + publication.type +
               " on trust (--accept-untyped-writers)";
      });
      return false;
    }
    say_writer_once(writer, [&] {
      return "cannot import topic '" + name + "' from DDS writer " + writer +
             ": it announces no type information, so DDS cannot check that its " +
             publication.type +
             " is the type's layout (--accept-untyped-writers takes such writers on trust)";
    });
    return true;
  }

  // Whether the import started; false when the type is not known yet (a plain DDS writer, and
  // no local topic of that name).
  bool import_topic(const std::string& name, const Publication& publication) {
    const std::optional<WriterIdentity> remote = parse_identity_user_data(publication.user_data);
    // A ROS 2 node's writer: the first twin of its type, when ros2_types names the topic.
    const Ros2Twin* first_twin = nullptr;
    if (bridge::any_matches(name, options_.ros2_types)) {
      for (const Ros2Twin& twin : ros2_twins()) {
        if (twin.dds_type() == publication.type) {
          first_twin = &twin;
          break;
        }
      }
    }
    std::optional<TopicInfo> local;
    for (TopicInfo& topic : list_topics(namespace_)) {
      if (topic.name == name && !topic.type_name.empty()) {
        local = std::move(topic);
        break;
      }
    }
    TopicIdentity identity;
    std::string description;
    std::size_t capacity = 0;  // the bridge creates the topic: kLocalCapacity, kPoolCapacity
    std::size_t max_message = kLocalMaxMessage;
    if (local) {
      identity = TopicIdentity{local->type_name, local->fingerprint, local->schema};
      if (remote) {
        if (const auto mismatch =
                bridge::identity_mismatch(identity, remote->topic, "DDS", publication.type)) {
          throw std::runtime_error(*mismatch);
        }
      }
      description = local->description;
      capacity = local->capacity;
      max_message = local->max_message_size;
    } else if (remote) {
      identity = remote->topic;
      description = remote->description;
    } else if (first_twin != nullptr) {
      const TypeIdentity standard = twin_type_identity(*first_twin);
      identity = TopicIdentity{standard.name, standard.fingerprint, standard.schema};
      description = standard.description;
    } else {
      return false;
    }
    const Ros2Twin* twin = twin_for(name, identity.type_name);
    const CarriedType& type = carried_type(identity, description);
    if (capacity == 0) {
      capacity = type.pool_backed ? kPoolCapacity : kLocalCapacity;
    }
    const TypeOnWire& wire = twin != nullptr ? twin_wire(*twin) : type.wire;
    if (wire.name != publication.type) {
      const Ros2Twin* own_twin = ros2_twin_of(identity.type_name);
      const std::string hint = own_twin != nullptr && own_twin->dds_type() == publication.type
                                   ? " (its ROS 2 twin: --ros2-types '" + name + "' carries it)"
                                   : "";
      throw std::runtime_error("the local topic has type " + identity.type_name + " (" + wire.name +
                               " on DDS), DDS carries " + publication.type + hint);
    }
    const Qos qos = topic_qos(name, &publication);
    auto reader = std::make_shared<Reader>(participant_, publication.topic, wire, qos,
                                           !options_.accept_untyped_writers);
    pumps_[name] = std::make_unique<ImportPump>(
        local_topic(name, type, capacity, max_message, false),
        twin != nullptr ? twin_conversion(*twin) : type.conversion(namespace_, capacity),
        reader->entity(), publication.topic, "horus bridge: topic '" + name + "'", reader,
        drop_cap_);
    watch(name, qos, [reader] { return reader->deadlines_missed(); });
    say("importing " + publication.topic + " (" + publication.type + ") as '" + name + "' (" +
        identity.type_name + ")");
    return true;
  }

  // -- deadlines ---------------------------------------------------------------------------------

  void watch(const std::string& name, const Qos& qos, std::function<std::uint32_t()> missed) {
    if (qos.deadline_ms > 0) {
      watched_[name] = Watch{std::move(missed), std::chrono::milliseconds(qos.deadline_ms)};
    }
  }

  void say_missed_deadlines() {
    for (auto& [name, watch] : watched_) {
      const std::uint32_t missed = watch.missed();
      if (missed > watch.said) {
        watch.said = missed;
        complain("topic '" + name + "': no message within its " +
                 std::to_string(watch.deadline.count()) + " ms deadline (missed " +
                 std::to_string(missed) + " times so far)");
      }
    }
  }

  Network options_;
  std::string namespace_;
  std::function<void(const std::string&)> on_failure_;
  std::map<std::string, TypeOnWire> twin_wires_;  // by ROS 2 type, made once each
  bridge::TopicPolicy policy_;
  std::size_t drop_cap_;
  std::shared_ptr<Participant> participant_;
  std::unique_ptr<ServiceRelays> services_;
  std::unique_ptr<FrameRelay> frames_;
  std::set<std::string> frame_topics_said_;  // local topics tf, tf_static refused (said once)
  std::map<std::string, std::unique_ptr<CarriedType>> types_;
  std::map<std::string, std::unique_ptr<bridge::Forwarder>> pumps_;
  std::map<std::string, Watch> watched_;
  std::set<std::string> refused_;  // DDS topic names refused (each said once)
  std::set<std::string> writers_said_;
  std::size_t writers_unsaid_ = 0;
  std::string faulted_;  // the topic HORUS_BRIDGE_FAULT broke
  std::mutex mutex_;
  std::condition_variable woken_;
  bool stopping_ = false;
  std::thread thread_;
};

DdsBridge::DdsBridge(Network options, std::string namespace_name,
                     std::function<void(const std::string&)> on_failure, TypeLookup find_type)
    : running_(std::make_unique<Running>(std::move(options), std::move(namespace_name),
                                         std::move(on_failure), std::move(find_type))) {}

DdsBridge::~DdsBridge() { stop(); }

void DdsBridge::stop() { running_->stop(); }

}  // namespace horus::dds
