"""OMG IDL spelling of the model, in ROS 2's naming, so that a DDS program (Cyclone DDS's `idlc`,
a ROS 2 node) with a matching type reads and writes what the HORUS DDS bridge sends.

One `<Name>.idl` per message and enum, and one `<Service>.idl` per service (its request and response
as `<Service>_Request_` and `<Service>_Response_`, as ROS 2 names them) under `idl/<package path>/`;
an action `A` adds `<snake A>_action.idl`, ROS 2's shapes of an action (`A_Goal_`, `A_SendGoal_Request_`
... `A_FeedbackMessage_`), whose goal ids and stamps are ROS 2's own types (unique_identifier_msgs'
UUID, builtin_interfaces' Time: their IDL is the DDS bridge's, bridges/dds/ros2_idl);
`idl/` is the include root (`-I`) of their `#include "<package path>/<Name>.idl"`. A package
`a.b` is `module a { module b { module dds_ { ... }; }; };` and a message `Name` its struct `Name_`
(ROS 2's DDS type names: `a::b::dds_::Name_`). Constants, with the type's HORUS name and fingerprint,
are in the module `<Name>_Constants` beside the struct, as ROS 2 puts a message's constants.

A field of type horus.msg.PoolBlock (the block of a tensor pool a descriptor of Image, DepthImage,
PointCloud or Tensor names) is `sequence<uint8> data` instead: a block means nothing on another
host, so the DDS bridge sends the block's bytes in its place (docs/dds-bridge.md, "Pool types").

IDL has no enums ROS 2 uses and no optional: an enum is a typedef of its underlying integer
(`Name_`) with one constant per variant in `<Name>_Constants`; `Option<T>` is `sequence<T, 1>`.
Names IDL reserves (its keywords compare without case) get a trailing underscore, as rosidl does,
instead of being refused: KEYWORDS is empty, so IDL refuses no schema.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

from ..data import DataPaths
from ..model import (Action, Bytes, DynString, Enum, EnumRef, EnumValue, FixedArray, FixedString, Message,
                     MessageRef, Model, Optional, Primitive, Service, Type, Vec)
from ..names import snake_case
from .common import banner, environment

DISPLAY_NAME = "OMG IDL"
KEYWORDS: frozenset[str] = frozenset()  # IDL renames what it reserves (identifier()), it refuses nothing

# OMG IDL 4.2's keywords (section 7.2.4) and the names idlc also reserves: a name equal to one of them
# in any case is renamed (idlc compares keywords without case: a field `Module` is a syntax error).
IDL_KEYWORDS = frozenset(word.lower() for word in """
    abstract any alias attribute bitfield bitmask bitset boolean case char component connector const
    consumes context custom default double exception emits enum eventtype factory false finder fixed
    float getraises getter home import in inout interface local long manages map mirrorport module
    multiple native object octet oneway out primarykey private port porttype provides public
    publishes raises readonly setraises setter sequence short string struct supports switch true
    truncatable typedef typeid typename typeprefix unsigned union uses valuebase valuetype void wchar
    wstring int8 uint8 int16 int32 int64 uint16 uint32 uint64
    """.split())

PRIMITIVES = {"bool": "boolean", "u8": "uint8", "u16": "uint16", "u32": "uint32", "u64": "uint64",
              "i8": "int8", "i16": "int16", "i32": "int32", "i64": "int64", "f32": "float", "f64": "double"}

# ROS 2's member of a message without fields (IDL 3.5 structs cannot be empty; rosidl adds it).
EMPTY_MEMBER = "structure_needs_at_least_one_member"

# A tensor pool's block: on DDS, the data it holds (`sequence<uint8> data`).
POOL_BLOCK = "horus.msg.PoolBlock"


def reserved(name: str) -> str | None:
    return None


def identifier(name: str) -> str:
    """A HORUS name as an IDL identifier: a keyword (in any case) gets a trailing underscore, and a
    leading underscore is doubled (IDL drops one: `_x` would be read as `x`)."""
    if name.lower() in IDL_KEYWORDS:
        name += "_"
    return "_" + name if name.startswith("_") else name


def unique(names: list[str], taken: set[str]) -> list[str]:
    """IDL identifiers of one scope: IDL compares them without case, and a member may not be named like
    its scope; a name that would collide gets one more trailing underscore until it does not."""
    seen = {t.lower() for t in taken}
    result = []
    for name in names:
        while name.lower() in seen:
            name += "_"
        seen.add(name.lower())
        result.append(name)
    return result


def modules(package: str) -> list[str]:
    return [identifier(segment) for segment in package.split(".")] + ["dds_"]


def declared_name(model: Model, qualified: str) -> str:
    """The ROS 2 name of a type without its trailing underscore: `Name`, or `<Service>_Request` and
    `<Service>_Response` for the messages a service declares (the model's `<Service>Request`)."""
    found = model.types[qualified]
    if isinstance(found, Message) and found.service:
        service = found.service.rsplit(".", 1)[1]
        return f"{service}_{found.name[len(service):]}"
    return found.name


def file_of(model: Model, qualified: str) -> str:
    """The IDL file declaring a type, relative to the include root `idl/`."""
    found = model.types[qualified]
    name = found.service.rsplit(".", 1)[1] if isinstance(found, Message) and found.service else found.name
    return "/".join([*found.package.split("."), f"{name}.idl"])


def scoped(model: Model, qualified: str) -> str:
    found = model.types[qualified]
    return "::" + "::".join([*modules(found.package), identifier(declared_name(model, qualified) + "_")])


def dds_type_name(model: Model, qualified: str) -> str:
    """The type's name on DDS, as idlc registers it from this IDL (and ROS 2 names it):
    `pkg::msg::dds_::Name_`, with the underscore that escapes an identifier dropped, as IDL drops it."""
    return "::".join(part[1:] if part.startswith("_") else part for part in scoped(model, qualified)[2:].split("::"))


@dataclass(frozen=True)
class Typedef:
    spec: str
    name: str
    dims: str


@dataclass(frozen=True)
class Member:
    spec: str
    name: str
    dims: str  # "[3][4]" for fixed arrays
    comment: tuple[str, ...]


POOL_DATA = Member("sequence<uint8>", "data", "", (
    "The data of the pool block the descriptor names (its block here: a block means nothing on",
    "another host, so its bytes cross instead).", "[B]"))


@dataclass(frozen=True)
class Const:
    spec: str
    name: str
    value: str
    comment: str


@dataclass(frozen=True)
class Struct:
    """One message as IDL: what message.idl.j2 spells."""
    qualified: str
    fingerprint: int
    name: str  # the struct's identifier, `Name_`
    constants_module: str
    constants: tuple[Const, ...]
    typedefs: tuple[Typedef, ...]
    members: tuple[Member, ...]
    comment: tuple[str, ...]
    omitted: tuple[str, ...] = ()  # constants IDL cannot write (literal())


def _typedef(typedefs: list[Typedef], prefix: str, spec: str, dims: str) -> str:
    """Appends `typedef spec name dims;` named `prefix`, or `prefix_2`, `_3`... when the struct's
    typedefs already hold that name (in any case); returns the name."""
    taken = {t.name.lower() for t in typedefs}
    name, count = prefix, 1
    while name.lower() in taken:
        count += 1
        name = f"{prefix}_{count}"
    typedefs.append(Typedef(spec, name, dims))
    return name


def spell(model: Model, spelled: Type, typedefs: list[Typedef], prefix: str) -> tuple[str, str]:
    """A type as (type spec, array dimensions). An array inside sequence<> gets a typedef named after
    `prefix` (IDL has no anonymous array types there), appended to `typedefs` before its use."""
    if isinstance(spelled, Primitive):
        return PRIMITIVES[spelled.name], ""
    if isinstance(spelled, FixedString):
        return f"string<{spelled.capacity}>", ""
    if isinstance(spelled, DynString):
        return "string", ""
    if isinstance(spelled, Bytes):
        return "sequence<uint8>", ""
    if isinstance(spelled, FixedArray):
        spec, dims = spell(model, spelled.element, typedefs, prefix)
        return spec, f"[{spelled.length}]{dims}"
    if isinstance(spelled, (Vec, Optional)):
        spec, dims = spell(model, spelled.element, typedefs, prefix)
        if dims:
            if spec.startswith("sequence<"):
                # idlc 0.10's C names an array typedef's anonymous sequence wrongly: name it first.
                spec = _typedef(typedefs, prefix, spec, "")
            spec = _typedef(typedefs, prefix, spec, dims)
        # ", 1": Option; a space keeps `> >` from reading as the shift operator `>>`.
        bound = ", 1" if isinstance(spelled, Optional) else " " if spec.endswith(">") else ""
        return f"sequence<{spec}{bound}>", ""
    if isinstance(spelled, (MessageRef, EnumRef)):
        return scoped(model, spelled.qualified), ""
    raise TypeError(f"no IDL for {spelled!r}")


def _comment(docs: tuple[str, ...], unit: str = "") -> tuple[str, ...]:
    # A trailing backslash would continue a // comment onto the next line; `??` could start a trigraph.
    lines = [line.rstrip().rstrip("\\").rstrip().replace("??", "? ?") for line in docs]
    lines = [line for line in lines if line.strip()]
    if unit:
        lines.append(f"[{unit}]")
    return tuple(lines)


def _string_literal(text: str) -> str | None:
    """A printable ASCII string as an IDL literal; None for any other (idlc 0.10 copies a string
    constant into the C it writes without escaping it again, and mangles `\\x` escapes: a quote, a
    backslash or a character outside printable ASCII would break or change that C)."""
    if any(not 0x20 <= ord(c) < 0x7f or c in '"\\' for c in text):
        return None
    return '"' + text.replace("?", "\\?") + '"'


def literal(value: object, spelled: Type) -> str | None:
    """An IDL constant's value; None when IDL (or idlc's C) cannot write it: a NaN, an infinity, a
    string other than printable ASCII without quotes and backslashes."""
    if isinstance(value, EnumValue):
        return str(value.number)
    if isinstance(value, bool):
        return "TRUE" if value else "FALSE"
    if isinstance(value, int) and not (isinstance(spelled, Primitive) and spelled.is_float):
        return str(value)
    if isinstance(value, (int, float)):
        number = float(value)
        if not math.isfinite(number):
            return None
        text = repr(number)
        return text if any(c in text for c in ".e") else text + ".0"
    if isinstance(value, str):
        return _string_literal(value)
    return None


def _fingerprint(value: int) -> str:
    return f"0x{value:016x}"


def struct_of(model: Model, message: Message, base: str | None = None) -> Struct:
    """The message as IDL, its struct named `<base>_` (default: its ROS 2 name, declared_name())."""
    base = base or declared_name(model, message.qualified)
    name = identifier(base + "_")
    constants_module = identifier(base + "_Constants")
    header = [Const("uint64", "HORUS_FINGERPRINT", _fingerprint(message.fingerprint), ""),
              Const("string", "HORUS_TYPE_NAME", _string_literal(message.qualified), "")]
    own = []
    omitted = []
    for constant in message.constants:
        spelled = constant.type
        comment = ""
        if isinstance(spelled, EnumRef):
            enum = model.types[spelled.qualified]
            assert isinstance(enum, Enum)
            comment = f"{enum.name}::{constant.value.variant}" if isinstance(constant.value, EnumValue) else ""
            spelled = enum.underlying
        value = literal(constant.value, spelled)
        if value is None:
            omitted.append(constant.name)
            continue
        spec, _ = spell(model, spelled, [], "")
        own.append(Const(spec, identifier(constant.name), value, comment))
    names = unique([c.name for c in header + own], {constants_module})
    constants = tuple(Const(c.spec, n, c.value, c.comment) for c, n in zip(header + own, names))

    typedefs: list[Typedef] = []
    members = []
    fields = message.fields
    pool_field = [isinstance(f.type, MessageRef) and f.type.qualified == POOL_BLOCK for f in fields]
    member_names = unique([POOL_DATA.name if pool else identifier(f.name)
                           for f, pool in zip(fields, pool_field)], {name})
    for f, member, pool in zip(fields, member_names, pool_field):
        if pool:
            members.append(Member(POOL_DATA.spec, member, "", POOL_DATA.comment))
            continue
        spec, dims = spell(model, f.type, typedefs, identifier(f"{base}__{f.name}"))
        members.append(Member(spec, member, dims, _comment(f.docs, f.unit)))
    if not members:
        members.append(Member("uint8", EMPTY_MEMBER, "", ("No fields: ROS 2's member of an empty message.",)))
    return Struct(message.qualified, message.fingerprint, name, constants_module, constants, tuple(typedefs),
                  tuple(members), _comment(message.docs), tuple(omitted))


def includes(model: Model, own_file: str, uses: list[str]) -> list[str]:
    """The IDL files of the types `uses` names, once each, in first-use order."""
    files = [file_of(model, q) for q in uses]
    return [f for f in dict.fromkeys(files) if f != own_file]


# ROS 2's types in an action's messages: the goal id and the time a goal was accepted.
ROS_UUID = "::unique_identifier_msgs::msg::dds_::UUID_"
ROS_TIME = "::builtin_interfaces::msg::dds_::Time_"
ROS_ACTION_INCLUDES = ["builtin_interfaces/msg/Time.idl", "unique_identifier_msgs/msg/UUID.idl"]


def action_file(action: Action) -> str:
    """The IDL file of an action's ROS 2 shapes, relative to the include root `idl/`."""
    return "/".join([*action.package.split("."), f"{snake_case(action.name)}_action.idl"])


def action_structs(model: Model, action: Action) -> tuple[list[Struct], list[tuple[str, list[tuple[str, str]]]]]:
    """ROS 2's shapes of an action: its goal, result and feedback as `A_Goal_`, `A_Result_`,
    `A_Feedback_` (Structs), and the messages around them as (struct name, [(type spec, member)]):
    `A_SendGoal_Request_`, `A_SendGoal_Response_`, `A_GetResult_Request_`, `A_GetResult_Response_`,
    `A_FeedbackMessage_`. Canceling and states are action_msgs' CancelGoal and GoalStatusArray."""
    a = action.name
    blocks = [struct_of(model, m, f"{a}_{role}") for role, m in
              (("Goal", action.goal), ("Result", action.result), ("Feedback", action.feedback))]
    own = ["::" + "::".join([*modules(action.package), b.name]) for b in blocks]
    wrappers = [
        (identifier(f"{a}_SendGoal_Request_"), [(ROS_UUID, "goal_id"), (own[0], "goal")]),
        (identifier(f"{a}_SendGoal_Response_"), [("boolean", "accepted"), (ROS_TIME, "stamp")]),
        (identifier(f"{a}_GetResult_Request_"), [(ROS_UUID, "goal_id")]),
        (identifier(f"{a}_GetResult_Response_"), [("int8", "status"), (own[1], "result")]),
        (identifier(f"{a}_FeedbackMessage_"), [(ROS_UUID, "goal_id"), (own[2], "feedback")]),
    ]
    return blocks, wrappers


def guard(path: str) -> str:
    return "HORUS_IDL_" + re.sub(r"[^A-Za-z0-9]", "_", path).upper() + "_"


def enum_constants(enum: Enum) -> tuple[str, tuple[Const, ...]]:
    module = identifier(enum.name + "_Constants")
    spec = PRIMITIVES[enum.underlying.name]
    header = [Const("uint64", "HORUS_FINGERPRINT", _fingerprint(enum.fingerprint), ""),
              Const("string", "HORUS_TYPE_NAME", _string_literal(enum.qualified), "")]
    variants = [Const(spec, identifier(v.name), str(v.value), " ".join(_comment(v.docs))) for v in enum.variants]
    names = unique([c.name for c in header + variants], {module})
    return module, tuple(Const(c.spec, n, c.value, c.comment) for c, n in zip(header + variants, names))


FILTERS = {"fingerprint": _fingerprint}


def emit(model: Model, data: DataPaths) -> dict[str, str]:
    env = environment(data, "idl", FILTERS)
    files: dict[str, str] = {}
    for item in model.generated_items():
        if isinstance(item, Message) and item.service:
            continue  # in its service's file
        if isinstance(item, Service):
            parts = [item.request, item.response]
            path = "/".join([*item.package.split("."), f"{item.name}.idl"])
            text = env.get_template("service.idl.j2").render(
                service=item, banner=banner("//", [item.source]), guard=guard(path),
                includes=includes(model, path, [*item.request.uses, *item.response.uses]),
                modules=modules(item.package), structs=[struct_of(model, m) for m in parts],
                constants_module=identifier(item.name + "_Constants"), comment=_comment(item.docs))
        elif isinstance(item, Enum):
            path = file_of(model, item.qualified)
            module, constants = enum_constants(item)
            text = env.get_template("enum.idl.j2").render(
                enum=item, banner=banner("//", [item.source]), guard=guard(path), modules=modules(item.package),
                typedef=identifier(item.name + "_"), underlying=PRIMITIVES[item.underlying.name],
                constants_module=module, constants=constants, comment=_comment(item.docs))
        elif isinstance(item, Message):
            path = file_of(model, item.qualified)
            text = env.get_template("message.idl.j2").render(
                banner=banner("//", [item.source]), guard=guard(path), includes=includes(model, path, list(item.uses)),
                modules=modules(item.package), struct=struct_of(model, item))
        elif isinstance(item, Action):
            path = action_file(item)
            blocks, wrappers = action_structs(model, item)
            uses = [*item.goal.uses, *item.result.uses, *item.feedback.uses]
            text = env.get_template("action.idl.j2").render(
                action=item, banner=banner("//", [item.source]), guard=guard(path),
                includes=ROS_ACTION_INCLUDES + includes(model, path, uses), modules=modules(item.package),
                structs=blocks, wrappers=wrappers, constants_module=identifier(item.name + "_Constants"),
                comment=_comment(item.docs))
        else:
            continue  # nodes have no IDL: their topics carry messages
        files[os.path.join("idl", *path.split("/"))] = text
    return files
