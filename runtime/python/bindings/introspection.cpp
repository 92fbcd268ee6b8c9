// horus._core: what the `horus` command reads about a namespace besides its topics: services,
// the log ring, the processes' presence, and the cleaning of what dead processes left.
#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "bindings.hpp"
#include "horus/error.hpp"
#include "horus/log.hpp"
#include "horus/presence.hpp"
#include "horus/service_registry.hpp"
#include "horus/topic_registry.hpp"

namespace horus::python {

namespace py = pybind11;

void bind_introspection(py::module_& m) {
  m.def(
      "list_services",
      [](const std::string& namespace_name) {
        py::list out;
        for (const ServiceInfo& info : list_services(namespace_name)) {
          py::dict service;
          service["name"] = info.name;
          service["request_type"] = info.request_type;
          service["response_type"] = info.response_type;
          service["fingerprint"] = info.fingerprint;
          service["servers"] = info.servers;
          service["server_pid"] = info.server_pid;
          service["clients"] = info.clients;
          out.append(service);
        }
        return out;
      },
      py::arg("namespace_name") = "",
      "The services of a namespace (empty: HORUS_NAMESPACE), sorted by name.");
  m.def(
      "read_log",
      [](const std::string& namespace_name) {
        const LogSnapshot snapshot = read_log(namespace_name);
        py::list records;
        for (const LogRecord& record : snapshot.records) {
          py::dict line;
          line["sequence"] = record.sequence;
          line["wall_time_ns"] = record.wall_time_ns;
          line["pid"] = record.pid;
          line["level"] = std::string(to_string(record.level));
          line["source"] = record.source;
          line["message"] = record.message;
          line["text"] = format_log_line(record);
          records.append(line);
        }
        py::dict out;
        out["records"] = records;
        out["written"] = snapshot.written;
        out["dropped"] = snapshot.dropped;
        return out;
      },
      py::arg("namespace_name") = "",
      "The namespace's log ring: retained lines oldest first, and its counters.");
  m.def(
      "list_presence",
      [](const std::string& namespace_name) {
        py::list out;
        for (const PresenceInfo& info : list_presence(namespace_name)) {
          py::dict entry;
          entry["entry"] = info.entry;
          entry["pid"] = info.pid;
          entry["alive"] = info.alive;
          entry["started_wall_ns"] = info.started_wall_ns;
          entry["updated_wall_ns"] = info.updated_wall_ns;
          entry["snapshot_json"] = info.snapshot_json;
          entry["error"] = info.error;
          out.append(entry);
        }
        return out;
      },
      py::arg("namespace_name") = "",
      "The schedulers' presence announcements of a namespace, dead processes' included.");
  m.def(
      "clean_presence",
      [](const std::string& namespace_name) { return clean_presence(namespace_name); },
      py::arg("namespace_name") = "",
      "Removes the presence announcements dead processes left; returns how many.");
  m.def(
      "topic_traffic",
      [](const std::string& topic, std::uint64_t since, const std::string& namespace_name) {
        const TopicTraffic traffic = topic_traffic(topic, since, namespace_name);
        py::dict out;
        out["message_count"] = traffic.message_count;
        out["counted"] = traffic.counted;
        out["bytes"] = traffic.bytes;
        const auto stamp = [](const std::optional<SendStamp>& sent) -> py::object {
          if (!sent) return py::none();
          py::dict fields;
          fields["ticket"] = sent->ticket;
          fields["second"] = sent->second;
          return fields;
        };
        out["first_new_second"] = stamp(traffic.first_new_second);
        out["last_new_second"] = stamp(traffic.last_new_second);
        out["newest"] = stamp(traffic.newest);
        return out;
      },
      py::arg("topic"), py::arg("since"), py::arg("namespace_name") = "",
      "A topic's message count, and the messages from ticket `since` still in the ring with "
      "their payload bytes, and the send stamps where the second changes (slot headers only).");
  m.def(
      "clean_namespace",
      [](const std::string& namespace_name) { return clean_namespace(namespace_name); },
      py::arg("namespace_name") = "",
      "Unlinks the topic segments whose every user process died; returns how many. The log "
      "ring and the presence folder go too once no live process uses them.");
  m.def(
      "remove_namespace",
      [](const std::string& namespace_name) { remove_namespace(namespace_name); },
      py::arg("namespace_name"),
      "Unlinks every segment of a namespace, its log ring and its presence folder, in use or not.");
  m.def(
      "list_namespace_objects",
      [](const std::string& namespace_name) {
        py::list out;
        for (const NamespaceObjectInfo& info : list_namespace_objects(namespace_name)) {
          py::dict entry;
          entry["kind"] = info.kind;
          entry["path"] = info.path;
          entry["size"] = info.size;
          entry["in_use"] = info.in_use;
          out.append(entry);
        }
        return out;
      },
      py::arg("namespace_name") = "",
      "The namespace's log ring (kind \"@logs\") and presence folder (\"@presence\"), those that "
      "exist: path, size and whether a live process uses it.");
  py::class_<detail::AnnouncedUse>(
      m, "AnnouncedUse",
      "A service server or client in this process's presence announcement, until close().")
      .def(py::init([](const std::string& role, std::string name, std::string request_type,
                       std::string response_type) {
             if (role != "server" && role != "client") {
               throw Error("AnnouncedUse role must be 'server' or 'client', not '" + role + "'");
             }
             const auto kind = role == "server" ? detail::ProcessUse::Kind::ServiceServer
                                                : detail::ProcessUse::Kind::ServiceClient;
             return std::make_unique<detail::AnnouncedUse>(detail::ProcessUse{
                 kind, {}, std::move(name), std::move(request_type), std::move(response_type)});
           }),
           py::arg("role"), py::arg("name"), py::arg("request_type"), py::arg("response_type"))
      .def("close", [](detail::AnnouncedUse& use) { use = detail::AnnouncedUse(); });
}

}  // namespace horus::python
