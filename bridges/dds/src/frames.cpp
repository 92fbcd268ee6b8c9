#include "horus/dds/frames.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "horus/bridge/topic_policy.hpp"
#include "horus/dds/pump.hpp"
#include "horus/dds/raw_cdr.hpp"
#include "horus/dds/ros2_twins.hpp"
#include "horus/dds/xtypes.hpp"
#include "horus/frames.hpp"
#include "horus/transform_feed.hpp"

namespace horus::dds_bridge {

// The child frames the import set: the export leaves them out. Both threads use it.
class ImportedFrames {
 public:
  bool contains(std::string_view child) const {
    const std::lock_guard lock(mutex_);
    return children_.contains(child);
  }
  // Whether it was new.
  bool insert(const std::string& child) {
    const std::lock_guard lock(mutex_);
    return children_.insert(child).second;
  }
  void erase(const std::string& child) {
    const std::lock_guard lock(mutex_);
    children_.erase(child);
  }

 private:
  mutable std::mutex mutex_;
  std::set<std::string, std::less<>> children_;
};

namespace {

// tf2_ros's QoS (tf2_ros/qos.hpp): DynamicBroadcasterQoS and DynamicListenerQoS are keep-last
// 100; StaticBroadcasterQoS keeps 1 (each sample holds the whole static set), StaticListenerQoS
// 100 (rt/tf_static has no key: every writer's set shares one instance).
constexpr Qos kDynamicQos{true, 100, false, 0};
constexpr Qos kStaticWriterQos{true, 1, true, 0};
constexpr Qos kStaticReaderQos{true, 100, true, 0};
// How long the export waits, when the bridge imports frames too, before its first batch: at least
// kSettle (discovery of the domain's rt/tf_static writers), until the import's reader matches
// every one discovered (their transient-local replay then comes in), at most kSettleAtMost (a
// writer it will never match).
constexpr std::chrono::milliseconds kSettle{1000};
constexpr std::chrono::milliseconds kSettleAtMost{5000};
// How long a frame found to be another authority's stays refused before the tree is read again
// (its authority may end; reading authorities reads /proc).
constexpr std::chrono::seconds kRecheckAuthority{1};

const TypeOnWire& tf_wire() {
  static const TypeOnWire wire = ros2_type_on_wire(kTfMessageType);
  return wire;
}

class FrameExport final : public bridge::Forwarder {
 public:
  FrameExport(std::vector<std::string> patterns, std::string namespace_name,
              const std::shared_ptr<Participant>& participant,
              std::shared_ptr<const ImportedFrames> imported, std::function<bool()> settled)
      : Forwarder("horus bridge: frames to DDS", {}),
        patterns_(std::move(patterns)),
        namespace_(std::move(namespace_name)),
        imported_(std::move(imported)),
        settled_(std::move(settled)),
        dynamic_(participant, kTfTopic, tf_wire(), kDynamicQos, ""),
        static_(participant, kTfStaticTopic, tf_wire(), kStaticWriterQos, "") {
    start([this] { loop(); });
  }
  ~FrameExport() override { stop(); }
  FrameExport(const FrameExport&) = delete;
  FrameExport& operator=(const FrameExport&) = delete;

 private:
  void loop() {
    if (settled_) {
      const auto start = std::chrono::steady_clock::now();
      for (auto waited = std::chrono::steady_clock::duration(0);
           !stopping() && waited < kSettleAtMost && (waited < kSettle || !settled_());
           waited = std::chrono::steady_clock::now() - start) {
        pause(kPoll);
      }
      pause(kPoll);  // the replay of the writers matched last, taken by the import's listener
    }
    std::optional<FrameTree> tree;
    while (!stopping() && !tree) {
      if (!frame_tree_exists(namespace_)) {
        pause(kPoll);
        continue;
      }
      try {
        tree.emplace(FrameTreeOptions{.namespace_name = namespace_});
      } catch (const FrameError& error) {
        failed(std::string("cannot open the frame tree: ") + error.what(), "trying again");
        pause();
      }
    }
    if (!tree) return;
    // A dead bridge's imports are not sent out as this machine's frames.
    TransformFeed feed(*tree,
                       [this](std::string_view child) {
                         return bridge::any_matches(child, patterns_) &&
                                !imported_->contains(child);
                       },
                       {.skip_dead_authorities = true});
    std::uint64_t lost_said = 0;
    while (!stopping()) {
      const TransformBatch batch = feed.next(kPoll);
      if (feed.lost() > lost_said) {
        failed(std::to_string(feed.lost() - lost_said) +
                   " frame entries were overwritten in the tree before the bridge read them",
               "sending the rest");
        lost_said = feed.lost();
      }
      if (batch.statics) send(static_, *batch.statics);
      if (!batch.dynamic.empty()) send(dynamic_, batch.dynamic);
    }
  }

