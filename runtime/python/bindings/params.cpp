// horus._core's parameters (runtime/include/horus/params.hpp): the declarations of Python nodes,
// the store's reader, writes through the owner and YAML parameter files, for horus.Params,
// horus.Node.declare_param and the `horus param` command. Values cross as MessagePack VALUE
// bytes; horus/_params.py turns them into Python values.
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <regex>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "bindings.hpp"
#include "horus/node.hpp"
#include "horus/params.hpp"
#include "py_params.hpp"

namespace py = pybind11;

namespace horus::python {

namespace {

std::chrono::nanoseconds timeout_of(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0.0) {
    throw ParamError("a timeout must be a finite number of seconds >= 0, got " +
                     std::to_string(seconds));
  }
  return std::chrono::round<std::chrono::nanoseconds>(std::chrono::duration<double>(seconds));
}

/// The declared type a schema spelling names (an enum's from its description).
void describe_type(ParamDeclaration& declaration, const std::string& spelling,
                   const std::optional<std::string>& enum_description) {
  static const std::regex array(R"(^\[([a-z0-9]+); ([1-9][0-9]*)\]$)");
  std::smatch match;
  if (auto primitive = primitive_named(spelling)) {
    declaration.type = detail::param_type_ref(*primitive);
  } else if (spelling == "String") {
    declaration.type = detail::param_string_type_ref();
  } else if (std::regex_match(spelling, match, array)) {
    auto element = primitive_named(match[1].str());
    if (!element) {
      throw ParamError("parameter '" + declaration.name + "': the elements of " + spelling +
                       " are not numbers or bools (a fixed array holds numbers or bools)");
    }
    declaration.type = detail::param_array_type_ref(*element, std::stoul(match[2].str()));
  } else if (enum_description) {
    auto [type, enumeration] = detail::param_enum_type(*enum_description);
    declaration.type = std::move(type);
    declaration.enumeration = std::move(enumeration);
  } else {
    throw ParamError("parameter '" + declaration.name + "': unknown type '" + spelling +
                     "' (bool, i8..i64, u8..u64, f32, f64, String, [T; N] of numbers or bools, "
                     "or a generated enum class)");
  }
  declaration.spelling = spelling;
}

py::dict info_dict(const ParamInfo& info) {
  const ParamDeclaration& declaration = info.declaration;
  py::list choices;
  for (const std::string& choice : declaration.choices) {
    choices.append(py::bytes(choice));
  }
  py::list enumerators;
  if (declaration.enumeration) {
    for (const Enumerator& enumerator : declaration.enumeration->values) {
      enumerators.append(enumerator.name);
    }
  }
  py::dict found;
  found["node"] = info.node;
  found["name"] = declaration.name;
  found["type"] = declaration.spelling;
  found["value"] = py::bytes(info.value);
  found["version"] = info.version;
  found["default"] = py::bytes(declaration.default_value);
  found["min"] = declaration.min;
  found["max"] = declaration.max;
  found["choices"] = choices;
  found["unit"] = declaration.unit;
  found["doc"] = declaration.doc;
  found["read_only"] = declaration.read_only;
  found["enumerators"] = enumerators;
  return found;
}

std::tuple<bool, std::string, std::uint64_t> result_tuple(const ParamSetResult& result) {
  return {result.accepted, result.reason, result.version};
}

}  // namespace

ParamDeclaration python_param_declaration(std::string name, const std::string& spelling,
                                          const std::string& default_value,
                                          std::optional<double> min, std::optional<double> max,
                                          const std::vector<std::string>& choices, std::string unit,
                                          std::string doc, bool read_only,
                                          const std::optional<std::string>& enum_description) {
  ParamDeclaration declaration;
  declaration.name = std::move(name);
  describe_type(declaration, spelling, enum_description);
  declaration.min = min;
  declaration.max = max;
  declaration.unit = std::move(unit);
  declaration.doc = std::move(doc);
  declaration.read_only = read_only;
  declaration.default_value = default_value;
  declaration.choices = choices;
  return declaration;
}

