"""Parameters (docs/parameters.md): a node's knobs, declared with their type, default and range,
held in the namespace's shared memory, read by anyone without asking, written through the node.

Everything that checks a declaration or a value, reads or writes the store, or reads and writes
YAML parameter files is the C++ runtime's (runtime/include/horus/params.hpp), reached through
horus._core; this module turns its MessagePack VALUE bytes into Python's plain values and back
(enums by their enumerator's name, arrays as lists) and gives the classes a Python user sees:

- in a node: `Node.declare_param(...)` returns a `Param`; `node.params.NAME` reads it;
  `on_param_change(change: ParamChange) -> ParamVerdict | None` may refuse a write;
- in tools: `Params(node)` (list, get, set, watch), `param_nodes()`, `load_params()`,
  `dump_params()`.
"""
from __future__ import annotations

import dataclasses
import enum
import math
import os
import re
import struct
import time

import msgpack

from . import _core

ParamError = _core.ParamError

_SCALARS = ("bool", "i8", "i16", "i32", "i64", "u8", "u16", "u32", "u64", "f32", "f64")
_FLOATS = ("f32", "f64")
_ARRAY = re.compile(r"^\[(bool|[iu](?:8|16|32|64)|f32|f64); ([1-9][0-9]*)\]$")
# How long one wait on a store's change counter lasts at most: Ctrl+C is seen between two.
_WAIT_SLICE_S = 0.1


def _pack(value) -> bytes:
    return msgpack.packb(value, use_bin_type=True)


def _unpack(data: bytes):
    return msgpack.unpackb(data, raw=False)


def _element_spelling(spelling: str) -> str | None:
    """The element type of a fixed array's spelling ("[f64; 3]" -> "f64"), else None."""
    match = _ARRAY.match(spelling)
    return match.group(1) if match else None


def plain_param_value(spelling: str, value, enum_class: type | None = None):
    """A Python value as the MessagePack VALUE of a parameter spelled `spelling` takes it: an enum
    member by its name, a whole number of a float parameter as a float, a tuple or numpy array as
    a list. Anything else is left for the runtime's check, which says what is wrong."""
    if isinstance(value, enum.Enum):
        return value.name
    if enum_class is not None and isinstance(value, int) and not isinstance(value, bool):
        try:
            return enum_class(value).name
        except ValueError:
            return value
    if hasattr(value, "tolist") and not isinstance(value, (bytes, str)):
        value = value.tolist()  # numpy arrays and scalars
    element = _element_spelling(spelling)
    if element is not None and isinstance(value, (list, tuple)):
        return [plain_param_value(element, item) for item in value]
    if spelling in _FLOATS and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def _short_f32(value: float) -> float:
    """The shortest decimal that is the same f32 (0.1 rather than 0.10000000149011612), as
    horus.typedesc shows f32 fields."""
    for digits in range(6, 10):
        short = float(f"{value:.{digits}g}")
        if struct.pack("<f", short) == struct.pack("<f", value):
            return short
    return value


