#include "horus/dds/endpoints.hpp"

#include <stdexcept>

#include "horus/dds/raw_cdr.hpp"

namespace horus::dds_bridge {
namespace {

[[noreturn]] void fail(const std::string& what, dds_return_t code) {
  throw std::runtime_error(what + ": " + dds_strretcode(code));
}

dds_entity_t checked(dds_entity_t entity, const std::string& what) {
  if (entity < 0) {
    fail(what, entity);
  }
  return entity;
}

dds_qos_t* make_qos(const Qos& qos, const std::string& user_data, bool typed_writers_only) {
  dds_qos_t* out = dds_create_qos();
  if (qos.reliable) {
    dds_qset_reliability(out, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  } else {
    dds_qset_reliability(out, DDS_RELIABILITY_BEST_EFFORT, 0);
  }
  dds_qset_history(out, DDS_HISTORY_KEEP_LAST, qos.depth);
  dds_qset_durability(
      out, qos.transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
  if (qos.transient_local) {
    // Latched: a reader that joins later gets the last sample (the writer keeps one for it).
    dds_qset_durability_service(out, 0, DDS_HISTORY_KEEP_LAST, 1, DDS_LENGTH_UNLIMITED,
                                DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  }
  if (qos.deadline_ms > 0) {
    dds_qset_deadline(out, DDS_MSECS(qos.deadline_ms));
  }
  dds_qset_ignorelocal(out, DDS_IGNORELOCAL_PARTICIPANT);
  // The bridge's CDR is XCDR1 only: DDS then refuses to match a writer or reader that insists on
  // XCDR2, instead of matching it and handing over samples the bridge misreads.
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(out, 1, &xcdr1);
  if (!user_data.empty()) {
    dds_qset_userdata(out, user_data.data(), user_data.size());
  }
  if (typed_writers_only) {
    // Match a writer only when it announces its type and that type is assignable to the reader's:
    // without force_type_validation DDS falls back to comparing type names when either side
    // announces none, and a same-named type of another layout would match. Bounds and member
    // names are checked too; the CDR decoders would refuse what does not fit anyway.
    dds_qset_type_consistency(out, DDS_TYPE_CONSISTENCY_ALLOW_TYPE_COERCION, false, false, false,
                              true, true);
  }
  return out;
}

dds_entity_t create_writer(Participant& participant, const std::string& topic,
                           const TypeOnWire& type, const Qos& qos, const std::string& user_data) {
  const dds_entity_t entity = participant.topic(topic, type);
  dds_qos_t* settings = make_qos(qos, user_data, false);
  const dds_entity_t writer = dds_create_writer(participant.handle(), entity, settings, nullptr);
  dds_delete_qos(settings);
  return checked(writer, "cannot create a DDS writer on '" + topic + "'");
}

dds_entity_t create_reader(Participant& participant, const std::string& topic,
                           const TypeOnWire& type, const Qos& qos, bool typed_writers_only) {
  const dds_entity_t entity = participant.topic(topic, type);
  dds_qos_t* settings = make_qos(qos, "", typed_writers_only);
  const dds_entity_t reader = dds_create_reader(participant.handle(), entity, settings, nullptr);
  dds_delete_qos(settings);
  return checked(reader, "cannot create a DDS reader on '" + topic + "'");
}

}  // namespace

Participant::Participant(std::uint32_t domain)
    : handle_(checked(dds_create_participant(domain, nullptr, nullptr),
                      "cannot create a DDS participant on domain " + std::to_string(domain))) {
  publications_ =
      checked(dds_create_reader(handle_, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr),
              "cannot read DDS's publications");
}

Participant::~Participant() { dds_delete(handle_); }

std::string Participant::guid() const {
  dds_guid_t guid{};
  const dds_return_t code = dds_get_guid(handle_, &guid);
  if (code < 0) {
    fail("cannot read the participant's GUID", code);
  }
  return guid_hex(guid);
}

dds_entity_t Participant::topic(const std::string& name, const TypeOnWire& wire) {
  const auto found = topics_.find(name);
  if (found != topics_.end()) {
    if (found->second.type_name != wire.name || found->second.type_info != wire.info) {
      throw std::runtime_error("DDS topic '" + name + "' is already open with type " +
                               found->second.type_name + ", not " + wire.name +
                               " (or other type information)");
    }
    return found->second.entity;
  }
  ddsi_sertype* type = raw_cdr_sertype(wire.name, wire.info, wire.map);
  const dds_entity_t entity =
      dds_create_topic_sertype(handle_, name.c_str(), &type, nullptr, nullptr, nullptr);
  if (entity < 0) {
    ddsi_sertype_unref(type);
    fail("cannot create DDS topic '" + name + "' of type " + wire.name, entity);
  }
  topics_.emplace(name, Topic{entity, type, wire.name, wire.info});
  return entity;
}

std::vector<Publication> Participant::publications() const {
  const std::string own = guid();
  std::vector<Publication> out;
  void* samples[256] = {};
  dds_sample_info_t infos[256];
  const dds_return_t count =
      dds_read_mask(publications_, samples, infos, 256, 256,
                    DDS_ANY_SAMPLE_STATE | DDS_ANY_VIEW_STATE | DDS_ALIVE_INSTANCE_STATE);
  if (count < 0) {
    fail("cannot read DDS's publications", count);
  }
  for (dds_return_t i = 0; i < count; ++i) {
    if (!infos[i].valid_data) {
      continue;
    }
    auto* endpoint = static_cast<dds_builtintopic_endpoint_t*>(samples[i]);
    Publication row;
    row.participant = guid_hex(endpoint->participant_key);
    if (row.participant == own) {
      continue;
    }
    void* data = nullptr;
    std::size_t size = 0;
    if (endpoint->qos != nullptr && dds_qget_userdata(endpoint->qos, &data, &size) &&
        data != nullptr) {
      row.user_data.assign(static_cast<const char*>(data), size);
      dds_free(data);
    }
    dds_durability_kind_t durability = DDS_DURABILITY_VOLATILE;
    dds_duration_t deadline = DDS_INFINITY;
    // A writer writes the first representation it offers; none offered means XCDR1.
    if (endpoint->qos != nullptr) {
      dds_qget_durability(endpoint->qos, &durability);
      dds_qget_deadline(endpoint->qos, &deadline);
      std::uint32_t offered = 0;
      dds_data_representation_id_t* representations = nullptr;
      if (dds_qget_data_representation(endpoint->qos, &offered, &representations) &&
          representations != nullptr) {
        if (offered > 0) {
          row.data_representation = representations[0];
        }
        dds_free(representations);
      }
    }
    const dds_typeinfo_t* type_info = nullptr;
    row.typed =
        dds_builtintopic_get_endpoint_type_info(endpoint, &type_info) == 0 && type_info != nullptr;
    row.topic = endpoint->topic_name;
    row.transient_local = durability == DDS_DURABILITY_TRANSIENT_LOCAL;
    row.deadline_ms = deadline == DDS_INFINITY ? 0 : deadline / DDS_MSECS(1);
    row.type = endpoint->type_name;
    row.writer = guid_hex(endpoint->key);
    out.push_back(std::move(row));
  }
  dds_return_loan(publications_, samples, count);
  return out;
}

Writer::Writer(const std::shared_ptr<Participant>& participant, const std::string& topic,
               const TypeOnWire& type, const Qos& qos, const std::string& user_data)
    : Endpoint(participant, create_writer(*participant, topic, type, qos, user_data), topic),
      type_(participant->sertype(topic)) {}

void Writer::write(std::span<const std::byte> cdr) {
  // dds_writecdr consumes the sample's reference.
  const dds_return_t code = dds_writecdr(entity_, raw_cdr_sample(type_, cdr.data(), cdr.size()));
  if (code < 0) {
    fail("cannot write to DDS topic '" + topic_ + "'", code);
  }
}

std::uint32_t Writer::matched() const {
  dds_publication_matched_status_t status{};
  dds_get_publication_matched_status(entity_, &status);
  return status.current_count;
}

std::uint32_t Writer::deadlines_missed() const {
  dds_offered_deadline_missed_status_t status{};
  dds_get_offered_deadline_missed_status(entity_, &status);
  return status.total_count;
}

Reader::Reader(const std::shared_ptr<Participant>& participant, const std::string& topic,
               const TypeOnWire& type, const Qos& qos, bool typed_writers_only)
    : Endpoint(participant, create_reader(*participant, topic, type, qos, typed_writers_only),
               topic) {
  waitset_ = checked(dds_create_waitset(participant->handle()), "cannot create a DDS waitset");
  const dds_entity_t condition =
      checked(dds_create_readcondition(entity_, DDS_ANY_STATE), "cannot create a condition");
  const dds_return_t code = dds_waitset_attach(waitset_, condition, 0);
  if (code < 0) {
    fail("cannot wait on DDS topic '" + topic + "'", code);
  }
}

Reader::~Reader() { dds_delete(waitset_); }

std::vector<std::pair<dds_instance_handle_t, std::string>> Reader::take(
    std::chrono::nanoseconds timeout) {
  dds_waitset_wait(waitset_, nullptr, 0, timeout.count() < 0 ? 0 : timeout.count());
  std::vector<std::pair<dds_instance_handle_t, std::string>> received;
  const dds_return_t code = take_raw_cdr(
      entity_, [&received](std::span<const std::byte> sample, dds_instance_handle_t writer) {
        received.emplace_back(
            writer, std::string(reinterpret_cast<const char*>(sample.data()), sample.size()));
      });
  if (code < 0) {
    fail("cannot take from DDS topic '" + topic_ + "'", code);
  }
  return received;
}

std::uint32_t Reader::matched() const {
  dds_subscription_matched_status_t status{};
  dds_get_subscription_matched_status(entity_, &status);
  return status.current_count;
}

std::uint32_t Reader::deadlines_missed() const {
  dds_requested_deadline_missed_status_t status{};
  dds_get_requested_deadline_missed_status(entity_, &status);
  return status.total_count;
}

}  // namespace horus::dds_bridge
