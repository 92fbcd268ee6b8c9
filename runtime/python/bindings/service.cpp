// horus._core.ServiceClient / ServiceServer: horus/raw_service.hpp for horus.ServiceClient and
// horus.ServiceServer, which turn bytes into messages. A service is the generated Python class
// (name, topics, fingerprint, Request, Response); failures come back as the names of
// horus::ServiceErrorKind, which _service.py turns into its exceptions.
#include <pybind11/stl.h>

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "bindings.hpp"
#include "horus/error.hpp"
#include "horus/raw_service.hpp"

namespace py = pybind11;

namespace horus::python {

namespace {

std::chrono::nanoseconds seconds(double value) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::duration<double>(value));
}

/// The identity of a generated message class, from its `__horus__`.
TypeIdentity identity_of(const py::handle& message_class) {
  const py::object meta = message_class.attr("__horus__");
  TypeIdentity type;
  type.name = meta.attr("name").cast<std::string>();
  type.fingerprint = meta.attr("fingerprint").cast<std::uint64_t>();
  type.schema = meta.attr("schema").cast<std::string>();
  type.is_pod = meta.attr("is_pod").cast<bool>();
  if (type.is_pod) {
    type.size = meta.attr("size").cast<std::size_t>();
    type.alignment = meta.attr("alignment").cast<std::size_t>();
  }
  type.description = meta.attr("description").cast<std::string>();
  return type;
}

std::vector<std::byte> to_vector(const py::bytes& data) {
  const std::string_view view(data);
  const auto* first = reinterpret_cast<const std::byte*>(view.data());
  return {first, first + view.size()};
}

std::span<const std::byte> bytes_of(std::string_view view) {
  return {reinterpret_cast<const std::byte*>(view.data()), view.size()};
}

py::bytes to_bytes(std::span<const std::byte> data) {
  return {reinterpret_cast<const char*>(data.data()), data.size()};
}

/// What a generated service class says about itself, with the encodings of its empty messages.
RawServiceType raw_type_of(const py::handle& service) {
  const py::object request = service.attr("Request");
  const py::object response = service.attr("Response");
  return {service.attr("name").cast<std::string>(),
          service.attr("request_topic").cast<std::string>(),
          service.attr("response_topic").cast<std::string>(),
          service.attr("fingerprint").cast<std::uint64_t>(),
          identity_of(request),
          identity_of(response),
          to_vector(request().attr("to_bytes")()),
          to_vector(response().attr("to_bytes")())};
}

/// The error of a kind named as horus::to_string(ServiceErrorKind) names it.
ServiceError error_of(std::string_view kind, std::string text) {
  if (kind == to_string(ServiceErrorKind::ServiceFailed)) {
    return ServiceError::service_failed(std::move(text));
  }
  if (kind == to_string(ServiceErrorKind::NoServer))
    return ServiceError::no_server(std::move(text));
  if (kind == to_string(ServiceErrorKind::Timeout)) return ServiceError::timeout(std::move(text));
  if (kind == to_string(ServiceErrorKind::Transport))
    return ServiceError::transport(std::move(text));
  throw Error("a service failure is ServiceFailed, NoServer, Timeout or Transport, not '" +
              std::string(kind) + "'");
}

/// (None, response bytes) or (the kind's name, the error's text).
py::tuple outcome_of(ServiceResult<std::vector<std::byte>>&& result) {
  if (result) {
    return py::make_tuple(py::none(), to_bytes(*result));
  }
  return py::make_tuple(std::string(to_string(result.error().kind())), result.error().message());
}

}  // namespace