def _typed_number(value, spelling: str):
    """A number of an f32 or f64 parameter as a float (MessagePack may carry a whole number as
    an integer), an f32 in its shortest form."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return value
    if spelling == "f32" and math.isfinite(value):
        return _short_f32(float(value))
    return float(value) if spelling == "f64" else value


def _python_value(data: bytes, spelling: str, enum_class: type | None = None):
    """A parameter's VALUE bytes as a Python value: floats for f32 and f64, an enum member when
    the node declared the parameter with its generated IntEnum class, a list for an array."""
    value = _unpack(data)
    if enum_class is not None and isinstance(value, str):
        return enum_class[value]
    element = _element_spelling(spelling)
    if element is not None and isinstance(value, list):
        return [_typed_number(item, element) for item in value]
    return _typed_number(value, spelling)


def _spelling_of(default, type_) -> tuple[str, type | None]:
    """(the schema spelling of a parameter's type, its generated enum class or None), from the
    `type` given to declare_param or else from the default's Python type."""
    if type_ is not None:
        if isinstance(type_, str):
            return type_, None
        info = getattr(type_, "__horus__", None)
        if isinstance(type_, type) and issubclass(type_, enum.IntEnum) and info is not None:
            return info.name, type_
        if type_ in (bool, int, float, str):
            return {bool: "bool", int: "i64", float: "f64", str: "String"}[type_], None
        raise TypeError(f"a parameter's type is a schema spelling ('f32', '[f64; 3]', 'String'), "
                        f"a generated enum class or bool/int/float/str, not {type_!r}")
    if isinstance(default, enum.IntEnum) and getattr(type(default), "__horus__", None):
        return type(default).__horus__.name, type(default)
    if hasattr(default, "tolist") and not isinstance(default, (bytes, str)):
        default = default.tolist()  # numpy arrays and scalars
    if isinstance(default, bool):
        return "bool", None
    if isinstance(default, int):
        return "i64", None
    if isinstance(default, float):
        return "f64", None
    if isinstance(default, str):
        return "String", None
    if isinstance(default, (list, tuple)) and default:
        if all(isinstance(item, bool) for item in default):
            return f"[bool; {len(default)}]", None
        if all(isinstance(item, (int, float)) and not isinstance(item, bool) for item in default):
            element = "i64" if all(isinstance(item, int) for item in default) else "f64"
            return f"[{element}; {len(default)}]", None
    raise TypeError(f"cannot tell a parameter's type from the default {default!r}: give type= "
                    "(a schema spelling such as 'f32' or '[f64; 3]', or a generated enum class)")


class ParamVerdict:
    """A node's answer to a proposed change: `ParamVerdict.accept()` or
    `ParamVerdict.refuse("reason")` (on_param_change returning None accepts too)."""

    __slots__ = ("accepted", "reason")

    def __init__(self, accepted: bool, reason: str = "") -> None:
        self.accepted = bool(accepted)
        self.reason = str(reason)

    @classmethod
    def accept(cls) -> "ParamVerdict":
        return cls(True)

    @classmethod
    def refuse(cls, reason: str) -> "ParamVerdict":
        if not reason:
            raise ValueError("a refusal says why: ParamVerdict.refuse('reason')")
        return cls(False, reason)

    def __repr__(self) -> str:
        return ("ParamVerdict.accept()" if self.accepted
                else f"ParamVerdict.refuse({self.reason!r})")


@dataclasses.dataclass(frozen=True)
class ParamChange:
    """A write offered to the node's on_param_change(), already checked against the declaration:
    `name`, the proposed `value` (a Python value) and its `source` ("horus param", "yaml:FILE",
    "remote:PEER", a program name)."""
    name: str
    value: object
    source: str


@dataclasses.dataclass(frozen=True)
class ParamSetResult:
    """What a write came to: `accepted`, else the `reason` it was refused; the parameter's
    `version` after it (unchanged when refused)."""
    accepted: bool
    reason: str
    version: int


@dataclasses.dataclass(frozen=True)
class ParamInfo:
    """One parameter as a reader sees it: its declaration, current `value` and `version` (1 for
    the value the node started with, +1 for each accepted write)."""
    node: str
    name: str
    type: str
    value: object
    version: int
    default: object
    min: float | None
    max: float | None
    choices: list
    unit: str
    doc: str
    read_only: bool
    enumerators: list[str]

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def _info(raw: dict) -> ParamInfo:
    spelling = raw["type"]
    return ParamInfo(node=raw["node"], name=raw["name"], type=spelling,
                     value=_python_value(raw["value"], spelling), version=raw["version"],
                     default=_python_value(raw["default"], spelling), min=raw["min"],
                     max=raw["max"],
                     choices=[_python_value(choice, spelling) for choice in raw["choices"]],
                     unit=raw["unit"],
                     doc=raw["doc"], read_only=raw["read_only"], enumerators=raw["enumerators"])


def _result(raw: tuple) -> ParamSetResult:
    accepted, reason, version = raw
    return ParamSetResult(accepted, reason, version)


def _timeout(value, what: str = "timeout") -> float:
    value = float(value)
    if not value >= 0.0 or math.isinf(value):
        raise ValueError(f"{what} must be a finite number of seconds >= 0, got {value!r}")
    return value


class Param:
    """A node's handle on one of its parameters (what declare_param returns): `get()` reads the
    current value (the default until a scheduler starts the node), `version()` its version."""

    __slots__ = ("name", "spelling", "enum_class", "_default", "_encoded_default", "_options",
                 "_handle", "_seen_version", "_seen_value")

    def __init__(self, name: str, spelling: str, enum_class: type | None, default,
                 options: dict) -> None:
        self.name = name
        self.spelling = spelling
        self.enum_class = enum_class
        plain = plain_param_value(spelling, default, enum_class)
        self._encoded_default = _pack(plain)
        self._default = _python_value(self._encoded_default, spelling, enum_class)
        self._options = options
        self._handle = None  # the C++ node's handle, once a scheduler holds the node
        self._seen_version = -1
        self._seen_value = None

    def get(self):
        handle = self._handle
        if handle is None:
            return self._default
        # The version first: a value read after it is at least that new, so a later change is
        # seen as a newer version on the next read.
        version = handle.version()
        if version != self._seen_version:
            self._seen_value = _python_value(handle.value(), self.spelling, self.enum_class)
            self._seen_version = version
        return self._seen_value

    def version(self) -> int:
        """1 for the value the node started with, +1 for each accepted write (0 before start)."""
        return 0 if self._handle is None else self._handle.version()

    def _declare(self, core_node) -> None:
        """Declares the parameter on the C++ node (which checks the declaration)."""
        options = self._options
        enum_description = (None if self.enum_class is None
                            else self.enum_class.__horus__.description)
        self._handle = core_node.declare_param(
            self.name, self.spelling, self._encoded_default, options["min"], options["max"],
            [_pack(plain_param_value(self.spelling, choice, self.enum_class))
             for choice in options["choices"]],
            options["unit"], options["doc"], options["read_only"], enum_description)
        self._seen_version = -1

    def _value_of(self, data: bytes):
        return _python_value(data, self.spelling, self.enum_class)

    def __repr__(self) -> str:
        return f"horus.Param({self.name!r}: {self.spelling} = {self.get()!r})"


def make_param(name, default, type_=None, min=None, max=None, choices=None, unit="", doc="",
               read_only=False) -> Param:
    """A Param of a Python node (see Node.declare_param), its declaration checked by the runtime
    the way a C++ node's is."""
    if not isinstance(name, str):
        raise TypeError(f"a parameter's name is a string, got {name!r}")
    spelling, enum_class = _spelling_of(default, type_)
    options = dict(min=None if min is None else float(min), max=None if max is None else float(max),
                   choices=list(choices or ()), unit=str(unit), doc=str(doc),
                   read_only=bool(read_only))
    param = Param(name, spelling, enum_class, default, options)
    # The runtime checks the declaration now (name, range, choices, size), so that a mistake is
    # raised where it is made rather than when a scheduler adds the node.
    _core.check_param_declaration(
        name, spelling, param._encoded_default, options["min"], options["max"],
        [_pack(plain_param_value(spelling, choice, enum_class)) for choice in options["choices"]],
        options["unit"], options["doc"], options["read_only"],
        None if enum_class is None else enum_class.__horus__.description)
    return param


class ParamValues:
    """`node.params`: each declared parameter as an attribute (`node.params.max_speed`, a
    lock-free read of the store), iteration over the names, `version(name)`."""

    __slots__ = ("_node", "_params")

    def __init__(self, node_name: str, params: dict) -> None:
        object.__setattr__(self, "_node", node_name)
        object.__setattr__(self, "_params", params)

    def __getattr__(self, name: str):
        params = object.__getattribute__(self, "_params")
        param = params.get(name)
        if param is None:
            raise AttributeError(self._unknown(name))
        return param.get()

    def __setattr__(self, name: str, value) -> None:
        raise AttributeError(f"node '{self._node}': parameters are written through their node "
                             f"(horus.Params('{self._node}').set('{name}', ...) or `horus param "
                             "set`), not assigned")

    def __getitem__(self, name: str):
        if name not in self._params:
            raise KeyError(self._unknown(name))
        return self._params[name].get()

    def __iter__(self):
        return iter(list(self._params))

    def __len__(self) -> int:
        return len(self._params)

    def __contains__(self, name) -> bool:
        return name in self._params

    def version(self, name: str) -> int:
        if name not in self._params:
            raise KeyError(self._unknown(name))
        return self._params[name].version()

    def _unknown(self, name: str) -> str:
        import difflib
        close = difflib.get_close_matches(name, list(self._params), n=3, cutoff=0.6)
        hint = ("; did you mean " + " or ".join(f"'{c}'" for c in close) + "?") if close else ""
        return f"node '{self._node}' declares no parameter '{name}'{hint}"

    def __repr__(self) -> str:
        values = ", ".join(f"{name}={param.get()!r}" for name, param in self._params.items())
        return f"<params of node '{self._node}': {values}>"


def _namespace(namespace: str | None) -> str:
    return namespace if namespace is not None else ""


class Params:
    """One node's parameters as any process sees them (the `horus param` command's view): reads
    are lock-free reads of the namespace's shared memory; writes go through the node that owns
    them. A context manager: `with horus.Params("motor") as params: params.set("max_speed", 1.5)`.

    Raises ParamError when the node has no parameter store (never declared any, or never ran)."""

    def __init__(self, node: str, namespace: str | None = None) -> None:
        self._node = node
        self._namespace = _namespace(namespace)
        self._reader = _core.ParamStoreReader(node, self._namespace)
        self._seen = self._reader.change_count()
        self._versions = {info.name: info.version for info in self.list()}

    def __enter__(self) -> "Params":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Lets go of the store (the object is unusable after)."""
        self._reader = None

    def _store(self):
        if self._reader is None:
            raise ParamError(f"the parameters of node '{self._node}' were closed")
        return self._reader

    @property
    def node(self) -> str:
        return self._node

    @property
    def owner_alive(self) -> bool:
        """Whether the process that runs the node runs now."""
        return self._store().owner_alive()

    @property
    def owner_pid(self) -> int:
        """The pid of the process that runs (or last ran) the node; 0 when none ever ran."""
        return self._store().owner_pid()

    def list(self) -> list[ParamInfo]:
        """Every parameter with its declaration and current value, in declaration order."""
        return [_info(raw) for raw in self._store().list()]

    def get(self, name: str) -> ParamInfo:
        """One parameter; ParamError (with the closest names) when the node has none so named."""
        return _info(self._store().get(name))

    def names(self) -> list[str]:
        return [info.name for info in self.list()]

    def set(self, name: str, value, persist: bool = False, timeout: float = 5.0,
            source: str | None = None) -> ParamSetResult:
        """Writes one parameter through its node, which may refuse it: a refusal (by the
        declaration, the node, or because the node does not run and persist is False) is a
        result with the reason. With persist, a node that does not run gets the value at its
        next start. ParamError for an unknown parameter or a value of the wrong type."""
        info = self.get(name)
        plain = plain_param_value(info.type, value)
        return _result(_core.set_param(self._node, name, _pack(plain), bool(persist),
                                       _timeout(timeout), source or "", self._namespace))

    def change_count(self) -> int:
        """How many changes the node's parameters went through (any of them)."""
        return self._store().change_count()

    def watch(self, timeout: float | None = None) -> list[ParamInfo]:
        """Sleeps until a parameter changes (or `timeout` seconds pass; None: for ever) and
        returns the parameters whose version moved since the last watch() (or since this object
        was made), empty on timeout."""
        store = self._store()
        deadline = None if timeout is None else time.monotonic() + _timeout(timeout)
        while True:
            slice_s = _WAIT_SLICE_S
            if deadline is not None:
                slice_s = min(slice_s, max(0.0, deadline - time.monotonic()))
            count = store.wait_for_change(self._seen, slice_s)
            if count != self._seen:
                self._seen = count
                changed = [info for info in self.list()
                           if info.version != self._versions.get(info.name)]
                for info in changed:
                    self._versions[info.name] = info.version
                if changed:
                    return changed
            if deadline is not None and time.monotonic() >= deadline:
                return []

    def __repr__(self) -> str:
        return f"horus.Params({self._node!r})"


def param_nodes(namespace: str | None = None) -> list[str]:
    """The nodes of a namespace (default: the current one) that have a parameter store, sorted."""
    return list(_core.param_nodes(_namespace(namespace)))


def load_params(path: str | os.PathLike, namespace: str | None = None, persist: bool = False,
                timeout: float = 5.0) -> list[ParamSetResult]:
    """Checks every value of a YAML parameter file (`node: {name: value}`) against the nodes'
    declarations (ParamError naming FILE:LINE and the reason for each mistake), then writes them
    through their nodes; one result per value, in the file's order."""
    return [_result(raw) for raw in _core.load_param_file(
        os.fspath(path), bool(persist), _timeout(timeout), _namespace(namespace))]


def dump_params(nodes: list[str] | None = None, namespace: str | None = None) -> str:
    """The current values of `nodes` (all with a store when None) as a YAML parameter file,
    which load_params() and Scheduler(params=...) read."""
    if isinstance(nodes, str):
        nodes = [nodes]
    return _core.dump_param_file(list(nodes or ()), _namespace(namespace))


def param_service_name(node: str) -> str:
    """The name of the service that carries writes to `node` (left out of service listings)."""
    return _core.param_service_name(node)
