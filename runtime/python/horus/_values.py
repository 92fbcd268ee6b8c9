"""Plain values on topics: what `horus.Topic(float, name)` or `subs={'speed': float}` carries.

The twin of runtime/include/horus/plain_value.hpp. A plain value type is named as the schema
language spells it (`f64`, `[f32; 3]`, `String`, `Vec<u8>`), its schema text is `value <name>\\n`
and its fingerprint the 64-bit FNV-1a hash of that text, so a C++ `Topic<double>` and a Python
`horus.Topic(float, ...)` open the same topic. On the wire a plain value is what the message
`PlainValue { value: <name> }` would be: the value's bytes for a fixed size, else a MessagePack
array of the one value. The codecs are the generated classes' own (_horus_gen_support_v1), so the
bytes, the accepted values and the log summary are those of a message field of that type, and each
carries the type description of that message (`description`, built by
horus.typedesc.plain_value_description): the bytes C++'s `TypeInfo<T>::description` holds.

Python's own types stand for one width each: float is f64, int i64, bool bool, str String,
bytes Vec<u8>. Other types are spelled as in a schema (`"f32"`, `"[u8; 4]"`, `"Vec<f32>"`) or
given as a numpy scalar type or dtype (`numpy.float32`, `numpy.dtype((numpy.float32, 3))`).
"""
from __future__ import annotations

import re
import struct

_SUPPORT_MODULE = "_horus_gen_support_v1"
_SCALARS = ("bool", "i8", "i16", "i32", "i64", "u8", "u16", "u32", "u64", "f32", "f64")
_PYTHON_TYPES = {float: "f64", int: "i64", bool: "bool", str: "String", bytes: "Vec<u8>"}
_ARRAY = re.compile(r"^\[(.+); ([1-9][0-9]*)\]$")
_VEC = re.compile(r"^Vec<(.+)>$")
_NUMPY_KINDS = {"b": "bool", "i": "i", "u": "u", "f": "f"}
_MSGPACK_FRAME = b"\x91"  # an array of one element: the message's one field
_support = None


def _codecs():
    """The generated classes' codecs, imported on first use (they come with horus.msg)."""
    global _support
    if _support is None:
        import importlib

        _support = importlib.import_module(_SUPPORT_MODULE)
    return _support