void bind_services(py::module_& m) {
  py::class_<ServiceCaller>(m, "ServiceCaller", "Who sent a request, and where its answer goes.")
      .def(py::init([](std::uint64_t client_id, std::uint64_t request_id, std::uint64_t reply_to) {
             return ServiceCaller{client_id, request_id, reply_to};
           }),
           py::arg("client_id"), py::arg("request_id"), py::arg("reply_to"))
      .def_readonly("client_id", &ServiceCaller::client_id)
      .def_readonly("request_id", &ServiceCaller::request_id)
      .def_readonly("reply_to", &ServiceCaller::reply_to);

  py::class_<RawServiceClient>(m, "ServiceClient",
                               "Calls a generated service with bytes (horus::RawServiceClient).")
      .def(py::init([](const py::object& service) {
             RawServiceType type = raw_type_of(service);
             py::gil_scoped_release released;
             return std::make_unique<RawServiceClient>(std::move(type));
           }),
           py::arg("service"))
      .def(
          "call",
          [](RawServiceClient& client, const py::bytes& request, double timeout_s) {
            const std::string_view data(request);
            ServiceResult<std::vector<std::byte>> result = ServiceError::timeout();
            {
              py::gil_scoped_release released;
              result = client.call(bytes_of(data), seconds(timeout_s));
            }
            return outcome_of(std::move(result));
          },
          py::arg("request"), py::arg("timeout"),
          "(None, the response's bytes) or (the failure's kind, its text).")
      .def(
          "wait_for_server",
          [](RawServiceClient& client, double timeout_s) {
            py::gil_scoped_release released;
            return client.wait_for_server(seconds(timeout_s));
          },
          py::arg("timeout"))
      .def_property_readonly("client_id", &RawServiceClient::client_id);

  py::class_<RawServiceServer>(
      m, "ServiceServer",
      "Serves a generated service with bytes (horus::RawServiceServer); registers on creation.")
      .def(py::init([](const py::object& service) {
             RawServiceType type = raw_type_of(service);
             py::gil_scoped_release released;
             return std::make_unique<RawServiceServer>(std::move(type));
           }),
           py::arg("service"))
      .def(
          "next",
          [](RawServiceServer& server, double timeout_s) -> py::object {
            std::optional<RawServiceServer::Request> request;
            {
              py::gil_scoped_release released;
              request = server.next(seconds(timeout_s));
            }
            if (!request) return py::none();
            return py::make_tuple(request->caller, to_bytes(request->payload));
          },
          py::arg("timeout"), "(caller, the request's bytes), or None.")
      .def(
          "answer",
          [](RawServiceServer& server, const ServiceCaller& caller, const py::bytes& response) {
            const std::string_view data(response);
            py::gil_scoped_release released;
            return server.answer(caller, bytes_of(data));
          },
          py::arg("caller"), py::arg("response"))
      .def(
          "fail",
          [](RawServiceServer& server, const ServiceCaller& caller, std::string_view kind,
             std::string text) {
            const ServiceError failure = error_of(kind, std::move(text));
            py::gil_scoped_release released;
            return server.fail(caller, failure);
          },
          py::arg("caller"), py::arg("kind"), py::arg("text"))
      .def("stop", &RawServiceServer::stop)
      .def("withdraw", &RawServiceServer::withdraw)
      .def_property_readonly("stopped", &RawServiceServer::stopped)
      .def_property_readonly("instance", &RawServiceServer::instance);

  // For tools that read and write frames themselves (`horus service call`, recordings).
  py::class_<ServiceFrameCodec>(m, "ServiceFrameCodec",
                                "The request or response frames of a generated message class.")
      .def(py::init([](const py::object& message_class, bool response) {
             return std::make_unique<ServiceFrameCodec>(identity_of(message_class), response);
           }),
           py::arg("message_class"), py::arg("response"))
      .def_property_readonly("name", [](const ServiceFrameCodec& c) { return c.frame_type().name; })
      .def_property_readonly("fingerprint",
                             [](const ServiceFrameCodec& c) { return c.frame_type().fingerprint; })
      .def_property_readonly("schema",
                             [](const ServiceFrameCodec& c) { return c.frame_type().schema; })
      .def_property_readonly("is_pod",
                             [](const ServiceFrameCodec& c) { return c.frame_type().is_pod; })
      .def_property_readonly("size", [](const ServiceFrameCodec& c) { return c.frame_type().size; })
      .def_property_readonly("alignment",
                             [](const ServiceFrameCodec& c) { return c.frame_type().alignment; })
      .def_property_readonly(
          "description",
          [](const ServiceFrameCodec& c) { return py::bytes(c.frame_type().description); })
      .def(
          "request",
          [](const ServiceFrameCodec& codec, const ServiceCaller& caller,
             const py::bytes& payload) {
            return to_bytes(codec.request(caller, bytes_of(std::string_view(payload))));
          },
          py::arg("caller"), py::arg("payload"))
      .def(
          "read_request",
          [](const ServiceFrameCodec& codec, const py::bytes& frame) -> py::object {
            const std::optional<RawRequestFrame> read =
                codec.read_request(bytes_of(std::string_view(frame)));
            if (!read) return py::none();
            return py::make_tuple(read->caller, to_bytes(read->payload));
          },
          py::arg("frame"), "(caller, payload bytes), or None when the bytes are not a frame.")
      .def(
          "read_response",
          [](const ServiceFrameCodec& codec, const py::bytes& frame) -> py::object {
            const std::optional<RawResponseFrame> read =
                codec.read_response(bytes_of(std::string_view(frame)));
            if (!read) return py::none();
            py::object kind = py::none();
            std::string text;
            if (read->failure) {
              kind = py::str(std::string(to_string(read->failure->kind())));
              text = read->failure->message();
            }
            return py::make_tuple(read->client_id, read->request_id, read->status, kind, text,
                                  to_bytes(read->payload));
          },
          py::arg("frame"),
          "(client_id, request_id, status, failure kind or None, error text, payload bytes), or "
          "None when the bytes are not a frame.");

  py::class_<ServiceRegistrationTopic>(m, "ServiceRegistrationTopic",
                                       "A service's `<Service>.service` topic.")
      .def(py::init<std::string_view>(), py::arg("service"))
      .def("latest", [](const ServiceRegistrationTopic& topic) -> py::object {
        const std::optional<ServiceRegistration> current = topic.latest();
        if (!current) return py::none();
        py::dict out;
        out["server_instance"] = current->server_instance;
        out["fingerprint"] = current->fingerprint;
        out["request_type"] = current->request_type.str();
        out["response_type"] = current->response_type.str();
        out["server_pid"] = current->server_pid;
        return out;
      });

  m.def("new_service_endpoint_id", &new_service_endpoint_id,
        "A non-zero client or server id, unique among the machine's live processes.");
  m.def("service_server_gone", &service_server_gone, py::arg("pid"),
        "Whether a registered server's process has exited (or is a zombie).");
}

}  // namespace horus::python
