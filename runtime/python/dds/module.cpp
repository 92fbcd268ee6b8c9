// horus._dds: the little of Cyclone DDS the bridge (`horus bridge`) needs, over raw CDR bytes.
// A participant on a domain; writers and readers of (DDS topic name, DDS type name) whose samples
// are CDR the caller encodes and decodes; the publications discovered. Every endpoint ignores
// those of its own participant, so a bridge never reads back what it wrote. For POD topics, a
// CdrPlan and the pumps (pump.hpp) that carry a topic between HORUS and DDS with no Python. For
// pool-backed topics (Image, ...), the runtime's PoolFrames: a descriptor's block read out, and a
// block of this namespace's pool filled in, as the recorder and its replay do.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "cdr_plan.hpp"
#include "horus/detail/pool_frames.hpp"
#include "pump.hpp"
#include "raw_cdr.hpp"

namespace py = pybind11;

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

struct Qos {
  bool reliable;
  std::int32_t depth;
  bool transient_local;
  std::int64_t deadline_ms;  // 0: none
};

// A DDS type: its name, and its serialized XTypes TypeInformation and TypeMapping (both empty:
// none, and DDS matches by the name alone).
struct TypeOnWire {
  std::string name;
  std::string info;
  std::string map;
};

// One participant and the raw-CDR topics it has made (one per DDS topic name).
class Participant {
 public:
  explicit Participant(std::uint32_t domain)
      : handle_(checked(dds_create_participant(domain, nullptr, nullptr),
                        "cannot create a DDS participant on domain " + std::to_string(domain))) {
    publications_ =
        checked(dds_create_reader(handle_, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr),
                "cannot read DDS's publications");
  }
  ~Participant() { dds_delete(handle_); }
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  dds_entity_t handle() const { return handle_; }

  std::string guid() const {
    dds_guid_t guid{};
    const dds_return_t code = dds_get_guid(handle_, &guid);
    if (code < 0) {
      fail("cannot read the participant's GUID", code);
    }
    return guid_hex(guid);
  }

  dds_entity_t topic(const std::string& name, const TypeOnWire& wire) {
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

  const ddsi_sertype* sertype(const std::string& name) const { return topics_.at(name).type; }

  // The publications DDS knows of now, this participant's own left out.
  py::list publications() const {
    const std::string own = guid();
    py::list out;
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
      const std::string participant = guid_hex(endpoint->participant_key);
      if (participant == own) {
        continue;
      }
      void* data = nullptr;
      std::size_t size = 0;
      std::string user_data;
      if (endpoint->qos != nullptr && dds_qget_userdata(endpoint->qos, &data, &size) &&
          data != nullptr) {
        user_data.assign(static_cast<const char*>(data), size);
        dds_free(data);
      }
      dds_durability_kind_t durability = DDS_DURABILITY_VOLATILE;
      dds_duration_t deadline = DDS_INFINITY;
      // A writer writes the first representation it offers; none offered means XCDR1.
      dds_data_representation_id_t representation = DDS_DATA_REPRESENTATION_XCDR1;
      if (endpoint->qos != nullptr) {
        dds_qget_durability(endpoint->qos, &durability);
        dds_qget_deadline(endpoint->qos, &deadline);
        std::uint32_t offered = 0;
        dds_data_representation_id_t* representations = nullptr;
        if (dds_qget_data_representation(endpoint->qos, &offered, &representations) &&
            representations != nullptr) {
          if (offered > 0) {
            representation = representations[0];
          }
          dds_free(representations);
        }
      }
      const dds_typeinfo_t* type_info = nullptr;
      const bool typed = dds_builtintopic_get_endpoint_type_info(endpoint, &type_info) == 0 &&
                         type_info != nullptr;
      py::dict row;
      row["topic"] = std::string(endpoint->topic_name);
      row["typed"] = typed;
      row["transient_local"] = durability == DDS_DURABILITY_TRANSIENT_LOCAL;
      row["deadline_ms"] = deadline == DDS_INFINITY ? 0 : deadline / DDS_MSECS(1);
      row["type"] = std::string(endpoint->type_name);
      row["participant"] = participant;
      row["writer"] = guid_hex(endpoint->key);
      row["data_representation"] = representation;
      row["user_data"] = py::bytes(user_data);
      out.append(row);
    }
    dds_return_loan(publications_, samples, count);
    return out;
  }

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

class Endpoint {
 public:
  Endpoint(std::shared_ptr<Participant> participant, dds_entity_t entity, std::string topic)
      : participant_(std::move(participant)), entity_(entity), topic_(std::move(topic)) {}
  ~Endpoint() { dds_delete(entity_); }
  Endpoint(const Endpoint&) = delete;
  Endpoint& operator=(const Endpoint&) = delete;

