"""C++: keywords, and the spelling of the model (type names, literals, include lists, file paths)."""
from __future__ import annotations

import json
import os
import struct

from .. import description, identity
from ..data import DataPaths
from ..model import (PRIMITIVES, Action, Bytes, DynString, Enum, EnumRef, EnumValue, FailurePolicy, Field, FixedArray,
                     FixedString, Message, MessageRef, Model, Node, NodeParam, Optional, Primitive, Service, SummaryExpr,
                     SummaryPart, Type, Vec)
from ..names import snake_case
from ..summary import printed_types
from .common import CONTRACT_VERSION, banner, environment

DISPLAY_NAME = "C++"

KEYWORDS = frozenset("""
alignas alignof and and_eq asm auto bitand bitor bool break case catch char char8_t char16_t
char32_t class compl concept const consteval constexpr constinit const_cast continue co_await
co_return co_yield decltype default delete do double dynamic_cast else enum explicit export extern
false float for friend goto if inline int long mutable namespace new noexcept not not_eq nullptr
operator or or_eq private protected public register reinterpret_cast requires return short signed
sizeof static static_assert static_cast struct switch template this thread_local throw true try
typedef typeid typename union unsigned using virtual void volatile wchar_t while xor xor_eq
""".split())


# Macros that code including a generated header sees: those of the runtime headers generated code
# includes, of the system headers they bring in, and GCC's own in its default GNU mode
# (-std=gnu++20, CMake's default), as `g++ -dM -E` lists them (cpp_macros.txt; the robustness test
# checks the list against the compiler and refreshes it). A member, type or enumerator so named would
# be replaced by the preprocessor. Names with a leading underscore are refused by their own rule.
MACROS_FILE = os.path.join(os.path.dirname(__file__), "cpp_macros.txt")
with open(MACROS_FILE, encoding="utf-8") as _handle:
    MACROS = frozenset(_handle.read().split())


def reserved(name: str) -> str | None:
    if name.startswith("__") or (name.startswith("_") and len(name) > 1 and name[1].isupper()):
        return "reserved in C++ (leading underscores)"
    if name in MACROS:
        return "a macro of the C/C++ headers that generated code includes"
    return None


# Packages whose C++ namespace another library owns: the runtime's (horus, its nested namespaces),
# msgpack-cxx's and the standard library's. A type there could redefine one of theirs.
RESERVED_PACKAGES = frozenset({"horus", "horus.detail", "horus.summary", "horus.literals", "horus.log"})
RESERVED_PACKAGE_ROOTS = frozenset({"std", "msgpack"})


def reserved_package(package: str) -> bool:
    return package in RESERVED_PACKAGES or package.split(".")[0] in RESERVED_PACKAGE_ROOTS


# What generated code declares in a package's namespace beside its types: each enum's to_string(),
# and the namespace of the summary tables. A type of the package so named would collide.
NAMESPACE_NAMES = frozenset({"to_string", "horus_log_summary"})


PRIMITIVE_TYPES = {"bool": "bool", "u8": "::std::uint8_t", "u16": "::std::uint16_t", "u32": "::std::uint32_t",
                   "u64": "::std::uint64_t", "i8": "::std::int8_t", "i16": "::std::int16_t", "i32": "::std::int32_t",
                   "i64": "::std::int64_t", "f32": "float", "f64": "double"}


def namespace(package: str) -> str:
    return package.replace(".", "::")


def header_path(qualified: str) -> str:
    package, name = qualified.rsplit(".", 1)
    return "/".join(package.split(".") + [snake_case(name) + ".hpp"])


def mixin_path(package: str, relative: str) -> str:
    """Where a #[cpp_mixin] fragment is copied, and the path the message's header includes it by:
    its path relative to the schema's folder, under the package's folder."""
    return os.path.join(*package.split("."), relative)


def package_header_path(package: str) -> str:
    """The header including every header of a package: horus.msg -> horus/msg.hpp."""
    return "/".join(package.split(".")) + ".hpp"


def package_source_path(package: str) -> str:
    """The one .cpp holding the out-of-line code of a package's types, beside the package header:
    horus.msg -> horus/msg.cpp. One translation unit per package, not one per schema file: each
    costs about as much as <string> to compile, whatever it holds."""
    return "/".join(package.split(".")) + ".cpp"


def package_nodes_source_path(package: str) -> str:
    """The one .cpp holding the out-of-line code of a package's nodes, in the package's folder:
    my_robot.nodes -> my_robot/nodes/_nodes.cpp (no header is named so: headers end in .hpp)."""
    return "/".join(package.split(".") + ["_nodes.cpp"])