void bind_params(py::module_& m) {
  static py::exception<ParamError> param_error(m, "ParamError", m.attr("HorusError").ptr());
  // Tried before the translator of every horus::Error (module.cpp), registered earlier.
  py::register_exception_translator([](std::exception_ptr thrown) {
    try {
      if (thrown) std::rethrow_exception(thrown);
    } catch (const ParamError& e) {
      param_error(e.what());
    }
  });

  py::class_<ParamHandle>(m, "ParamHandle", "A Python node's parameter as its C++ node holds it")
      .def("value", [](const ParamHandle& handle) { return py::bytes(handle.value()); })
      .def("version", &ParamHandle::version);

  m.def(
      "check_param_declaration",
      [](std::string name, const std::string& spelling, const std::string& default_value,
         std::optional<double> min, std::optional<double> max,
         const std::vector<std::string>& choices, std::string unit, std::string doc, bool read_only,
         const std::optional<std::string>& enum_description) {
        // The runtime's own checks of a declaration (name, range, choices, size), on a node of
        // its own: a duplicate is found when the node declares it.
        struct Checker final : Node {
          void tick() override {}
          using Node::declare_param;
        };
        Checker().declare_param(
            python_param_declaration(std::move(name), spelling, default_value, min, max, choices,
                                     std::move(unit), std::move(doc), read_only, enum_description));
      },
      py::arg("name"), py::arg("spelling"), py::arg("default"), py::arg("min"), py::arg("max"),
      py::arg("choices"), py::arg("unit"), py::arg("doc"), py::arg("read_only"),
      py::arg("enum_description"));

  py::class_<ParamStoreReader>(m, "ParamStoreReader",
                               "One node's parameter store, read-only (horus.Params)")
      .def(py::init<std::string_view, std::string_view>(), py::arg("node"),
           py::arg("namespace") = "")
      .def("node", &ParamStoreReader::node)
      .def("list",
           [](const ParamStoreReader& reader) {
             py::list found;
             for (const ParamInfo& info : reader.list()) found.append(info_dict(info));
             return found;
           })
      .def("get", [](const ParamStoreReader& reader,
                     std::string_view name) { return info_dict(reader.get(name)); })
      .def("owner_alive", &ParamStoreReader::owner_alive)
      .def("owner_pid", &ParamStoreReader::owner_pid)
      .def("change_count", &ParamStoreReader::change_count)
      .def(
          "wait_for_change",
          [](const ParamStoreReader& reader, std::uint64_t seen, double timeout_s) {
            const auto timeout = timeout_of(timeout_s);
            py::gil_scoped_release release;
            return reader.wait_for_change(seen, timeout);
          },
          py::arg("seen"), py::arg("timeout"));

  m.def(
      "set_param",
      [](const std::string& node, const std::string& name, const std::string& value, bool persist,
         double timeout_s, std::string source, std::string namespace_name) {
        ParamSetOptions options;
        options.persist = persist;
        options.timeout = timeout_of(timeout_s);
        options.source = std::move(source);
        options.namespace_name = std::move(namespace_name);
        // set_param() makes Python's encoding of a value (a float as f64 for an f32, say) the
        // runtime's before it compares or sends it.
        py::gil_scoped_release release;
        return result_tuple(set_param(node, name, value, options));
      },
      py::arg("node"), py::arg("name"), py::arg("value"), py::arg("persist"), py::arg("timeout"),
      py::arg("source"), py::arg("namespace"));

  m.def(
      "param_nodes", [](std::string_view namespace_name) { return param_nodes(namespace_name); },
      py::arg("namespace") = "");
  m.def("param_service_name", [](std::string_view node) { return param_service_name(node); });

  m.def(
      "load_param_file",
      [](const std::string& path, bool persist, double timeout_s, std::string namespace_name) {
        ParamSetOptions options;
        options.persist = persist;
        options.timeout = timeout_of(timeout_s);
        options.namespace_name = std::move(namespace_name);
        std::vector<ParamSetResult> results;
        {
          py::gil_scoped_release release;
          results = load_param_file(path, options);
        }
        std::vector<std::tuple<bool, std::string, std::uint64_t>> found;
        for (const ParamSetResult& result : results) found.push_back(result_tuple(result));
        return found;
      },
      py::arg("path"), py::arg("persist"), py::arg("timeout"), py::arg("namespace"));
  m.def(
      "dump_param_file",
      [](const std::vector<std::string>& nodes, std::string_view namespace_name) {
        return dump_param_file(nodes, namespace_name);
      },
      py::arg("nodes"), py::arg("namespace") = "");
}

}  // namespace horus::python
