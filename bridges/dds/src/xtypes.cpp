#include "horus/dds/xtypes.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <vector>

extern char** environ;

namespace horus::dds_bridge {
namespace {

// OMG IDL 4.2's keywords and the names idlc also reserves (lang/idl.py IDL_KEYWORDS), lowercase.
const std::set<std::string>& idl_keywords() {
  static const std::set<std::string> words = [] {
    std::istringstream text(
        "abstract any alias attribute bitfield bitmask bitset boolean case char component "
        "connector const consumes context custom default double exception emits enum eventtype "
        "factory false finder fixed float getraises getter home import in inout interface local "
        "long manages map mirrorport module multiple native object octet oneway out primarykey "
        "private port porttype provides public publishes raises readonly setraises setter "
        "sequence short string struct supports switch true truncatable typedef typeid typename "
        "typeprefix unsigned union uses valuebase valuetype void wchar wstring int8 uint8 int16 "
        "int32 int64 uint16 uint32 uint64");
    std::set<std::string> out;
    for (std::string word; text >> word;) {
      out.insert(word);
    }
    return out;
  }();
  return words;
}

std::string lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// A HORUS name as an IDL identifier: a keyword gets a trailing underscore, a leading underscore
// is doubled (IDL drops one).
std::string identifier(std::string name) {
  if (idl_keywords().contains(lower(name))) {
    name += "_";
  }
  return name.starts_with('_') ? "_" + name : name;
}

// The identifiers of one scope, IDL comparing them without case: a collision gets trailing
// underscores until it is unique.
std::vector<std::string> unique(const std::vector<std::string>& names,
                                const std::set<std::string>& taken) {
  std::set<std::string> seen;
  for (const std::string& name : taken) {
    seen.insert(lower(name));
  }
  std::vector<std::string> out;
  for (std::string name : names) {
    while (seen.contains(lower(name))) {
      name += "_";
    }
    seen.insert(lower(name));
    out.push_back(std::move(name));
  }
  return out;
}

std::vector<std::string> split_package(const std::string& package) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t dot = package.find('.', start);
    out.push_back(package.substr(start, dot - start));
    if (dot == std::string::npos) {
      return out;
    }
    start = dot + 1;
  }
}

// A type without a package is a plain value (`f32`, `[f32; 3]`, `Vec<u8>`, `String`: the
// message its description makes of it): its IDL lives in the module horus::plain.
constexpr std::string_view kPlainValuePackage = "horus.plain";

std::vector<std::string> modules(const std::string& package) {
  std::vector<std::string> out;
  for (const std::string& segment :
       split_package(package.empty() ? std::string(kPlainValuePackage) : package)) {
    out.push_back(identifier(segment));
  }
  out.emplace_back("dds_");
  return out;
}

// A plain value's name as an identifier: each run of characters IDL does not allow in one is an
// underscore (`[f32; 3]` is f32_3, `Vec<u8>` Vec_u8), none at either end.
std::string identifier_of_plain_value(const std::string& name) {
  std::string out;
  for (const char c : name) {
    if (std::isalnum(static_cast<unsigned char>(c)) != 0) {
      out += c;
    } else if (!out.empty() && out.back() != '_') {
      out += '_';
    }
  }
  while (!out.empty() && out.back() == '_') {
    out.pop_back();
  }
  return out;
}

std::string short_name(const std::string& qualified, const std::string& package) {
  return package.empty() ? identifier_of_plain_value(qualified)
                         : qualified.substr(package.size() + 1);
}

std::string scoped(const std::string& qualified, const std::string& package) {
  std::string out;
  for (const std::string& module : modules(package)) {
    out += "::" + module;
  }
  return out + "::" + identifier(short_name(qualified, package) + "_");
}

std::string primitive_idl(Primitive primitive) {
  switch (primitive) {
    case Primitive::Bool:
      return "boolean";
    case Primitive::U8:
      return "uint8";
    case Primitive::U16:
      return "uint16";
    case Primitive::U32:
      return "uint32";
    case Primitive::U64:
      return "uint64";
    case Primitive::I8:
      return "int8";
    case Primitive::I16:
      return "int16";
    case Primitive::I32:
      return "int32";
    case Primitive::I64:
      return "int64";
    case Primitive::F32:
      return "float";
    case Primitive::F64:
      return "double";
  }
  return "uint8";
}

struct Typedef {
  std::string spec;
  std::string name;
  std::string dims;
};

std::string add_typedef(std::vector<Typedef>& typedefs, const std::string& prefix,
                        const std::string& spec, const std::string& dims) {
  std::set<std::string> taken;
  for (const Typedef& t : typedefs) {
    taken.insert(lower(t.name));
  }
  std::string name = prefix;
  for (int count = 2; taken.contains(lower(name)); ++count) {
    name = prefix + "_" + std::to_string(count);
  }
  typedefs.push_back(Typedef{spec, name, dims});
  return name;
}