  // One TFMessage of `transforms`, a failed write retried.
  void send(Writer& writer, std::span<const StampedTransform> transforms) {
    tf_message_to_cdr(transforms, sample_);
    while (!stopping()) {
      try {
        writer.write(sample_);
        count_carried();
        return;
      } catch (const std::runtime_error& error) {
        failed(error.what(), "writing the same message again");
        pause();
      }
    }
  }

  std::vector<std::string> patterns_;
  std::string namespace_;
  std::shared_ptr<const ImportedFrames> imported_;
  std::function<bool()> settled_;  // whether the import took rt/tf_static's replay; none: no import
  Writer dynamic_;
  Writer static_;
  std::vector<std::byte> sample_;
};

class FrameImport final : public bridge::Forwarder {
 public:
  FrameImport(std::vector<std::string> patterns, std::string namespace_name,
              const std::shared_ptr<Participant>& participant,
              std::shared_ptr<ImportedFrames> imported, bool typed_writers_only,
              std::size_t drop_cap)
      : Forwarder("horus bridge: frames from DDS", {}),
        patterns_(std::move(patterns)),
        namespace_(std::move(namespace_name)),
        imported_(std::move(imported)),
        participant_(participant),
        dynamic_(participant, kTfTopic, tf_wire(), kDynamicQos, typed_writers_only),
        static_(participant, kTfStaticTopic, tf_wire(), kStaticReaderQos, typed_writers_only),
        drops_(drop_cap),
        writers_(drop_cap) {
    start([this] { loop(); });
    const std::array readers{dynamic_.entity(), static_.entity()};
    for (const dds_entity_t reader : readers) {
      dds_listener_t* listener = dds_create_listener(this);
      dds_lset_data_available(listener, &FrameImport::data_available);
      const dds_return_t code = dds_set_listener(reader, listener);  // copies it
      dds_delete_listener(listener);
      if (code < 0) {
        unlisten();
        stop();  // before the members the thread uses are unwound
        throw std::runtime_error(std::string("cannot listen on DDS topics rt/tf, rt/tf_static: ") +
                                 dds_strretcode(code));
      }
    }
  }
  ~FrameImport() override {
    unlisten();
    stop();
  }
  FrameImport(const FrameImport&) = delete;
  FrameImport& operator=(const FrameImport&) = delete;

  /// Whether its rt/tf_static reader matches every writer of it the participant discovered.
  bool caught_up() const {
    std::size_t writers = 0;
    for (const Publication& publication : participant_->publications()) {
      if (publication.topic == kTfStaticTopic) ++writers;
    }
    return static_.matched() >= writers;
  }

 private:
  // The readers' listener, in Cyclone's receive thread.
  static void data_available(dds_entity_t reader, void* arg) {
    auto* import = static_cast<FrameImport*>(arg);
    if (!import->stopping()) {
      import->guarded([import, reader] { import->drain(reader);
    });
  }
}