  dds_entity_t entity() const { return entity_; }
  const std::string& topic() const { return topic_; }

 protected:
  std::shared_ptr<Participant> participant_;
  dds_entity_t entity_;
  std::string topic_;
};

class Writer : public Endpoint {
 public:
  Writer(const std::shared_ptr<Participant>& participant, const std::string& topic,
         const TypeOnWire& type, const Qos& qos, const std::string& user_data)
      : Endpoint(participant, create(*participant, topic, type, qos, user_data), topic),
        type_(participant->sertype(topic)) {}

  const ddsi_sertype* type() const { return type_; }

  void write(const py::buffer& data) {
    const py::buffer_info info = data.request();
    ddsi_serdata* sample =
        raw_cdr_sample(type_, info.ptr, static_cast<std::size_t>(info.size * info.itemsize));
    dds_return_t code = 0;
    {
      // A reliable writer blocks while its history is full of unacknowledged samples.
      py::gil_scoped_release released;
      code = dds_writecdr(entity_, sample);  // consumes the sample's reference
    }
    if (code < 0) {
      fail("cannot write to DDS topic '" + topic_ + "'", code);
    }
  }

  std::uint32_t matched() const {
    dds_publication_matched_status_t status{};
    dds_get_publication_matched_status(entity_, &status);
    return status.current_count;
  }

  std::uint32_t deadlines_missed() const {
    dds_offered_deadline_missed_status_t status{};
    dds_get_offered_deadline_missed_status(entity_, &status);
    return status.total_count;
  }

 private:
  static dds_entity_t create(Participant& participant, const std::string& topic,
                             const TypeOnWire& type, const Qos& qos, const std::string& user_data) {
    const dds_entity_t entity = participant.topic(topic, type);
    dds_qos_t* settings = make_qos(qos, user_data, false);
    const dds_entity_t writer = dds_create_writer(participant.handle(), entity, settings, nullptr);
    dds_delete_qos(settings);
    return checked(writer, "cannot create a DDS writer on '" + topic + "'");
  }

  const ddsi_sertype* type_;
};

class Reader : public Endpoint {
 public:
  Reader(const std::shared_ptr<Participant>& participant, const std::string& topic,
         const TypeOnWire& type, const Qos& qos, bool typed_writers_only)
      : Endpoint(participant, create(*participant, topic, type, qos, typed_writers_only), topic) {
    waitset_ = checked(dds_create_waitset(participant->handle()), "cannot create a DDS waitset");
    const dds_entity_t condition =
        checked(dds_create_readcondition(entity_, DDS_ANY_STATE), "cannot create a condition");
    const dds_return_t code = dds_waitset_attach(waitset_, condition, 0);
    if (code < 0) {
      fail("cannot wait on DDS topic '" + topic + "'", code);
    }
  }
  ~Reader() { dds_delete(waitset_); }
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  // The samples that arrived, oldest first, waiting up to `timeout` seconds for the first: each
  // its bytes, or (with `writers`) a tuple of its writer's instance handle and its bytes. The
  // handle, not the GUID: finding a GUID allocates and locks in DDS, and only a sample dropped
  // needs one (WriterGuids).
  py::list take(double timeout, bool writers) {
    std::vector<std::pair<dds_instance_handle_t, std::string>> received;
    dds_return_t failure = 0;
    {
      py::gil_scoped_release released;
      const auto wait = std::chrono::duration_cast<std::chrono::nanoseconds>(
          std::chrono::duration<double>(timeout < 0 ? 0 : timeout));
      dds_waitset_wait(waitset_, nullptr, 0, wait.count());
      failure = take_all(received);
    }
    if (failure < 0) {
      fail("cannot take from DDS topic '" + topic_ + "'", failure);
    }
    py::list out;
    for (const auto& [writer, sample] : received) {
      if (writers) {
        out.append(py::make_tuple(writer, py::bytes(sample)));
      } else {
        out.append(py::bytes(sample));
      }
    }
    return out;
  }

