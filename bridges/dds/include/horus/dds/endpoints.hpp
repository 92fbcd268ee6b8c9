// The little of Cyclone DDS the bridge needs, over raw CDR bytes (raw_cdr.hpp): a participant on
// a domain and the publications it discovers; writers and readers of (DDS topic name, DDS type
// name) whose samples are CDR the caller encodes and decodes. Every endpoint ignores those of its
// own participant, so a bridge never reads back what it wrote, and accepts XCDR1 alone.
// Failures to create or use an entity throw std::runtime_error naming it and DDS's reason.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "dds/dds.h"

namespace horus::dds_bridge {

/// The QoS of a bridge's writer or reader.
struct Qos {
  bool reliable = true;
  std::int32_t depth = 100;
  bool transient_local = false;
  std::int64_t deadline_ms = 0;  // 0: none
};

/// A DDS type: its name, and its serialized XTypes TypeInformation and TypeMapping (both empty:
/// none, and DDS matches by the name alone).
struct TypeOnWire {
  std::string name;
  std::string info;
  std::string map;
};

/// A writer another participant has on the domain, as discovery tells of it.
struct Publication {
  std::string topic;
  std::string type;
  bool typed = false;       // whether it announces XTypes type information
  std::string participant;  // GUIDs, hex
  std::string writer;
  std::string user_data;
  bool transient_local = false;
  std::int64_t deadline_ms = 0;                                      // 0: none
  std::int32_t data_representation = DDS_DATA_REPRESENTATION_XCDR1;  // the one it writes
};

/// One participant and the raw-CDR topics it has made (one per DDS topic name).
class Participant {
 public:
  explicit Participant(std::uint32_t domain);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  dds_entity_t handle() const noexcept { return handle_; }
  std::string guid() const;
  /// The DDS topic `name` of type `wire`, made on first use; the same name with another type
  /// throws.
  dds_entity_t topic(const std::string& name, const TypeOnWire& wire);
  const ddsi_sertype* sertype(const std::string& name) const { return topics_.at(name).type; }
  /// The publications DDS knows of now, this participant's own left out.
  std::vector<Publication> publications() const;

 private:
  struct Topic {
    dds_entity_t entity;
    const ddsi_sertype* type;  // the topic holds the reference
    std::string type_name;
    std::string type_info;
  };
  dds_entity_t handle_;
  dds_entity_t publications_;
  std::map<std::string, Topic> topics_;
};

/// A writer or reader; deleted with the object, which keeps its participant alive.
class Endpoint {
 public:
  Endpoint(std::shared_ptr<Participant> participant, dds_entity_t entity, std::string topic)
      : participant_(std::move(participant)), entity_(entity), topic_(std::move(topic)) {}
  ~Endpoint() { dds_delete(entity_); }
  Endpoint(const Endpoint&) = delete;
  Endpoint& operator=(const Endpoint&) = delete;

  dds_entity_t entity() const noexcept { return entity_; }
  const std::string& topic() const noexcept { return topic_; }

 protected:
  std::shared_ptr<Participant> participant_;
  dds_entity_t entity_;
  std::string topic_;
};

class Writer : public Endpoint {
 public:
  /// `user_data`: the writer's DDS user data (the bridge's: the HORUS identity).
  Writer(const std::shared_ptr<Participant>& participant, const std::string& topic,
         const TypeOnWire& type, const Qos& qos, const std::string& user_data);

  const ddsi_sertype* type() const noexcept { return type_; }
  /// Writes one sample: its CDR, 4-byte encapsulation header included. A reliable writer blocks
  /// while its history is full of unacknowledged samples.
  void write(std::span<const std::byte> cdr);
  /// How many readers match it now.
  std::uint32_t matched() const;
  /// How many times it wrote nothing within its deadline.
  std::uint32_t deadlines_missed() const;

 private:
  const ddsi_sertype* type_;
};

class Reader : public Endpoint {
 public:
  /// `typed_writers_only`: DDS matches only writers that announce type information and whose type
  /// is assignable to this one (else writers of the same type name, whatever their layout).
  Reader(const std::shared_ptr<Participant>& participant, const std::string& topic,
         const TypeOnWire& type, const Qos& qos, bool typed_writers_only);
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  /// The samples that arrived, oldest first, waiting up to `timeout` for the first: each its
  /// writer's instance handle (not its GUID: finding one allocates and locks in DDS, and only a
  /// sample dropped needs one: WriterGuids) and its bytes.
  std::vector<std::pair<dds_instance_handle_t, std::string>> take(std::chrono::nanoseconds timeout);
  /// How many writers match it now.
  std::uint32_t matched() const;
  /// How many times nothing arrived within its deadline.
  std::uint32_t deadlines_missed() const;

 private:
  dds_entity_t waitset_ = 0;
};

}  // namespace horus::dds_bridge