  void unlisten() {
  // Each returns once no call of the listener runs.
  dds_set_listener(dynamic_.entity(), nullptr);
  dds_set_listener(static_.entity(), nullptr);
}

void loop() {
  // Samples that arrived before the listeners were set, or that a failed take left.
  while (!stopping()) {
    const bool taken = drain(static_.entity()) && drain(dynamic_.entity());
    pause(taken ? kPoll : kRetry);
  }
  const std::lock_guard lock(draining_);
  say(drops_.due(failures(), std::chrono::steady_clock::time_point::max()));
}

bool drain(dds_entity_t reader) {
  const std::lock_guard lock(draining_);
  const bool is_static = reader == static_.entity();
  const auto deliver_each = [this, reader, is_static](std::span<const std::byte> sample,
                                                      dds_instance_handle_t writer) {
    deliver(sample, reader, writer, is_static);
  };
  const dds_return_t code = take_raw_cdr(reader, deliver_each);
  say(drops_.due(failures(), std::chrono::steady_clock::now()));
  if (code < 0) {
    failed(std::string("cannot take from DDS topic '") + (is_static ? kTfStaticTopic : kTfTopic) +
               "': " + dds_strretcode(code),
           "retrying");
    return false;
  }
  return true;
}

void deliver(std::span<const std::byte> sample, dds_entity_t reader, dds_instance_handle_t writer,
             bool is_static) {
  if (std::string why = tf_message_from_cdr(sample, transforms_); !why.empty()) {
    drop(reader, writer, "does not decode: " + why);
    return;
  }
  if (!tree_) {
    try {
      tree_.emplace(FrameTreeOptions{.namespace_name = namespace_});
    } catch (const FrameError& error) {
      failed(std::string("cannot open the frame tree: ") + error.what(), "dropped the sample");
      return;
    }
  }
  for (const StampedTransform& transform : transforms_) {
    if (!bridge::any_matches(transform.child, patterns_)) continue;
    if (std::string owner = authority_elsewhere(transform.child); !owner.empty()) {
      drop(reader, writer,
           "sets frame '" + transform.child + "', whose authority here is " + owner +
               ": not imported");
      continue;
    }
    // Marked before it is written, so that the export never sees it as its own.
    const bool marked = imported_->insert(transform.child);
    try {
      if (is_static) {
        tree_->set_static_transform(transform.parent, transform.child, transform.transform);
      } else {
        tree_->set_transform(transform.parent, transform.child, transform.transform,
                             transform.stamp);
      }
      count_carried();
    } catch (const FrameError& error) {
      if (marked) imported_->erase(transform.child);
      drop(reader, writer,
           "sets frame '" + transform.child + "', which the frame tree refused (" + error.what() +
               ")");
    }
  }
}

// "pid P (program)" when another live process, or this one, is the authority of `child` and
// the bridge did not import it; else empty. Read from the tree (and /proc) only for a child
// not imported yet, and at most every kRecheckAuthority for one refused.
std::string authority_elsewhere(const std::string& child) {
  if (imported_->contains(child)) return {};
  const auto now = std::chrono::steady_clock::now();
  if (const auto refused = refused_.find(child);
      refused != refused_.end() && now - refused->second.first < kRecheckAuthority) {
    return refused->second.second;
  }
  refused_.erase(child);
  for (const FrameInfo& info : tree_->frames(true)) {
    if (info.name != child || info.parent.empty() || info.authority_pid == 0 ||
        !info.authority_alive) {
      continue;
    }
    std::string owner = "pid " + std::to_string(info.authority_pid) +
                        (info.authority_program.empty() ? "" : " (" + info.authority_program + ")");
    refused_.emplace(child, std::pair{now, owner});
    return owner;
  }
  return {};
}

void drop(dds_entity_t reader, dds_instance_handle_t writer, const std::string& reason) {
  say(drops_.dropped(writers_.find(reader, writer), reason, count_failure(),
                     std::chrono::steady_clock::now()));
}

std::vector<std::string> patterns_;
std::string namespace_;
std::shared_ptr<ImportedFrames> imported_;
std::shared_ptr<Participant> participant_;
Reader dynamic_;
Reader static_;
std::optional<FrameTree> tree_;
std::vector<StampedTransform> transforms_;
// Children refused for another authority: when, and the authority said.
std::map<std::string, std::pair<std::chrono::steady_clock::time_point, std::string>> refused_;
DropReport drops_;
WriterGuids writers_;
std::mutex draining_;  // the listeners and the thread: one take and delivery at a time
};                     // namespace

}  // namespace horus::dds_bridge

FrameRelay::FrameRelay(const std::vector<std::string>& exports,
                       const std::vector<std::string>& imports, const std::string& namespace_name,
                       const std::shared_ptr<Participant>& participant, bool typed_writers_only,
                       std::size_t drop_cap)
    : imported_(std::make_shared<ImportedFrames>()) {
  std::function<bool()> settled;
  if (!imports.empty()) {
    auto import = std::make_unique<FrameImport>(imports, namespace_name, participant, imported_,
                                                typed_writers_only, drop_cap);
    // The export ends before the import (~FrameRelay).
    settled = [import = import.get()] { return import->caught_up(); };
    import_ = std::move(import);
  }
  if (!exports.empty()) {
    export_ = std::make_unique<FrameExport>(exports, namespace_name, participant, imported_,
                                            std::move(settled));
  }
}

FrameRelay::~FrameRelay() {
  export_.reset();
  import_.reset();
}

std::string FrameRelay::broken() const {
  for (const auto* direction : {import_.get(), export_.get()}) {
    if (direction == nullptr) continue;
    if (std::string why = direction->broken(); !why.empty()) return why;
  }
  return {};
}

}  // namespace horus::dds_bridge