  std::uint32_t matched() const {
    dds_subscription_matched_status_t status{};
    dds_get_subscription_matched_status(entity_, &status);
    return status.current_count;
  }

  std::uint32_t deadlines_missed() const {
    dds_requested_deadline_missed_status_t status{};
    dds_get_requested_deadline_missed_status(entity_, &status);
    return status.total_count;
  }

 private:
  static dds_entity_t create(Participant& participant, const std::string& topic,
                             const TypeOnWire& type, const Qos& qos, bool typed_writers_only) {
    const dds_entity_t entity = participant.topic(topic, type);
    dds_qos_t* settings = make_qos(qos, "", typed_writers_only);
    const dds_entity_t reader = dds_create_reader(participant.handle(), entity, settings, nullptr);
    dds_delete_qos(settings);
    return checked(reader, "cannot create a DDS reader on '" + topic + "'");
  }

  dds_return_t take_all(std::vector<std::pair<dds_instance_handle_t, std::string>>& out) {
    const auto keep = [&out](std::span<const std::byte> sample, dds_instance_handle_t writer) {
      out.emplace_back(writer,
                       std::string(reinterpret_cast<const char*>(sample.data()), sample.size()));
    };
    return take_raw_cdr(entity_, keep);
  }

  dds_entity_t waitset_ = 0;
};

CdrStep::Kind step_kind(const std::string& name) {
  static const std::map<std::string, CdrStep::Kind> kinds{{"copy", CdrStep::Kind::kCopy},
                                                          {"bool", CdrStep::Kind::kBool},
                                                          {"string", CdrStep::Kind::kString},
                                                          {"empty", CdrStep::Kind::kEmpty}};
  const auto found = kinds.find(name);
  if (found == kinds.end()) {
    throw std::invalid_argument("no CDR step of kind '" + name + "'");
  }
  return found->second;
}

CdrPlan make_plan(
    std::string type_name, std::size_t size,
    const std::vector<std::tuple<std::string, std::uint32_t, std::uint32_t, std::uint32_t>>&
        steps) {
  std::vector<CdrStep> plan;
  for (const auto& [kind, offset, step_size, count] : steps) {
    plan.push_back(CdrStep{step_kind(kind), offset, step_size, count});
  }
  return {std::move(type_name), size, std::move(plan)};
}

std::span<const std::byte> bytes_of(const py::buffer_info& info) {
  return {static_cast<const std::byte*>(info.ptr),
          static_cast<std::size_t>(info.size * info.itemsize)};
}

LocalTopic local_topic(const py::dict& local) {
  LocalTopic out;
  out.name = local["name"].cast<std::string>();
  out.type_name = local["type_name"].cast<std::string>();
  out.fingerprint = local["fingerprint"].cast<std::uint64_t>();
  out.schema = local["schema"].cast<std::string>();
  out.alignment = local["alignment"].cast<std::size_t>();
  out.capacity = local["capacity"].cast<std::size_t>();
  out.max_message_size = local["max_message_size"].cast<std::size_t>();
  out.single_publisher = local["single_publisher"].cast<bool>();
  out.namespace_name = local["namespace"].cast<std::string>();
  return out;
}

void bind_pump(py::class_<Pump, std::unique_ptr<Pump>>& pump) {
  pump.def("stop", &Pump::stop, py::call_guard<py::gil_scoped_release>(),
           "Stops the thread and waits for it.")
      .def_property_readonly("carried", &Pump::carried, "Messages carried so far.")
      .def_property_readonly("failures", &Pump::failures, "Failures so far (each said on stderr).")
      .def_property_readonly(
          "broken",
          [](const Pump& self) -> std::optional<std::string> {
            std::string why = self.broken();
            return why.empty() ? std::nullopt : std::optional(std::move(why));
          },
          "Why the thread ended on its own (a bug), or None.");
}

py::object pool_frames(const std::string& type_name, std::uint64_t fingerprint,
                       const std::string& namespace_name, std::size_t keep) {
  std::unique_ptr<detail::PoolFrames> frames =
      detail::make_pool_frames(type_name, fingerprint, namespace_name, keep);
  return frames ? py::cast(std::move(frames)) : py::none();
}

py::object record_frame(detail::PoolFrames& frames, const py::buffer& descriptor) {
  const py::buffer_info info = descriptor.request();
  const std::span<const std::byte> bytes = bytes_of(info);
  std::string recorded;
  std::size_t size = 0;
  {
    const py::gil_scoped_release unlocked;
    size = frames.record(bytes.data(), bytes.size(), [&recorded](std::size_t wanted) {
      recorded.resize(wanted);
      return reinterpret_cast<std::uint8_t*>(recorded.data());
    });
  }
  if (size == 0) {
    return py::none();
  }
  return py::bytes(recorded.data(), size);
}

py::object replay_frame(detail::PoolFrames& frames, const py::buffer& recorded) {
  const py::buffer_info info = recorded.request();
  std::span<const std::byte> descriptor;
  {
    const py::gil_scoped_release unlocked;
    descriptor = frames.replay({static_cast<const std::uint8_t*>(info.ptr),
                                static_cast<std::size_t>(info.size * info.itemsize)});
  }
  if (descriptor.empty()) {
    return py::none();
  }
  return py::bytes(reinterpret_cast<const char*>(descriptor.data()), descriptor.size());
}

// A time.monotonic() reading as the steady clock's time point (seconds past its epoch); one
// beyond the clock's range, inf included, is its last: a DropReport then says what it counted.
std::chrono::steady_clock::time_point steady_at(double seconds) {
  using Clock = std::chrono::steady_clock;
  // Half the range: a cast of a double near its end could round past it and overflow.
  constexpr double kLast = std::chrono::duration<double>(Clock::duration::max()).count() / 2;
  if (!(seconds < kLast)) {  // NaN too
    return Clock::time_point::max();
  }
  if (seconds <= -kLast) {
    return Clock::time_point{};
  }
  return Clock::time_point(
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds)));
}

