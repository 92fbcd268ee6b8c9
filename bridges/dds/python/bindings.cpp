// horus._core.dds: the DDS bridge's library (bridges/dds/) as the Python bridge (`horus bridge`,
// horus.Network) uses it, built into horus._core so the process has one copy of the runtime and
// its process-wide state. Raw-CDR endpoints (endpoints.hpp); for POD topics, a CdrPlan and the
// pumps (pump.hpp) that carry a topic between HORUS and DDS with no Python; for pool-backed topics
// (Image, ...), the runtime's PoolFrames: a descriptor's block read out, and a block of this
// namespace's pool filled in, as the recorder and its replay do.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "horus/dds/cdr_plan.hpp"
#include "horus/dds/endpoints.hpp"
#include "horus/dds/pump.hpp"
#include "horus/dds/ros2_twins.hpp"
#include "horus/dds/serialized_cdr.hpp"
#include "horus/dds/services.hpp"
#include "horus/dds/xtypes.hpp"
#include "horus/dds_bridge.hpp"
#include "horus/pool_frames.hpp"

namespace py = pybind11;

namespace horus::dds_bridge {
namespace {

using Pump = bridge::Forwarder;

py::dict publication_row(const Publication& publication) {
  py::dict row;
  row["topic"] = publication.topic;
  row["typed"] = publication.typed;
  row["transient_local"] = publication.transient_local;
  row["deadline_ms"] = publication.deadline_ms;
  row["type"] = publication.type;
  row["participant"] = publication.participant;
  row["writer"] = publication.writer;
  row["data_representation"] = publication.data_representation;
  row["user_data"] = py::bytes(publication.user_data);
  return row;
}

py::list publications(const Participant& participant) {
  py::list out;
  for (const Publication& publication : participant.publications()) {
    out.append(publication_row(publication));
  }
  return out;
}

void write(Writer& writer, const py::buffer& data) {
  const py::buffer_info info = data.request();
  const std::span<const std::byte> cdr{static_cast<const std::byte*>(info.ptr),
                                       static_cast<std::size_t>(info.size * info.itemsize)};
  // A reliable writer blocks while its history is full of unacknowledged samples.
  const py::gil_scoped_release released;
  writer.write(cdr);
}

py::list take(Reader& reader, double timeout, bool writers) {
  std::vector<std::pair<dds_instance_handle_t, std::string>> received;
  {
    const py::gil_scoped_release released;
    received = reader.take(std::chrono::duration_cast<std::chrono::nanoseconds>(
        std::chrono::duration<double>(timeout < 0 ? 0 : timeout)));
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

// A SerializedCdr with the description it reads, for Python.
class SerializedCodec {
 public:
  explicit SerializedCodec(const py::bytes& description)
      : description_(TypeDescription::decode(std::string_view(description))),
        codec_(description_, description_.root_message()) {}

  py::bytes encode(const py::buffer& message) const {
    const py::buffer_info info = message.request();
    std::vector<std::byte> sample;
    codec_.encode({static_cast<const std::uint8_t*>(info.ptr),
                   static_cast<std::size_t>(info.size * info.itemsize)},
                  sample);
    return {reinterpret_cast<const char*>(sample.data()), sample.size()};
  }

  py::bytes decode(const py::buffer& sample) const {
    const py::buffer_info info = sample.request();
    std::vector<std::uint8_t> message;
    const std::string error = codec_.decode(bytes_of(info), message);
    if (!error.empty()) {
      throw py::value_error(error);
    }
    return {reinterpret_cast<const char*>(message.data()), message.size()};
  }

 private:
  TypeDescription description_;
  SerializedCdr codec_;
};

// A ROS 2 twin's conversion for Python: a message's bytes to the twin's CDR and back.
class TwinCodec {
 public:
  explicit TwinCodec(const std::string& horus_type) {
    const Ros2Twin* twin = ros2_twin_of(horus_type);
    if (twin == nullptr) {
      throw py::value_error(horus_type + " has no ROS 2 twin");
    }
    conversion_ = twin_conversion(*twin);
  }

  py::bytes encode(const py::bytes& message) {
    const std::string_view bytes = message;
    try {
      conversion_->to_dds(std::as_bytes(std::span(bytes.data(), bytes.size())), buffer_);
    } catch (const std::invalid_argument& error) {
      throw py::value_error(error.what());
    }
    return {reinterpret_cast<const char*>(buffer_.data()), buffer_.size()};
  }

  py::bytes decode(const py::bytes& cdr) {
    const std::string_view bytes = cdr;
    const std::string why =
        conversion_->to_local(std::as_bytes(std::span(bytes.data(), bytes.size())), buffer_);
    if (!why.empty()) {
      throw py::value_error(why);
    }
    return {reinterpret_cast<const char*>(buffer_.data()), buffer_.size()};
  }

 private:
  std::unique_ptr<Conversion> conversion_;
  std::vector<std::byte> buffer_;
};

// A DdsBridge for the Python bridge: its failure kept for Python to look at (the bridge's thread
// takes no GIL, so stop() never waits on Python).
class PythonDdsBridge {
 public:
  // `find_type`: a Python callable, a generated class's type description by its HORUS name (or
  // None); called on the bridge's thread, which takes the GIL for it.
  PythonDdsBridge(Network options, std::string namespace_name,
                  std::shared_ptr<py::object> find_type)
      : failure_(std::make_shared<Failure>()),
        find_type_(std::move(find_type)),
        bridge_(
            std::move(options), std::move(namespace_name),
            [failure = failure_](const std::string& why) {
              const std::lock_guard lock(failure->mutex);
              failure->why = why;
            },
            lookup(find_type_)) {}

  void stop() { bridge_.stop(); }
  std::optional<std::string> broken() const {
    const std::lock_guard lock(failure_->mutex);
    return failure_->why.empty() ? std::nullopt : std::optional(failure_->why);
  }

 private:
  struct Failure {
    std::mutex mutex;
    std::string why;
  };

  static horus::dds::TypeLookup lookup(const std::shared_ptr<py::object>& find_type) {
    if (find_type->is_none()) {
      return {};
    }
    return [find_type](const std::string& type_name) -> std::optional<TypeIdentity> {
      std::string description;
      {
        const py::gil_scoped_acquire gil;
        const py::object found = (*find_type)(type_name);
        if (found.is_none()) {
          return std::nullopt;
        }
        description = found.cast<std::string>();
      }
      return described_type(std::move(description));
    };
  }

  std::shared_ptr<Failure> failure_;
  // Held here too, so the last reference goes with this object (under the GIL), not on the
  // bridge's thread.
  std::shared_ptr<py::object> find_type_;
  horus::dds::DdsBridge bridge_;
};

}  // namespace
}  // namespace horus::dds_bridge

namespace horus::python {

void bind_dds(py::module_& m) {
  using namespace horus::dds_bridge;

  using namespace horus::dds_bridge;

  py::class_<Participant, std::shared_ptr<Participant>>(m, "Participant")
      .def(py::init<std::uint32_t>(), py::arg("domain"))
      .def_property_readonly("guid", &Participant::guid)
      .def("publications", &publications,
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
      .def("write", &write, py::arg("cdr"),
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
      .def("take", &take, py::arg("timeout"), py::arg("writers") = false,
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
      .def_static(
          "from_description",
          [](const py::bytes& description) {
            const TypeDescription decoded = TypeDescription::decode(std::string_view(description));
            return pod_cdr_plan(decoded, decoded.root_message());
          },
          py::arg("description"),
          "The plan of the POD type a type description (T.__horus__.description) is for; "
          "ValueError for a serialized type, HorusError for bytes that are no description.")
      .def_property_readonly(
          "steps",
          [](const CdrPlan& plan) {
            static constexpr const char* kKinds[] = {"copy", "bool", "string", "empty",
                                                     "pool_data"};
            py::list out;
            for (const CdrStep& step : plan.steps()) {
              out.append(py::make_tuple(kKinds[static_cast<int>(step.kind)], step.offset, step.size,
                                        step.count));
            }
            return out;
          },
          "The steps as (kind, offset, size, count) tuples.")
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

  py::class_<SerializedCodec>(
      m, "SerializedCdr",
      "A serialized type's CDR from its type description (the C++ bridge's conversion): "
      "encode(MessagePack bytes) -> CDR sample, decode(CDR sample) -> MessagePack bytes "
      "(ValueError when it does not fit).")
      .def(py::init<const py::bytes&>(), py::arg("description"))
      .def("encode", &SerializedCodec::encode, py::arg("message"))
      .def("decode", &SerializedCodec::decode, py::arg("cdr"));
  m.def(
      "ros2_twins",
      [] {
        std::vector<std::tuple<std::string, std::string, std::string>> out;
        for (const Ros2Twin& twin : ros2_twins()) {
          out.emplace_back(twin.horus, twin.ros2, twin.dds_type());
        }
        return out;
      },
      "The ROS 2 twins of standard types, (HORUS type, ROS 2 type, DDS type name) each, the "
      "first twin of a ROS 2 type first.");
  py::class_<TwinCodec>(m, "TwinCodec",
                        "A standard type's messages (their bytes) to its ROS 2 twin's CDR and "
                        "back (ValueError saying why a sample does not decode).")
      .def(py::init<const std::string&>(), py::arg("horus_type"))
      .def("encode", &TwinCodec::encode, py::arg("message"))
      .def("decode", &TwinCodec::decode, py::arg("cdr"));
  py::class_<PythonDdsBridge>(
      m, "DdsBridge",
      "The C++ bridge (bridges/dds/): carries the topics, services and frames (export_frames, "
      "import_frames: child frame patterns, as rt/tf and rt/tf_static) and the actions "
      "(export_actions: served to ROS 2 action clients; import_actions: ROS 2 action servers "
      "offered to local clients) the patterns name on threads of its own, "
      "saying each on stdout and each refusal on stderr, until stop(). "
      "find_type(name): a generated class's type description by its HORUS name, or None (how an "
      "exported service's response type is found before a local call showed it).")
      .def(
          py::init(
              [](const std::string& namespace_name, std::vector<std::string> exports,
                 std::vector<std::string> imports, int domain, bool reliable, int depth,
                 std::vector<std::string> transient_local,
                 const std::vector<std::pair<std::string, std::int64_t>>& deadlines,
                 bool accept_untyped_writers, std::vector<std::string> ros2_types,
                 std::vector<std::string> export_services, std::vector<std::string> import_services,
                 double service_timeout, py::object find_type,
                 std::vector<std::string> export_frames, std::vector<std::string> import_frames,
                 std::vector<std::string> export_actions, std::vector<std::string> import_actions) {
                Network options{.export_ = std::move(exports),
                                .import_ = std::move(imports),
                                .domain = domain,
                                .reliable = reliable,
                                .depth = depth,
                                .transient_local = std::move(transient_local),
                                .export_services = std::move(export_services),
                                .import_services = std::move(import_services),
                                .service_timeout = std::chrono::duration<double>(service_timeout),
                                .ros2_types = std::move(ros2_types),
                                .accept_untyped_writers = accept_untyped_writers,
                                .export_frames = std::move(export_frames),
                                .import_frames = std::move(import_frames),
                                .export_actions = std::move(export_actions),
                                .import_actions = std::move(import_actions)};
                for (const auto& [pattern, milliseconds] : deadlines) {
                  options.deadlines.emplace_back(pattern, std::chrono::milliseconds(milliseconds));
                }
                // Made (and, should the bridge not start, let go) under the GIL.
                const auto held = std::make_shared<py::object>(std::move(find_type));
                const py::gil_scoped_release released;  // it starts DDS and a thread
                return std::make_unique<PythonDdsBridge>(std::move(options), namespace_name, held);
              }),
          py::arg("namespace"), py::arg("exports"), py::arg("imports"), py::arg("domain"),
          py::arg("reliable"), py::arg("depth"), py::arg("transient_local"), py::arg("deadlines"),
          py::arg("accept_untyped_writers"), py::arg("ros2_types"),
          py::arg("export_services") = std::vector<std::string>{},
          py::arg("import_services") = std::vector<std::string>{},
          py::arg("service_timeout") = 10.0, py::arg("find_type") = py::none(),
          py::arg("export_frames") = std::vector<std::string>{},
          py::arg("import_frames") = std::vector<std::string>{},
          py::arg("export_actions") = std::vector<std::string>{},
          py::arg("import_actions") = std::vector<std::string>{})
      .def("stop", &PythonDdsBridge::stop, py::call_guard<py::gil_scoped_release>(),
           "Stops every carried topic and deletes the bridge's DDS entities.")
      .def_property_readonly("broken", &PythonDdsBridge::broken,
                             "Why the bridge stopped on its own (said on stderr), or None.");
  m.def(
      "type_on_wire",
      [](const py::bytes& description) {
        const TypeDescription decoded = TypeDescription::decode(std::string_view(description));
        TypeOnWire wire;
        {
          const py::gil_scoped_release released;  // idlc runs
          wire = type_on_wire(decoded, decoded.root_message());
        }
        return py::make_tuple(wire.name, py::bytes(wire.info), py::bytes(wire.map));
      },
      py::arg("description"),
      "(DDS type name, type_info, type_map) of the type a description is for, from the IDL the "
      "C++ bridge spells and idlc (what its endpoints announce).");
}

}  // namespace horus::python