def type_name(t: Type, package: str) -> str:
    if isinstance(t, Primitive):
        return PRIMITIVE_TYPES[t.name]
    if isinstance(t, FixedString):
        return f"::horus::FixedString<{t.capacity}>"
    if isinstance(t, FixedArray):
        return f"::std::array<{type_name(t.element, package)}, {t.length}>"
    if isinstance(t, DynString):
        return "::std::string"
    if isinstance(t, Bytes):
        return "::std::vector<::std::uint8_t>"
    if isinstance(t, Vec):
        return f"::std::vector<{type_name(t.element, package)}>"
    if isinstance(t, Optional):
        return f"::std::optional<{type_name(t.element, package)}>"
    if isinstance(t, (MessageRef, EnumRef)):  # qualified: a member may take the name of a type
        return cpp_ref(t.qualified, package)
    raise ValueError(t)


def string_literal(text: str) -> str:
    """A C++ string literal of `text`: ASCII, other bytes as octal escapes, and a `?` after a `?`
    as `\\?`, so that no trigraph appears (GCC warns of them even where it ignores them)."""
    out = []
    previous = ""
    for byte in text.encode("utf-8"):
        c = chr(byte)
        if c in '"\\' or (c == "?" and previous == "?"):
            out.append("\\" + c)
        elif c == "\n":
            out.append("\\n")
        elif 0x20 <= byte < 0x7F:
            out.append(c)
        else:
            out.append(f"\\{byte:03o}")
        previous = c
    return '"' + "".join(out) + '"'


def bytes_literal(data: bytes, indent: str = "      ") -> str:
    """`data` as adjacent C++ string literals, 32 bytes a line, and its length: the arguments of a
    std::string_view over exactly these bytes (embedded NULs included). Printable ASCII stays as it
    is; other bytes, quotes, backslashes and `?` (no trigraphs) are three-digit octal escapes, which
    never run into the character after them."""
    lines = []
    for start in range(0, len(data), 32):
        chunk = data[start:start + 32]
        lines.append('"' + "".join(chr(b) if 0x20 <= b < 0x7F and chr(b) not in '"\\?' else f"\\{b:03o}"
                                   for b in chunk) + '"')
    return ("\n" + indent).join(lines or ['""']) + f", {len(data)}"


def char_literal(byte: int) -> str:
    c = chr(byte)
    if c in "'\\":
        return f"'\\{c}'"
    if 0x20 <= byte < 0x7F:
        return f"'{c}'"
    return f"'\\{byte:03o}'"


def float_literal(value: float, single: bool) -> str:
    if single:
        target = struct.unpack("<f", struct.pack("<f", value))[0]
        shortest = next(t for t in (f"{value:.{p}g}" for p in range(1, 10))
                        if struct.unpack("<f", struct.pack("<f", float(t)))[0] == target)
        text = repr(float(shortest))
    else:
        text = repr(value)
    if not any(c in text for c in ".e"):
        text += ".0"
    return text + ("f" if single else "")


def value_literal(value, t: Type, package: str) -> str:
    if isinstance(t, Primitive):
        if t.is_bool:
            return "true" if value else "false"
        if t.is_float:
            return float_literal(float(value), t.name == "f32")
        if t.name == "u64":
            return f"{value}ULL"
        if t.name == "i64":
            return "(-9223372036854775807LL - 1)" if value == -(1 << 63) else f"{value}LL"
        if t.name == "u32":
            return f"{value}U"
        return str(value)
    if isinstance(t, EnumRef):
        assert isinstance(value, EnumValue)
        return f"{type_name(t, package)}::{value.variant}"
    if isinstance(t, FixedString):
        return "{{" + ", ".join(char_literal(b) for b in value.encode("utf-8")) + "}}"
    if isinstance(t, DynString):
        return string_literal(value)
    if isinstance(t, FixedArray):
        return "{{" + ", ".join(value_literal(v, t.element, package) for v in value) + "}}"
    raise ValueError(t)


def typed_value(value, t: Type, package: str) -> str:
    """`value` as an expression that declare_param<T>() and ParamOptions<T>::choices take: a
    literal, or an array's braces prefixed with its type (braces alone in a list of choices
    would not say which element each opens)."""
    literal = value_literal(value, t, package)
    return type_name(t, package) + literal if literal.startswith("{") else literal


def optional_bound(bound: float | int | None) -> str:
    """A #[min]/#[max] as ParamOptions holds it (std::optional<double>)."""
    return "::std::nullopt" if bound is None else float_literal(float(bound), single=False)