// WriterGuids over one reader, for the Python threads.
class ReaderWriterGuids {
 public:
  ReaderWriterGuids(std::shared_ptr<Reader> reader, std::size_t cap)
      : reader_(std::move(reader)), guids_(cap) {}

  std::optional<std::string> find(dds_instance_handle_t writer) {
    const std::string* guid = guids_.find(reader_->entity(), writer);
    return guid == nullptr ? std::nullopt : std::optional(*guid);
  }
  std::size_t kept() const { return guids_.kept(); }

 private:
  std::shared_ptr<Reader> reader_;
  WriterGuids guids_;
};

}  // namespace
}  // namespace horus::dds_bridge

PYBIND11_MODULE(_dds, m) {
  using namespace horus::dds_bridge;
  m.doc() = "Raw-CDR endpoints on Cyclone DDS for the HORUS bridge (horus bridge).";

  py::class_<Participant, std::shared_ptr<Participant>>(m, "Participant")
      .def(py::init<std::uint32_t>(), py::arg("domain"))
      .def_property_readonly("guid", &Participant::guid)
      .def("publications", &Participant::publications,
           "The publications on the domain other participants have: dicts of topic, type, "
           "typed (whether the writer announces XTypes type information), participant and "
           "writer (GUIDs), user_data (bytes), transient_local, deadline_ms (0: none) and "
           "data_representation (the one the writer writes: 0 XCDR1, 2 XCDR2).");

  py::class_<Writer, std::shared_ptr<Writer>>(m, "Writer")
      .def(py::init([](const std::shared_ptr<Participant>& participant, const std::string& topic,
                       const std::string& type_name, bool reliable, std::int32_t depth,
                       bool transient_local, std::int64_t deadline_ms, const py::bytes& user_data,
                       const py::bytes& type_info, const py::bytes& type_map) {
             return std::make_shared<Writer>(
                 participant, topic, TypeOnWire{type_name, type_info, type_map},
                 Qos{reliable, depth, transient_local, deadline_ms}, std::string(user_data));
           }),
           py::arg("participant"), py::arg("topic"), py::arg("type_name"), py::kw_only(),
           py::arg("reliable") = true, py::arg("depth") = 100, py::arg("transient_local") = false,
           py::arg("deadline_ms") = 0, py::arg("user_data") = py::bytes(),
           py::arg("type_info") = py::bytes(), py::arg("type_map") = py::bytes(),
           "A writer of raw CDR; type_info and type_map: the type's serialized XTypes "
           "TypeInformation and TypeMapping (idlc's), announced to readers (empty: none).")
      .def("write", &Writer::write, py::arg("cdr"),
           "Writes one sample: its CDR, 4-byte encapsulation header included.")
      .def("matched", &Writer::matched, "How many readers match this writer now.")
      .def("deadlines_missed", &Writer::deadlines_missed,
           "How many times this writer wrote nothing within its deadline (deadline_ms).");

  py::class_<Reader, std::shared_ptr<Reader>>(m, "Reader")
      .def(py::init([](const std::shared_ptr<Participant>& participant, const std::string& topic,
                       const std::string& type_name, bool reliable, std::int32_t depth,
                       bool transient_local, std::int64_t deadline_ms, const py::bytes& type_info,
                       const py::bytes& type_map, bool typed_writers_only) {
             return std::make_shared<Reader>(
                 participant, topic, TypeOnWire{type_name, type_info, type_map},
                 Qos{reliable, depth, transient_local, deadline_ms}, typed_writers_only);
           }),
           py::arg("participant"), py::arg("topic"), py::arg("type_name"), py::kw_only(),
           py::arg("reliable") = true, py::arg("depth") = 100, py::arg("transient_local") = false,
           py::arg("deadline_ms") = 0, py::arg("type_info") = py::bytes(),
           py::arg("type_map") = py::bytes(), py::arg("typed_writers_only") = false,
           "A reader of raw CDR; type_info and type_map as a Writer's. typed_writers_only: DDS "
           "matches only writers that announce type information and whose type is assignable "
           "to this one (else writers of the same type name, whatever their layout).")
      .def("take", &Reader::take, py::arg("timeout"), py::arg("writers") = false,
           "The samples received (CDR bytes, oldest first), waiting up to timeout seconds; "
           "with writers=True each is (the writer's instance handle, its bytes): WriterGuids "
           "finds its GUID.")
      .def("matched", &Reader::matched, "How many writers match this reader now.")
      .def("deadlines_missed", &Reader::deadlines_missed,
           "How many times nothing arrived within this reader's deadline (deadline_ms).");

  py::class_<ReaderWriterGuids>(
      m, "WriterGuids",
      "The GUIDs of the writers a reader matches, by the instance handle take(writers=True) "
      "gives: looked up in DDS once a writer, at most `cap` kept (DropReport's cap).")
      .def(py::init<std::shared_ptr<Reader>, std::size_t>(), py::arg("reader"),
           py::arg("cap") = DropReport::kCap)
      .def("find", &ReaderWriterGuids::find, py::arg("writer"),
           "The GUID (hex) of the writer of that handle (\"unknown\" once DDS forgot it), or None "
           "when `cap` others are kept already.")
      .def_property_readonly("kept", &ReaderWriterGuids::kept, "How many GUIDs it keeps.");

  py::class_<DropReport>(
      m, "DropReport",
      "The samples of an imported topic dropped for what a writer sent (the C++ pumps' report): "
      "the first of each (writer, reason) a line, the rest counted, a count line at most every "
      "EVERY_S; at most `cap` (writer, reason) pairs kept, past them the samples of other "
      "writers and reasons counted as other writers'. Times are time.monotonic() seconds.")
      .def(py::init<std::size_t>(), py::arg("cap") = DropReport::kCap)
      .def_property_readonly_static(
          "EVERY_S",
          [](const py::object&) {
            return std::chrono::duration<double>(DropReport::kEvery).count();
          })
      .def_property_readonly_static("CAP", [](const py::object&) { return DropReport::kCap; })
      .def(
          "dropped",
          [](DropReport& self, const std::optional<std::string>& writer, const std::string& reason,
             std::uint64_t failure, double now) {
            return self.dropped(writer ? &*writer : nullptr, reason, failure, steady_at(now));
          },
          py::arg("writer"), py::arg("reason"), py::arg("failure"), py::arg("now"),
          "The line to say (without the topic) of one more sample dropped, or \"\" when it is "
          "only counted; writer: its GUID, None for one past WriterGuids' cap; failure: the "
          "topic's running count of failures, this one included.")
      .def(
          "due",
          [](DropReport& self, std::uint64_t failures, double now) {
            return self.due(failures, steady_at(now));
          },
          py::arg("failures"), py::arg("now"),
          "The line counting the samples dropped unsaid once EVERY_S has passed since the last "
          "line (now=inf: whenever there are some, as a thread ends), or \"\".")
      .def_property_readonly("kept", &DropReport::kept,
                             "How many (writer, reason) pairs it keeps (cap at most).");

  py::class_<CdrPlan>(m, "CdrPlan",
                      "A POD type's CDR as steps over its struct bytes (dds_cdr.pod_plan).")
      .def(py::init(&make_plan), py::arg("type_name"), py::arg("size"), py::arg("steps"))
      .def(
          "encode",
          [](const CdrPlan& plan, const py::buffer& pod) {
            const py::buffer_info info = pod.request();
            const std::span<const std::byte> bytes = bytes_of(info);
            if (bytes.size() != plan.pod_size()) {
              throw std::invalid_argument(plan.type_name() + " is " +
                                          std::to_string(plan.pod_size()) + " bytes, not " +
                                          std::to_string(bytes.size()));
            }
            std::vector<std::byte> sample;
            plan.encode(bytes.data(), sample);
            return py::bytes(reinterpret_cast<const char*>(sample.data()), sample.size());
          },
          py::arg("pod"), "The DDS sample (CDR) of a message's POD bytes.")
      .def(
          "decode",
          [](const CdrPlan& plan, const py::buffer& sample) {
            const py::buffer_info info = sample.request();
            std::string pod(plan.pod_size(), '\0');
            const std::string error =
                plan.decode(bytes_of(info), reinterpret_cast<std::byte*>(pod.data()));
            if (!error.empty()) {
              throw py::value_error(error);
            }
            return py::bytes(pod);
          },
          py::arg("cdr"),
          "A message's POD bytes from a DDS sample; ValueError when it does not fit.");

  py::class_<Pump, std::unique_ptr<Pump>> pump(
      m, "Pump", "The C++ thread that carries one POD topic (stopped when deleted).");
  bind_pump(pump);
  horus::detail::enable_pool_frames();
  py::class_<horus::detail::PoolFrames>(
      m, "PoolFrames",
      "The frames of a pool-backed topic (Image, DepthImage, PointCloud, Tensor): its "
      "descriptors with the data of their blocks (horus/detail/pool_frames.hpp).")
      .def("record", &record_frame, py::arg("descriptor"),
           "The descriptor (its block zeroed) followed by the data of the block it names, or "
           "None when the block was freed or reused since, or is of another pool.")
      .def("replay", &replay_frame, py::arg("recorded"),
           "What record() gave, made again in a block of this namespace's default pool: the "
           "descriptor naming it (held until `keep` more were made), or None when malformed; "
           "RuntimeError when the pool has no block to give.");
  m.def("pool_frames", &pool_frames, py::arg("type_name"), py::arg("fingerprint"),
        py::arg("namespace"), py::arg("keep"),
        "The PoolFrames of a pool-backed type in a namespace (empty: the current one), or None "
        "for any other type.");
  m.def(
      "export_pump",
      [](const std::shared_ptr<Writer>& writer, const CdrPlan& plan, const py::dict& local,
         std::string label, bool latched) -> std::unique_ptr<Pump> {
        return std::make_unique<ExportPump>(local_topic(local), plan, writer->entity(),
                                            writer->type(), writer->topic(), latched,
                                            std::move(label), writer);
      },
      py::arg("writer"), py::arg("plan"), py::arg("local"), py::arg("label"),
      py::arg("latched") = false,
      "Carries the local topic `local` (horus._core.Topic's arguments as a dict, and namespace) "
      "to `writer` on a thread of its own; failures are lines on stderr starting with `label`. "
      "latched: first the topic's newest message (for a transient-local writer).");
  m.def(
      "import_pump",
      [](const std::shared_ptr<Reader>& reader, const CdrPlan& plan, const py::dict& local,
         std::string label, std::size_t drop_cap) -> std::unique_ptr<Pump> {
        return std::make_unique<ImportPump>(local_topic(local), plan, reader->entity(),
                                            reader->topic(), std::move(label), reader, drop_cap);
      },
      py::arg("reader"), py::arg("plan"), py::arg("local"), py::arg("label"),
      py::arg("drop_cap") = DropReport::kCap,
      "Carries what `reader` receives into the local topic `local` on a thread of its own; "
      "drop_cap: the cap of its DropReport and WriterGuids.");
}
