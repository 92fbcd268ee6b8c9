// YAML parameter files: `node: {name: value}` per node, read with yaml-cpp and checked against
// the declarations (every problem as FILE:LINE: reason, nothing applied when any is found), and
// the dump that writes the same form back.
#include <yaml-cpp/yaml.h>

#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "../types/msgpack_input.hpp"
#include "horus/internal/param_owner.hpp"
#include "horus/json_string.hpp"
#include "param_internal.hpp"

namespace horus {
namespace detail {
namespace {

using Packer = msgpack::packer<msgpack::sbuffer>;

std::size_t line_of(const YAML::Node& node) {
  return static_cast<std::size_t>(node.Mark().line + 1);
}

bool is_float(Primitive primitive) {
  return primitive == Primitive::F32 || primitive == Primitive::F64;
}

/// Packs one YAML scalar as a value of `primitive` (or of the enum); the reason when it is not.
std::string pack_scalar(msgpack::sbuffer& buffer, Packer& packer,
                        const ParamDeclaration& declaration, const TypeRef& type,
                        const std::string& text) {
  if (type.kind == TypeRef::Kind::Enum || type.kind == TypeRef::Kind::String) {
    packer.pack_str(static_cast<std::uint32_t>(text.size()));
    packer.pack_str_body(text.data(), static_cast<std::uint32_t>(text.size()));
    return {};
  }
  if (type.primitive == Primitive::Bool) {
    if (text == "true" || text == "True" || text == "TRUE") {
      packer.pack_true();
    } else if (text == "false" || text == "False" || text == "FALSE") {
      packer.pack_false();
    } else {
      return "'" + text + "' is not true or false";
    }
    return {};
  }
  if (is_float(type.primitive)) {
    std::string number = text;
    if (number == ".inf" || number == ".Inf" || number == "+.inf") number = "inf";
    if (number == "-.inf" || number == "-.Inf") number = "-inf";
    if (number == ".nan" || number == ".NaN") number = "nan";
    errno = 0;
    char* end = nullptr;
    const double value = std::strtod(number.c_str(), &end);
    if (number.empty() || end != number.c_str() + number.size()) {
      return "'" + text + "' is not a number (" + declaration.spelling + ")";
    }
    pack_float64(buffer, value);
    return {};
  }
  const char* first = text.data();
  const char* last = text.data() + text.size();
  if (!text.empty() && text[0] == '+') ++first;
  if (!text.empty() && text[0] == '-') {
    std::int64_t value = 0;
    const auto parsed = std::from_chars(first, last, value);
    if (parsed.ec != std::errc() || parsed.ptr != last) {
      return "'" + text + "' is not an integer (" + declaration.spelling + ")";
    }
    packer.pack_int64(value);
  } else {
    std::uint64_t value = 0;
    const auto parsed = std::from_chars(first, last, value);
    if (parsed.ec != std::errc() || parsed.ptr != last) {
      return "'" + text + "' is not an integer (" + declaration.spelling + ")";
    }
    packer.pack_uint64(value);
  }
  return {};
}

/// The file value as MessagePack VALUE bytes of the declaration's type; the reason when not.
std::string pack_file_value(const ParamDeclaration& declaration, ParamFileValue& value) {
  msgpack::sbuffer buffer;
  Packer packer(buffer);
  if (declaration.type.kind == TypeRef::Kind::Array) {
    if (!value.list) return "expected a list of " + std::to_string(declaration.type.length);
    packer.pack_array(static_cast<std::uint32_t>(value.items.size()));
    for (const std::string& item : value.items) {
      if (std::string problem =
              pack_scalar(buffer, packer, declaration, *declaration.type.element, item);
          !problem.empty()) {
        return problem;
      }
    }
  } else {
    if (value.list) return "expected one value of " + declaration.spelling + ", not a list";
    if (std::string problem =
            pack_scalar(buffer, packer, declaration, declaration.type, value.items.front());
        !problem.empty()) {
      return problem;
    }
  }
  value.value.assign(buffer.data(), buffer.size());
  return {};
}

std::string yaml_key(const std::string& name) {
  const bool plain = !name.empty() && ((name[0] >= 'a' && name[0] <= 'z') ||
                                       (name[0] >= 'A' && name[0] <= 'Z') || name[0] == '_');
  return plain ? name : json_string(name);  // a JSON string is a YAML double-quoted one
}

}  // namespace

ParamFile read_param_file(const std::filesystem::path& path) {
  ParamFile file;
  file.path = path.string();
  std::ifstream stream(path);
  if (!stream) throw ParamError(file.path + ": cannot read the parameter file");
  std::vector<std::string> problems;
  const auto problem = [&](std::size_t line, const std::string& why) {
    problems.push_back(file.path + ":" + std::to_string(line) + ": " + why);
  };
  YAML::Node top;
  try {
    top = YAML::Load(stream);
  } catch (const YAML::Exception& e) {
    throw ParamError(file.path + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (top.IsNull()) return file;
  if (!top.IsMap()) {
    throw ParamError(file.path + ":" + std::to_string(line_of(top)) +
                     ": expected `node: {parameter: value}` entries");
  }
  for (const auto& node_entry : top) {
    const std::size_t node_line = line_of(node_entry.first);
    if (!node_entry.first.IsScalar()) {
      problem(node_line, "a node's name must be text");
      continue;
    }
    const std::string node = node_entry.first.Scalar();
    if (file.nodes.contains(node)) {
      problem(node_line, "node '" + node + "' appears twice");
      continue;
    }
    file.node_lines[node] = node_line;
    auto& params = file.nodes[node];
    const YAML::Node& values = node_entry.second;
    if (values.IsNull()) continue;
    if (!values.IsMap()) {
      problem(line_of(values), "node '" + node + "': expected `parameter: value` entries");
      continue;
    }
    for (const auto& param_entry : values) {
      const std::size_t line = line_of(param_entry.first);
      if (!param_entry.first.IsScalar()) {
        problem(line, "node '" + node + "': a parameter's name must be text");
        continue;
      }
      const std::string name = param_entry.first.Scalar();
      if (params.contains(name)) {
        problem(line, "node '" + node + "': parameter '" + name + "' appears twice");
        continue;
      }
      ParamFileValue value;
      value.line = line;
      const YAML::Node& given = param_entry.second;
      if (given.IsScalar()) {
        value.items.push_back(given.Scalar());
      } else if (given.IsSequence()) {
        value.list = true;
        bool scalars = true;
        for (const YAML::Node& item : given) {
          scalars = scalars && item.IsScalar();
          if (item.IsScalar()) value.items.push_back(item.Scalar());
        }
        if (!scalars) {
          problem(line, node + "." + name + ": a list of plain values is expected");
          continue;
        }
      } else {
        problem(line, node + "." + name + ": expected a value or a list of values");
        continue;
      }
      params[name] = std::move(value);
    }
  }
  if (!problems.empty()) {
    std::string text;
    for (const std::string& each : problems) text += (text.empty() ? "" : "\n") + each;
    throw ParamError(text);
  }
  return file;
}

std::vector<std::string> param_file_problems(
    ParamFile& file,
    const std::map<std::string, const std::vector<ParamDeclaration>*>& declarations,
    bool known_nodes_only) {
  std::vector<std::string> problems;
  const auto problem = [&](std::size_t line, const std::string& why) {
    problems.push_back(file.path + ":" + std::to_string(line) + ": " + why);
  };
  for (auto& [node, params] : file.nodes) {
    const auto declared = declarations.find(node);
    if (declared == declarations.end()) {
      if (known_nodes_only) {
        problem(file.node_lines[node], "no node '" + node + "' with parameters runs here");
      }
      continue;
    }
    for (auto& [name, value] : params) {
      const ParamDeclaration* declaration = nullptr;
      for (const ParamDeclaration& each : *declared->second) {
        if (each.name == name) declaration = &each;
      }
      if (declaration == nullptr) {
        problem(value.line, "node '" + node + "' has no parameter '" + name + "'");
        continue;
      }
      std::string why = pack_file_value(*declaration, value);
      if (why.empty()) why = param_value_problem(*declaration, value.value);
      if (!why.empty()) problem(value.line, node + "." + name + ": " + why);
    }
  }
  return problems;
}

ParamFileValues read_scheduler_param_file(
    const std::filesystem::path& path,
    const std::map<std::string, const std::vector<ParamDeclaration>*>& declarations) {
  ParamFile file = read_param_file(path);
  const std::vector<std::string> problems = param_file_problems(file, declarations, true);
  if (!problems.empty()) {
    std::string text;
    for (const std::string& each : problems) text += (text.empty() ? "" : "\n") + each;
    throw ParamError(text);
  }
  ParamFileValues values;
  for (const auto& [node, params] : file.nodes) {
    for (const auto& [name, value] : params) values[node][name] = value.value;
  }
  return values;
}

}  // namespace detail

std::vector<ParamSetResult> load_param_file(const std::filesystem::path& path,
                                            const ParamSetOptions& options) {
  detail::ParamFile file = detail::read_param_file(path);
  std::map<std::string, ParamStoreReader> readers;
  std::map<std::string, std::vector<ParamDeclaration>> declared;
  std::vector<std::string> problems;
  for (const auto& [node, params] : file.nodes) {
    try {
      ParamStoreReader reader(node, options.namespace_name);
      std::vector<ParamDeclaration>& list = declared[node];
      for (ParamInfo& info : reader.list()) list.push_back(std::move(info.declaration));
      readers.emplace(node, std::move(reader));
    } catch (const Error& e) {
      problems.push_back(file.path + ":" + std::to_string(file.node_lines[node]) + ": " + e.what());
    }
  }
  std::map<std::string, const std::vector<ParamDeclaration>*> views;
  for (const auto& [node, list] : declared) views[node] = &list;
  for (std::string& each : detail::param_file_problems(file, views, false)) {
    problems.push_back(std::move(each));
  }
  // A value the node holds already is not written again (a dump loads back without moving a
  // version), and a read-only one that would change is refused before anything is written.
  std::map<std::pair<std::string, std::string>, std::uint64_t> unchanged;
  if (problems.empty()) {
    for (const auto& [node, params] : file.nodes) {
      const ParamStoreReader& reader = readers.at(node);
      for (const auto& [name, value] : params) {
        const ParamInfo current = reader.get(name);
        if (detail::canonical_param_value(current.declaration, current.value) ==
            detail::canonical_param_value(current.declaration, value.value)) {
          unchanged[{node, name}] = current.version;
        } else if (current.declaration.read_only && reader.owner_alive()) {
          problems.push_back(file.path + ":" + std::to_string(value.line) + ": parameter '" + name +
                             "' is read-only while node " + node + " runs");
        }
      }
    }
  }
  if (!problems.empty()) {
    std::string text;
    for (const std::string& each : problems) text += (text.empty() ? "" : "\n") + each;
    throw ParamError(text);
  }
  ParamSetOptions write = options;
  if (write.source.empty()) write.source = "yaml:" + file.path;
  std::vector<ParamSetResult> results;
  for (const auto& [node, params] : file.nodes) {
    for (const auto& [name, value] : params) {
      if (const auto same = unchanged.find({node, name}); same != unchanged.end()) {
        results.push_back(ParamSetResult{true, {}, same->second});
        continue;
      }
      ParamSetResult result = set_param(node, name, value.value, write);
      if (!result.accepted) {
        result.reason = file.path + ":" + std::to_string(value.line) + ": " + result.reason;
      }
      results.push_back(std::move(result));
    }
  }
  return results;
}

std::string dump_param_file(const std::vector<std::string>& nodes,
                            std::string_view namespace_name) {
  const std::vector<std::string> chosen = nodes.empty() ? param_nodes(namespace_name) : nodes;
  std::string out = "# horus param dump\n";
  for (const std::string& node : chosen) {
    const ParamStoreReader reader(node, namespace_name);
    out += detail::yaml_key(node) + ":";
    const std::vector<ParamInfo> params = reader.list();
    if (params.empty()) out += " {}";
    out += "\n";
    for (const ParamInfo& info : params) {
      out += "  " + info.declaration.name + ": ";
      const msgpack::object_handle handle = types::unpack_whole<ParamError>(
          info.value.data(), info.value.size(), "parameter '" + info.declaration.name + "'");
      const TypeRef& type = info.declaration.type.kind == TypeRef::Kind::Array
                                ? *info.declaration.type.element
                                : info.declaration.type;
      if (info.declaration.type.kind == TypeRef::Kind::Enum) {
        const msgpack::object& name = handle.get();
        out += std::string(name.via.str.ptr, name.via.str.size);
      } else {
        detail::append_param_value_text(out, handle.get(), type.primitive == Primitive::F32, true);
      }
      out += "\n";
    }
  }
  return out;
}

}  // namespace horus