// A type as (spec, array dimensions); an array inside sequence<> gets a typedef named after
// `prefix` (IDL has no anonymous array types there).
std::pair<std::string, std::string> spell(const TypeDescription& description, const TypeRef& type,
                                          std::vector<Typedef>& typedefs,
                                          const std::string& prefix) {
  switch (type.kind) {
    case TypeRef::Kind::Primitive:
      return {primitive_idl(type.primitive), ""};
    case TypeRef::Kind::FixedString:
      return {"string<" + std::to_string(type.length) + ">", ""};
    case TypeRef::Kind::String:
      return {"string", ""};
    case TypeRef::Kind::Bytes:
      return {"sequence<uint8>", ""};
    case TypeRef::Kind::Array: {
      auto [spec, dims] = spell(description, *type.element, typedefs, prefix);
      return {spec, "[" + std::to_string(type.length) + "]" + dims};
    }
    case TypeRef::Kind::Vec:
    case TypeRef::Kind::Optional: {
      auto [spec, dims] = spell(description, *type.element, typedefs, prefix);
      if (!dims.empty()) {
        if (spec.starts_with("sequence<")) {
          // idlc 0.10's C names an array typedef's anonymous sequence wrongly: name it first.
          spec = add_typedef(typedefs, prefix, spec, "");
        }
        spec = add_typedef(typedefs, prefix, spec, dims);
      }
      // ", 1": Option; a space keeps `> >` from reading as the shift operator `>>`.
      const std::string bound = type.kind == TypeRef::Kind::Optional ? ", 1"
                                : spec.ends_with('>')                ? " "
                                                                     : "";
      return {"sequence<" + spec + bound + ">", ""};
    }
    case TypeRef::Kind::Message: {
      const MessageType& message = description.message(type);
      return {scoped(message.name, message.package), ""};
    }
    case TypeRef::Kind::Enum: {
      const EnumType& enumeration = description.enumeration(type);
      return {scoped(enumeration.name, enumeration.package), ""};
    }
  }
  throw std::invalid_argument("a type the IDL has no spelling for");
}

constexpr std::string_view kPoolBlock = "horus.msg.PoolBlock";

void open_modules(std::string& out, const std::string& package) {
  for (const std::string& module : modules(package)) {
    out += "module " + module + " {\n";
  }
}

void close_modules(std::string& out, const std::string& package) {
  for (std::size_t i = 0; i < modules(package).size(); ++i) {
    out += "};\n";
  }
}

void struct_idl(std::string& out, const TypeDescription& description, const MessageType& type) {
  const std::string base = short_name(type.name, type.package);
  const std::string name = identifier(base + "_");
  std::vector<std::string> wanted;
  for (const MessageField& field : type.fields) {
    const bool pool = field.type.kind == TypeRef::Kind::Message && field.type.name == kPoolBlock;
    wanted.push_back(pool ? "data" : identifier(field.name));
  }
  const std::vector<std::string> members = unique(wanted, {name});
  std::vector<Typedef> typedefs;
  std::string body;
  for (std::size_t i = 0; i < type.fields.size(); ++i) {
    const MessageField& field = type.fields[i];
    if (field.type.kind == TypeRef::Kind::Message && field.type.name == kPoolBlock) {
      body += "  sequence<uint8> " + members[i] + ";\n";
      continue;
    }
    const auto [spec, dims] =
        spell(description, field.type, typedefs, identifier(base + "__" + field.name));
    body += "  " + spec + " " + members[i] + dims + ";\n";
  }
  if (type.fields.empty()) {
    body += "  uint8 structure_needs_at_least_one_member;\n";
  }
  open_modules(out, type.package);
  for (const Typedef& t : typedefs) {
    out += "typedef " + t.spec + " " + t.name + t.dims + ";\n";
  }
  out += "@final\nstruct " + name + " {\n" + body + "};\n";
  close_modules(out, type.package);
}

