// horus._core.Topic: a RawTopic for the `horus.Topic` class, which turns bytes into messages.
#include <pybind11/stl.h>

#include <chrono>
#include <memory>

#include "bindings.hpp"
#include "horus/error.hpp"
#include "horus/raw_topic.hpp"
#include "horus/topic_log.hpp"
#include "horus/topic_registry.hpp"

namespace py = pybind11;

namespace horus::python {

namespace {

std::span<const std::byte> bytes_of(const py::buffer_info& info) {
  return {static_cast<const std::byte*>(info.ptr),
          static_cast<std::size_t>(info.size * info.itemsize)};
}

py::object received_bytes(RawTopic& topic, std::ptrdiff_t size) {
  if (size < 0) {
    return py::none();
  }
  const auto bytes = topic.received(static_cast<std::size_t>(size));
  return py::bytes(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

py::object received_view(RawTopic& topic, std::ptrdiff_t size) {
  if (size < 0) {
    return py::none();
  }
  const auto bytes = topic.received(static_cast<std::size_t>(size));
  return py::memoryview::from_memory(static_cast<void*>(bytes.data()),
                                     static_cast<py::ssize_t>(bytes.size()), false);
}

}  // namespace

void bind_topics(py::module_& m) {
  py::class_<RawTopic>(m, "Topic", "A type-erased topic handle: bytes in, bytes (or a view) out.")
      .def(py::init([](std::string name, std::string type_name, std::uint64_t fingerprint,
                       std::string schema, bool is_pod, std::size_t size, std::size_t alignment,
                       std::size_t capacity, std::size_t max_message_size, bool single_publisher,
                       const py::bytes& description) {
             TopicOptions options;
             options.capacity = capacity;
             options.max_message_size = max_message_size;
             options.single_publisher = single_publisher;
             return std::make_unique<RawTopic>(
                 std::move(name),
                 TypeIdentity{std::move(type_name), fingerprint, std::move(schema), is_pod, size,
                              alignment, std::string(description)},
                 options);
           }),
           py::arg("name"), py::arg("type_name"), py::arg("fingerprint"), py::arg("schema"),
           py::arg("is_pod"), py::arg("size"), py::arg("alignment"), py::arg("capacity"),
           py::arg("max_message_size"), py::arg("single_publisher"),
           py::arg("description") = py::bytes())
      .def_property_readonly("name", &RawTopic::name)
      .def(
          "send",
          [](RawTopic& topic, const py::buffer& data) {
            const py::buffer_info info = data.request();
            return topic.send(bytes_of(info));
          },
          py::arg("data"))
      .def(
          "try_recv",
          [](RawTopic& topic, bool view) {
            const std::ptrdiff_t size = topic.try_recv();
            return view ? received_view(topic, size) : received_bytes(topic, size);
          },
          py::arg("view") = false)
      .def(
          "recv",
          [](RawTopic& topic, double timeout_s, bool view) {
            std::ptrdiff_t size = 0;
            {
              py::gil_scoped_release released;
              size = topic.recv(std::chrono::duration_cast<std::chrono::nanoseconds>(
                  std::chrono::duration<double>(timeout_s)));
            }
            return view ? received_view(topic, size) : received_bytes(topic, size);
          },
          py::arg("timeout"), py::arg("view") = false)
      .def("read_latest",
           [](RawTopic& topic) { return received_bytes(topic, topic.read_latest()); })
      .def("has_msg", &RawTopic::has_msg)
      .def("loan",
           [](RawTopic& topic) {
             if (!topic.type().is_pod) {
               throw Error("topic '" + topic.name() + "' carries " + topic.type().name +
                           ", a serialized type: only POD messages can be written in place");
             }
             std::byte* payload = topic.loan();
             return py::memoryview::from_memory(static_cast<void*>(payload),
                                                static_cast<py::ssize_t>(topic.type().size), false);
           })
      .def("publish", &RawTopic::publish)
      .def("release_loan", &RawTopic::release_loan)
      .def_property_readonly("loaned", &RawTopic::loaned)
      .def("lost", [](const RawTopic& topic) { return topic.stats().lost; })
      .def("stats",
           [](const RawTopic& topic) {
             const TopicStats stats = topic.stats();
             py::dict out;
             out["lost"] = stats.lost;
             out["send_failures"] = stats.send_failures;
             out["oversized"] = stats.oversized;
             out["not_the_publisher"] = stats.not_the_publisher;
             out["invalid"] = stats.invalid;
             return out;
           })
      .def_property_readonly("capacity", &RawTopic::capacity)
      .def_property_readonly("payload_capacity", &RawTopic::payload_capacity);

  // A verbose horus.Topic's log lines: the same limiter and line as a C++ Topic's, with the
  // summary made in Python (log_summary(), or the plain value's) only once admit() said yes.
  py::class_<TopicLog>(m, "TopicLog", "The rate-limited log lines of one verbose topic handle.")
      .def(py::init<std::string_view>(), py::arg("topic"))
      .def("admit", &TopicLog::admit,
           "Whether one more message may have its line now; if not, it is counted suppressed.")
      .def(
          "write",
          [](TopicLog& log, bool sent, std::string_view summary) {
            log.write(sent ? TopicLogDirection::Send : TopicLogDirection::Recv,
                      summary.substr(0, TopicLog::kMaxSummary));
          },
          py::arg("sent"), py::arg("summary"));

  m.def(
      "list_topics",
      [](const std::string& namespace_name) {
        py::list out;
        for (const TopicInfo& info : list_topics(namespace_name)) {
          py::dict topic;
          topic["name"] = info.name;
          topic["type_name"] = info.type_name;
          topic["fingerprint"] = info.fingerprint;
          topic["is_pod"] = info.is_pod;
          topic["publishers"] = info.publishers;
          topic["subscribers"] = info.subscribers;
          topic["user_pids"] = info.user_pids;
          topic["message_count"] = info.message_count;
          topic["schema"] = info.schema;
          topic["description"] = py::bytes(info.description);
          topic["capacity"] = info.capacity;
          topic["max_message_size"] = info.max_message_size;
          topic["single_publisher"] = info.single_publisher;
          topic["last_send_s"] =
              info.last_send ? py::object(py::int_(std::chrono::duration_cast<std::chrono::seconds>(
                                                       info.last_send->time_since_epoch())
                                                       .count()))
                             : py::object(py::none());
          topic["error"] = info.error;
          out.append(topic);
        }
        return out;
      },
      py::arg("namespace_name") = "",
      "The topics of a namespace (empty: HORUS_NAMESPACE), with their users.");
  m.def(
      "remove_created_topics_nobody_uses",
      [] {
        py::gil_scoped_release released;
        return remove_created_topics_nobody_uses();
      },
      "Removes the topic segments this process created that no live process has open any more "
      "(what a C++ Scheduler does when it is destroyed); returns how many.");
  m.def("current_namespace", [] { return current_namespace(); });
  m.def(
      "namespace_directory",
      [](const std::string& namespace_name) { return namespace_directory(namespace_name); },
      py::arg("namespace_name") = "", "The folder holding a namespace's topic segments.");
}

}  // namespace horus::python