def param_facts(param: NodeParam) -> list[str]:
    """What a parameter's declaration says beyond its doc, as one doc line for its accessor
    (`In m/s; from 0.0 to 2.0; read-only.`), or none."""
    facts = []
    if param.unit:
        facts.append(f"in {param.unit}")
    if param.minimum is not None and param.maximum is not None:
        facts.append(f"from {param.minimum} to {param.maximum}")
    elif param.minimum is not None:
        facts.append(f"at least {param.minimum}")
    elif param.maximum is not None:
        facts.append(f"at most {param.maximum}")
    if param.choices:
        facts.append("one of " + ", ".join(
            c.variant if isinstance(c, EnumValue) else json.dumps(description.value_tree(c)) for c in param.choices))
    if param.read_only:
        facts.append("read-only while the node runs")
    if not facts:
        return []
    text = "; ".join(facts) + "."
    return [text[0].upper() + text[1:]]


def initializer(f: Field, package: str) -> str:
    if f.default is None:
        return "{}"
    literal = value_literal(f.default, f.type, package)
    return literal if literal.startswith("{") else "{" + literal + "}"


def padding_initializer(message: Message) -> str:
    return "{{" + ", ".join(f"{{{p.offset}, {p.size}}}" for p in message.padding) + "}}"


def constant_type(t: Type, package: str) -> str:
    if isinstance(t, (FixedString, DynString)):
        return "::std::string_view"
    return type_name(t, package)


def constant_literal(value, t: Type, package: str) -> str:
    if isinstance(t, (FixedString, DynString)):
        return string_literal(value)
    return value_literal(value, t, package)


def field_headers(types: list[Type]) -> set[str]:
    """Every header that declares what fields of these types spell (standard ones in <>)."""
    needed: set[str] = set()

    def visit(t: Type) -> None:
        if isinstance(t, (Vec, Bytes)):
            needed.add("<vector>")
        if isinstance(t, Optional):
            needed.add("<optional>")
        if isinstance(t, FixedArray):
            needed.add("<array>")
        if isinstance(t, DynString):
            needed.add("<string>")
        if isinstance(t, FixedString):
            needed.add('"horus/fixed_string.hpp"')
        if isinstance(t, Primitive) and t.is_integer:
            needed.add("<cstdint>")
        if isinstance(t, (FixedArray, Vec, Optional)):
            visit(t.element)

    for t in types:
        visit(t)
    return needed


def std_headers(message: Message) -> list[str]:
    """The standard headers a message's fields need beyond horus/message.hpp (which has the rest)."""
    needed = field_headers([f.type for f in message.fields]) & {"<vector>", "<optional>"}
    return sorted(needed | set(message.cpp_includes))


# Standard headers included as a lighter one where the library has it, each with the comment that
# says why in the generated header. GCC 12's <chrono> also parses calendars, time zones and
# formatting: 0.1 s of every file that includes a message header asking for it, when helpers take
# durations. Other standard libraries get the full header.
LIGHTER_HEADERS = {"<chrono>": ("<bits/chrono.h>", (
    "libstdc++'s durations, time points, clocks and chrono literals, without the calendars, time",
    "zones and formatting that make the full <chrono> cost 0.1 s in every file including this one."))}


def lighter_header(header: str) -> tuple[str, tuple[str, ...]] | None:
    """(lighter header, comment lines saying why) to include instead of `header` when it exists."""
    return LIGHTER_HEADERS.get(header)


def type_headers(message: Message) -> list[str]:
    return [header_path(q) for q in message.uses]


def contract_check(header: str) -> str:
    """The static_assert by which the header `header` refuses a runtime of another contract."""
    return (f"static_assert(HORUS_GENERATED_CONTRACT_VERSION == {CONTRACT_VERSION},\n"
            f"              \"{header} was generated by horus-gen for version {CONTRACT_VERSION} of the contract "
            f"between generated code and the horus runtime, and this runtime implements another: regenerate it "
            f"with this runtime's horus-gen\");")


SUMMARY_KINDS = {"bool": "kBool", "u8": "kU8", "u16": "kU16", "u32": "kU32", "u64": "kU64", "i8": "kI8",
                 "i16": "kI16", "i32": "kI32", "i64": "kI64", "f32": "kF32", "f64": "kF64"}