def _fnv1a(text: str) -> int:
    """The fingerprint of the identities the runtime spells itself (plain values, service frames
    and registrations): the 64-bit FNV-1a hash of their schema text, as detail::fnv1a computes."""
    value = 0xCBF29CE484222325
    for byte in text.encode():
        value = ((value ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return value


class PlainValue:
    """One plain value type: its identity (`name`, `schema`, `fingerprint`, `is_pod`, `size`,
    `alignment`, `description`) and its bytes (`to_bytes`, `from_bytes`), and
    `log_summary(value)`, the line C++'s `horus::log_summary` prints for the same value."""

    __slots__ = ("name", "schema", "fingerprint", "is_pod", "size", "alignment", "_codec",
                 "_label", "_struct", "_description")

    def __init__(self, name: str) -> None:
        codec, label, alignment = _resolve(name)
        self.name = name
        self.schema = f"value {name}\n"
        self.fingerprint = _fnv1a(self.schema)
        self._codec, self._label = codec, label
        self.is_pod = alignment is not None
        self.size = codec.size if self.is_pod else None
        self.alignment = alignment
        self._struct = struct.Struct("<" + codec.fmt) if self.is_pod and codec.fmt else None
        self._description = None

    @property
    def description(self) -> bytes:
        """The type description (MessagePack) of the message `PlainValue { value: <name> }`, made
        the first time it is read: what a topic segment of this type stores."""
        if self._description is None:
            from . import typedesc

            self._description = typedesc.plain_value_bytes(self.name)
        return self._description

    @property
    def __horus__(self) -> "PlainValue":
        """What horus.Topic reads of a type: a plain value is its own type information."""
        return self

    def to_bytes(self, value) -> bytes:
        """The bytes a topic of this type carries for `value`; ValueError or TypeError when
        `value` is not one (an int out of range, a str for a number, an array of another
        shape)."""
        support = _codecs()
        try:
            if self._struct is not None:
                return self._struct.pack(self._codec.raw(value))
            if self.is_pod:
                return self._codec.raw(value)
            out = [_MSGPACK_FRAME]
            self._codec.pack(out, value)
            return b"".join(out)
        except support.FieldError as error:
            raise ValueError(f"{self.name}: {error}") from None
        except (struct.error, OverflowError) as error:
            raise ValueError(f"{self.name}: {error}") from None

    def from_bytes(self, data):
        """The value `data` holds; ValueError when it holds none of this type."""
        support = _codecs()
        try:
            if self._struct is not None:
                if len(data) != self.size:
                    raise support.FieldError(f"expected {self.size} bytes, got {len(data)}")
                return self._codec.from_raw(self._struct.unpack(data)[0])
            if self.is_pod:
                if len(data) != self.size:
                    raise support.FieldError(f"expected {self.size} bytes, got {len(data)}")
                return self._codec.raw_from(data, 0).copy()  # writable, not over `data`
            return self._codec.unpack(self._unframe(support, data))
        except support.FieldError as error:
            raise ValueError(f"{self.name}: cannot decode: {error}") from None

    def _unframe(self, support, data):
        msgpack = support._msgpack()
        try:
            frame = msgpack.unpackb(data, raw=False, use_list=True, strict_map_key=False)
        except msgpack.ExtraData as extra:
            raise support.FieldError(f"{len(extra.extra)} trailing bytes after the value") from None
        except (ValueError, TypeError, msgpack.UnpackException) as error:
            raise support.FieldError(f"not a valid MessagePack encoding ({error})") from None
        if type(frame) is not list or len(frame) != 1:
            raise support.FieldError("expected an array holding the one value")
        return frame[0]

    def log_summary(self, value) -> str:
        return self._codec.summary(value, self._label)

    def __eq__(self, other) -> bool:
        return isinstance(other, PlainValue) and other.name == self.name

    def __hash__(self) -> int:
        return hash(self.name)

    def __repr__(self) -> str:
        return f"horus.plain_value({self.name!r})"


def _resolve(name: str):
    """(codec, element label, alignment or None for a serialized type) of a type's spelling."""
    support = _codecs()
    if name in _SCALARS:
        codec = support.BOOL if name == "bool" else getattr(support, name.upper())
        return codec, "", codec.size
    if name == "String":
        return support.STR, "", None
    array = _ARRAY.match(name)
    if array is not None:
        element_name, length = array.group(1), int(array.group(2))
        element, _label, alignment = _resolve(element_name)
        if alignment is None:
            raise ValueError(f"plain value {name!r}: an array's elements have a fixed size "
                             f"(numbers, bool, arrays of them), not {element_name}")
        if isinstance(element, support.NumArray):
            codec = support.NumArray(element.element, (length, *element.shape))
        else:
            codec = support.NumArray(element, (length,))
        return codec, element_name, alignment
    vec = _VEC.match(name)
    if vec is not None:
        element_name = vec.group(1)
        element, _label, _alignment = _resolve(element_name)
        return (support.BYTES if element_name == "u8" else support.Vec(element)), element_name, None
    raise ValueError(f"not a plain value type: {name!r} (bool, i8..i64, u8..u64, f32, f64, "
                     "String, [T; N], Vec<T>)")


def _numpy_name(spec) -> str:
    import numpy

    dtype = numpy.dtype(spec)
    if dtype.subdtype is not None:
        base, shape = dtype.subdtype
        name = _numpy_name(base)
        for length in reversed(shape):
            name = f"[{name}; {length}]"
        return name
    kind = _NUMPY_KINDS.get(dtype.kind)
    if kind is None or dtype.byteorder == ">" or (kind == "f" and dtype.itemsize not in (4, 8)):
        raise ValueError(f"numpy {dtype} is not a plain value type")
    return kind if kind == "bool" else f"{kind}{8 * dtype.itemsize}"


def plain_value(spec) -> PlainValue:
    """The plain value type `spec` stands for: float, int, bool, str or bytes; a schema spelling
    ("f32", "[f32; 3]", "Vec<u8>"); a numpy scalar type or dtype; or a PlainValue. ValueError
    for anything else."""
    if isinstance(spec, PlainValue):
        return spec
    if isinstance(spec, str):
        return PlainValue(spec)
    if isinstance(spec, type) and spec in _PYTHON_TYPES:
        return PlainValue(_PYTHON_TYPES[spec])
    if _is_numpy(spec):
        return PlainValue(_numpy_name(spec))
    raise ValueError(f"not a plain value type: {spec!r}")


def plain_value_of(spec) -> PlainValue | None:
    """plain_value(spec), or None when `spec` is no plain value type (a message class, dict)."""
    if isinstance(spec, (PlainValue, str)) or _is_numpy(spec) or (
            isinstance(spec, type) and spec in _PYTHON_TYPES):
        return plain_value(spec)
    return None


def python_spelling(name: str) -> str:
    """How Python code names the plain value type `name`: float for f64, else its spelling."""
    return next((cls.__name__ for cls, spelled in _PYTHON_TYPES.items() if spelled == name),
                repr(name))


def _is_numpy(spec) -> bool:
    module = type(spec).__module__ if not isinstance(spec, type) else spec.__module__
    return module.split(".", 1)[0] == "numpy"