// Runs `arguments` (the program looked up on PATH) with its output to `log`; its exit status, or
// throws naming the program when it cannot run.
int run(const std::vector<std::string>& arguments, const std::filesystem::path& log) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  std::vector<char*> argv;
  for (const std::string& argument : arguments) {
    argv.push_back(const_cast<char*>(argument.c_str()));
  }
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int failed = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (failed != 0) {
    throw std::runtime_error(std::strerror(failed));
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Removes its folder (and what idlc wrote there) however the conversion ends.
struct TemporaryFolder {
  std::filesystem::path path;
  TemporaryFolder() {
    std::string pattern = (std::filesystem::temp_directory_path() / "horus-bridge-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) {
      throw std::runtime_error(std::string("cannot make a temporary folder: ") +
                               std::strerror(errno));
    }
    path = pattern;
  }
  ~TemporaryFolder() {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
  TemporaryFolder(const TemporaryFolder&) = delete;
  TemporaryFolder& operator=(const TemporaryFolder&) = delete;
};

std::string bytes_of_define(const std::string& c_text, const std::string& macro,
                            const std::string& dds_type) {
  const std::string head = "#define " + macro + " (unsigned char []){";
  const std::size_t start = c_text.find(head);
  const std::size_t end = start == std::string::npos ? start : c_text.find('}', start);
  if (end == std::string::npos) {
    throw std::runtime_error("idlc gave no " + macro + " for " + dds_type);
  }
  std::string out;
  static const std::regex byte("0x([0-9a-f]{2})");
  const std::string values = c_text.substr(start + head.size(), end - start - head.size());
  for (auto it = std::sregex_iterator(values.begin(), values.end(), byte);
       it != std::sregex_iterator(); ++it) {
    out += static_cast<char>(std::stoi((*it)[1].str(), nullptr, 16));
  }
  return out;
}

}  // namespace

std::string dds_type_name(const TypeDescription& /*description*/, const MessageType& type) {
  // The scoped name without its leading "::", each part's escaping underscore dropped as IDL
  // drops it.
  const std::string full = scoped(type.name, type.package).substr(2);
  std::string out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = full.find("::", start);
    std::string part = full.substr(start, end - start);
    if (part.starts_with('_')) {
      part.erase(0, 1);
    }
    out += (out.empty() ? "" : "::") + part;
    if (end == std::string::npos) {
      return out;
    }
    start = end + 2;
  }
}

std::string idl_of(const TypeDescription& description) {
  std::string out;
  for (const EnumType& enumeration : description.enums) {
    open_modules(out, enumeration.package);
    out += "typedef " + primitive_idl(enumeration.underlying) + " " +
           identifier(short_name(enumeration.name, enumeration.package) + "_") + ";\n";
    close_modules(out, enumeration.package);
  }
  for (const MessageType& message : description.messages) {
    struct_idl(out, description, message);
  }
  return out;
}

namespace {

// The type information of `dds_type` from the C idlc makes of `idl` (with `-I include`, when
// given) in `folder`; `c_file` is that C's name.
TypeOnWire idlc_type_on_wire(const std::string& dds_type, const std::filesystem::path& folder,
                             const std::filesystem::path& idl, const std::string& include,
                             const std::string& c_file) {
  const std::filesystem::path log = folder / "idlc.log";
  std::vector<std::string> arguments{"idlc", "-o", folder.string()};
  if (!include.empty()) {
    arguments.insert(arguments.end(), {"-I", include});
  }
  arguments.push_back(idl.string());
  int status = 0;
  try {
    status = run(arguments, log);
  } catch (const std::runtime_error& error) {
    throw std::runtime_error(
        "cannot run idlc (Cyclone DDS's IDL compiler, Debian's cyclonedds-tools), which gives "
        "the bridge the XTypes type information of " +
        dds_type + ": " + error.what());
  }
  if (status != 0) {
    std::string first = read_text(log);
    first = first.substr(0, first.find('\n'));
    throw std::runtime_error("idlc refuses the IDL of " + dds_type + ": " +
                             (first.empty() ? "(no message)" : first));
  }
  const std::string c_text = read_text(folder / c_file);
  std::string mangled = dds_type;
  for (std::size_t at = mangled.find("::"); at != std::string::npos; at = mangled.find("::")) {
    mangled.replace(at, 2, "_");
  }
  return TypeOnWire{dds_type, bytes_of_define(c_text, "TYPE_INFO_CDR_" + mangled, dds_type),
                    bytes_of_define(c_text, "TYPE_MAP_CDR_" + mangled, dds_type)};
}

}  // namespace

TypeOnWire type_on_wire(const TypeDescription& description, const MessageType& type) {
  const TemporaryFolder folder;
  const std::filesystem::path idl = folder.path / "types.idl";
  std::ofstream(idl) << idl_of(description);
  return idlc_type_on_wire(dds_type_name(description, type), folder.path, idl, "", "types.c");
}

TypeOnWire ros2_type_on_wire(std::string_view ros2_type) {
  // geometry_msgs/msg/Twist: geometry_msgs::msg::dds_::Twist_ in geometry_msgs/msg/Twist.idl.
  const std::size_t last = ros2_type.rfind('/');
  const std::string name(ros2_type.substr(last + 1));
  std::string dds_type(ros2_type.substr(0, last));
  for (std::size_t at = dds_type.find('/'); at != std::string::npos; at = dds_type.find('/')) {
    dds_type.replace(at, 1, "::");
  }
  dds_type += "::dds_::" + name + "_";
  const TemporaryFolder folder;
  const std::filesystem::path root = folder.path / "idl";
  for (const Ros2IdlFile& file : ros2_idl_files()) {
    const std::filesystem::path path = root / file.path;
    std::filesystem::create_directories(path.parent_path());
    std::ofstream(path) << file.text;
  }
  return idlc_type_on_wire(dds_type, folder.path, root / (std::string(ros2_type) + ".idl"),
                           root.string(), name + ".c");
}

}  // namespace horus::dds_bridge