def summary_type(t: Type, package: str, ids: dict[Type, str], model: Model) -> str:
    """The horus::summary::Type by which the one summary formatter reads a value of `t`
    (horus/summary_table.hpp); `ids` names the other entries of the package's table."""
    cpp = type_name(t, package)
    size = f"sizeof({cpp})"
    ns = "::horus::summary::"  # qualified: the package may have types of any name
    if isinstance(t, Primitive):
        return f"{ns}plain_type({ns}Kind::{SUMMARY_KINDS[t.name]}, {size})"
    if isinstance(t, DynString):
        return f"{ns}plain_type({ns}Kind::kString, {size})"
    if isinstance(t, FixedString):
        return f"{ns}fixed_string_type({t.capacity})"
    if isinstance(t, FixedArray):
        return f"{ns}array_type({size}, {t.length}, {ids[t.element]})"
    if isinstance(t, (Vec, Bytes)):
        element = t.element if isinstance(t, Vec) else PRIMITIVES["u8"]
        if element == PRIMITIVES["bool"]:
            return f"{ns}bool_vector_type({size}, {ids[element]})"
        return f"{ns}vector_type({size}, {ids[element]}, &{ns}vector_elements<{cpp}>)"
    if isinstance(t, Optional):
        return f"{ns}optional_type({size}, {ids[t.element]}, &{ns}optional_value<{cpp}>)"
    if isinstance(t, EnumRef):
        enum = model.types[t.qualified]
        names = f"{ids[t]}Names" if enum.variants else "nullptr"
        return f"{ns}enum_type({size}, {ids[enum.underlying]}, {names}, {len(enum.variants)})"
    if isinstance(t, MessageRef):
        return f"{ns}message_type({size}, &{ns}message_summary<{cpp}>)"
    raise ValueError(t)


def summary_enumerators(t: Type, package: str, model: Model) -> str | None:
    """The initializer of the horus::summary::Enumerator array of an enum with variants, else None:
    what the formatter prints for a value of `t`, without compiling code per enum."""
    if not isinstance(t, EnumRef) or not model.types[t.qualified].variants:
        return None
    cpp = type_name(t, package)
    return "{" + ", ".join(f"{{static_cast<::std::uint64_t>({cpp}::{v.name}), \"{v.name}\"}}"
                           for v in model.types[t.qualified].variants) + "}"


def summary_expression(expr: SummaryExpr, package: str) -> str:
    """A computed summary value in C++: f64 arithmetic through the package's helpers (source.cpp.j2),
    so that each operation is rounded on its own, as Python rounds it."""
    if expr.op == "field":
        return f"static_cast<double>(this->{expr.field})"
    if expr.op == "number":
        return float_literal(expr.number, single=False)
    if expr.op == "neg":
        return f"-({summary_expression(expr.operands[0], package)})"
    left, right = (summary_expression(e, package) for e in expr.operands)
    return f"::{namespace(package)}::horus_log_summary::{SUMMARY_OPERATIONS[expr.op]}({left}, {right})"


SUMMARY_OPERATIONS = {"+": "add", "-": "subtract", "*": "multiply", "/": "divide"}


def computes_summary(message: Message) -> bool:
    return any(part.expression is not None for part in message.summary)


def summary_type_id(part: SummaryPart, message: Message, ids: dict[Type, str]) -> str:
    """The table entry of the type of the field a summary part prints."""
    return ids[next(f.type for f in message.fields if f.name == part.field)]


# What every node header includes from the standard library: its declarations need them.
NODE_STD_HEADERS = frozenset({"<cstddef>", "<memory>", "<string_view>", "<utility>", "<vector>"})


def node_std_headers(node: Node) -> list[str]:
    """The standard headers a node header includes: its own and what its data, parameters and
    servers need."""
    needed = {h for h in field_headers([f.type for f in node.data] + [p.type for p in node.params])
              if h.startswith("<")}
    return sorted(NODE_STD_HEADERS | needed | ({"<optional>"} if node.servers else set()))


def node_horus_headers(node: Node) -> list[str]:
    """The runtime headers a node's data fields and parameters need beyond the node, topic and
    scheduler ones."""
    needed = {h.strip('"') for h in field_headers([f.type for f in node.data]) if not h.startswith("<")}
    return sorted(needed | ({"horus/params.hpp"} if node.params else set()))


def node_headers(node: Node) -> list[str]:
    """The generated headers of the messages, enums and services a node names."""
    return [header_path(q) for q in node.uses]


def cpp_ref(qualified: str, package: str) -> str:
    """A message's, enum's or service's C++ name, from the global namespace: inside a class, a member
    may have the name of a type, and a type of the package the name of a namespace (`std`)."""
    owner, name = qualified.rsplit(".", 1)
    return f"::{namespace(owner)}::{name}"


