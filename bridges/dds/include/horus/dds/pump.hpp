// The per-message path of a topic through the bridge: one C++ thread per carried topic (a
// bridge::Forwarder, bridges/core/). An export pump waits on the local HORUS topic through a
// bridge::FrameSource (a pool-backed type's frames recorded with their block's data), turns each
// frame into CDR with the type's Conversion and writes it with dds_writecdr. An import pump
// takes the samples with dds_takecdr, turns each back into a message and publishes it, from the
// reader's data-available listener (in Cyclone's receive thread: no thread of its own to wake
// per message); its thread takes what a failed take left behind.
// Failures follow docs/dds-bridge.md "When something fails": one line on stderr per failure with
// the topic's running count, a failed DDS write or take retried after kRetry (the same message:
// nothing is reordered), a message that cannot be decoded or delivered dropped. A DDS writer can
// send bad samples as fast as the network carries them, so those are said once per writer and
// reason and otherwise counted (DropReport). The thread never dies of a failure; anything else it
// meets (a bug) ends it and shows in broken().
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "dds/dds.h"
#include "horus/bridge/forwarder.hpp"
#include "horus/bridge/frame_source.hpp"
#include "horus/dds/conversion.hpp"
#include "horus/raw_topic.hpp"

namespace horus::dds_bridge {

/// What a pump opens its own handle of the local topic with (horus._core.Topic's arguments).
struct LocalTopic {
  std::string name;
  std::string type_name;
  std::uint64_t fingerprint = 0;
  std::string schema;
  std::string description;  // the type description's bytes (empty: none)
  bool is_pod = true;
  std::size_t size = 0;  // a POD type's
  std::size_t alignment = 1;
  std::size_t capacity = 64;
  std::size_t max_message_size = 0;
  bool single_publisher = false;
  std::string namespace_name;  // empty: HORUS_NAMESPACE
};

/// Local topic -> DDS writer.
class ExportPump final : public bridge::Forwarder {
 public:
  /// `latched`: first sends the topic's newest message, if it has one and nothing newer came.
  ExportPump(const LocalTopic& local, std::unique_ptr<Conversion> conversion, dds_entity_t writer,
             const ddsi_sertype* type, std::string dds_topic, bool latched, std::string label,
             std::shared_ptr<void> keep_alive);
  ~ExportPump() override { stop(); }

 private:
  void loop();
  /// Writes a frame the source gave, retrying a failed write.
  void send_to_dds(std::span<const std::byte> frame);
  /// A failure line for each pool frame the source skipped since the last call (its block was
  /// freed or reused before the pump read it).
  void say_stale_frames();

  bridge::FrameSource local_;
  std::uint64_t stale_said_ = 0;
  std::unique_ptr<Conversion> conversion_;
  dds_entity_t writer_;
  const ddsi_sertype* type_;
  std::string dds_topic_;
  bool latched_;
  std::vector<std::byte> sample_;
};

/// Samples of one imported topic dropped for what a writer sent: the first of each (writer,
/// reason) is a line naming both, the rest are counted and the count is a line at most every
/// kEvery. A reason is its text with numbers left out, so a writer whose every sample is a
/// different size still has one reason. A participant can make writers without end, so at most
/// `cap` (writer, reason) pairs are kept: past them, one line says so and the samples of any other
/// writer and reason are counted as other writers'. The Python threads use it too
/// (horus._core.dds).
class DropReport {
 public:
  static constexpr std::chrono::seconds kEvery{5};
  static constexpr std::size_t kCap = 1024;

  explicit DropReport(std::size_t cap = kCap) : cap_(cap) {}

  /// The line to say of one more sample dropped, or empty when it is only counted; `writer`: its
  /// GUID, or null for one of the writers past the cap (WriterGuids); `failure`: the topic's
  /// running count of failures, this one included.
  std::string dropped(const std::string* writer, const std::string& reason, std::uint64_t failure,
                      std::chrono::steady_clock::time_point now);
  /// The line counting the samples dropped unsaid, when there are some and kEvery has passed
  /// since the last line; else empty.
  std::string due(std::uint64_t failures, std::chrono::steady_clock::time_point now);
  /// How many (writer, reason) pairs it keeps: `cap` at most.
  std::size_t kept() const noexcept { return said_.size(); }

 private:
  std::size_t cap_;
  std::set<std::pair<std::string, std::string>> said_;
  bool full_said_ = false;    // the line saying the cap is reached went
  std::uint64_t unsaid_ = 0;  // of pairs said before
  std::uint64_t others_ = 0;  // of other writers and reasons, past the cap
  std::chrono::steady_clock::time_point last_line_{};
};

/// The GUIDs of the writers of dropped samples, by the instance handle a sample names its writer
/// with: DDS allocates and locks to find a GUID, so it is looked up on a writer's first drop only,
/// never for a sample delivered. At most `cap` are kept (a participant can make writers without
/// end); with the same cap as the DropReport's, a writer past it would only be counted there.
class WriterGuids {
 public:
  explicit WriterGuids(std::size_t cap = DropReport::kCap) : cap_(cap) {}

  /// The GUID of `writer`, matched by `reader`, or null when `cap` others are kept already.
  const std::string* find(dds_entity_t reader, dds_instance_handle_t writer);
  std::size_t kept() const noexcept { return guids_.size(); }

 private:
  std::size_t cap_;
  std::map<dds_instance_handle_t, std::string> guids_;
};

/// DDS reader -> local topic.
class ImportPump final : public bridge::Forwarder {
 public:
  /// `drop_cap`: the cap of its DropReport and WriterGuids.
  ImportPump(const LocalTopic& local, std::unique_ptr<Conversion> conversion, dds_entity_t reader,
             std::string dds_topic, std::string label, std::shared_ptr<void> keep_alive,
             std::size_t drop_cap = DropReport::kCap);
  ~ImportPump() override;

 private:
  void loop();
  /// Takes and delivers every sample the reader holds: false when the take failed (said).
  bool drain();
  void deliver(std::span<const std::byte> sample, dds_instance_handle_t writer);
  void drop(dds_instance_handle_t writer, const std::string& reason);

  RawTopic local_;
  std::unique_ptr<Conversion> conversion_;
  dds_entity_t reader_;
  std::string dds_topic_;
  std::vector<std::byte> message_;
  DropReport drops_;
  WriterGuids writers_;
  std::mutex draining_;  // the listener and the thread: one take and delivery at a time, in order
};

}  // namespace horus::dds_bridge