def nanoseconds(ns: int) -> str:
    return f"::std::chrono::nanoseconds({ns}LL)"


def failure_policy(policy: FailurePolicy) -> str:
    """A ::horus::FailurePolicy expression; arguments not given keep the runtime's defaults."""
    if not policy.arguments:
        return f"::horus::FailurePolicy::{policy.kind}{{}}"
    fields = ", ".join(f".{name} = " + (f"{value}U" if name.startswith("max_") else nanoseconds(value))
                       for name, value in policy.arguments)
    return f"::horus::FailurePolicy::{policy.kind}{{{fields}}}"


def doc_lines(docs: tuple[str, ...]) -> list[str]:
    """The `///` lines of doc text. A `//` line ending in a backslash (or in `??/`, a backslash
    spelled as a trigraph, which GCC warns of) would continue the comment onto the next line of
    code: such a line ends in `<!---->`, an HTML comment Doxygen leaves out."""
    lines = []
    for line in docs:
        text = f"/// {line}".rstrip()
        lines.append(text + "<!---->" if text.endswith(("\\", "??/")) else text)
    return lines


FILTERS = {
    "namespace": namespace, "type_name": type_name, "initializer": initializer,
    "value_literal": value_literal, "typed_value": typed_value, "param_facts": param_facts, "optional_bound": optional_bound, "padding_initializer": padding_initializer, "constant_type": constant_type, "constant_literal": constant_literal, "string_literal": string_literal,
    "header_path": header_path, "std_headers": std_headers, "type_headers": type_headers,
    "lighter_header": lighter_header, "mixin_path": mixin_path,
    "doc_lines": doc_lines, "contract_check": contract_check, "node_std_headers": node_std_headers,
    "node_horus_headers": node_horus_headers,
    "node_headers": node_headers, "nanoseconds": nanoseconds, "cpp_ref": cpp_ref,
    "basename": os.path.basename, "failure_policy": failure_policy,
    "float_literal": float_literal, "bytes_literal": bytes_literal,
    "summary_type": summary_type, "summary_type_id": summary_type_id,
    "summary_enumerators": summary_enumerators, "summary_expression": summary_expression,
    "computes_summary": computes_summary, "schema_spelling": identity.spelling,
    "hex": lambda n: f"0x{n:016x}ULL",
}


def emit(model: Model, data: DataPaths) -> dict[str, str]:
    env = environment(data, "cpp", FILTERS)
    files: dict[str, str] = {}
    by_package: dict[str, list[Message | Enum | Service | Action | Node]] = {}
    for item in model.generated_items():
        path = header_path(item.qualified)
        if isinstance(item, Node):
            template, context = "node.hpp.j2", {"node": item, "model": model}
        elif isinstance(item, Service):
            template, context = "service.hpp.j2", {"service": item}
        elif isinstance(item, Action):
            template, context = "action.hpp.j2", {"action": item}
        elif isinstance(item, Enum):
            template, context = "enum.hpp.j2", {"enum": item,
                                                "description": description.carried_bytes(model, item.qualified)}
        else:
            template, context = "message.hpp.j2", {"message": item, "model": model,
                                                   "description": description.carried_bytes(model, item.qualified)}
            if item.cpp_mixin is not None:
                with open(item.cpp_mixin.source_path, encoding="utf-8") as handle:
                    files[os.path.join("cpp", mixin_path(item.package, item.cpp_mixin.relative))] = handle.read()
        files[os.path.join("cpp", path)] = env.get_template(template).render(
            banner=banner("//", [item.source]), **context)
        by_package.setdefault(item.package, []).append(item)
    for package, items in by_package.items():
        package_banner = banner("//", [i.source for i in items])
        files[os.path.join("cpp", package_header_path(package))] = env.get_template("package.hpp.j2").render(
            banner=package_banner, package=package, headers=sorted(header_path(i.qualified) for i in items))
        nodes = [i for i in items if isinstance(i, Node)]
        if nodes:
            files[os.path.join("cpp", package_nodes_source_path(package))] = env.get_template("nodes.cpp.j2").render(
                banner=banner("//", [n.source for n in nodes]), package=package, nodes=nodes)
        messages = [i for i in items if isinstance(i, Message)]
        if messages:
            summary_types = printed_types(model, messages)
            files[os.path.join("cpp", package_source_path(package))] = env.get_template("source.cpp.j2").render(
                banner=package_banner, package=package, messages=messages, model=model,
                headers=sorted(header_path(m.qualified) for m in messages), summary_types=summary_types,
                summary_ids={t: f"kType{i}" for i, t in enumerate(summary_types)})
    return files
