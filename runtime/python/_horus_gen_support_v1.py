"""_horus_gen_support_v1: what the generated message classes have in common, in one place.

The name carries a version: a change that breaks generated modules of an older horus-gen gets a new
module name, so output roots of different horus-gen versions can share sys.path.

Encoding rules mirror the C++ side exactly (horus/codec.hpp, horus/msgpack.hpp over msgpack-cxx,
horus/log_summary.hpp), so both languages write and read the same bytes and print the same lines:

- POD messages are the C++ struct bytes, padding zeroed; each class packs itself with a struct.Struct
  spelled by horus-gen from the resolved layout.
- Serialized messages are MessagePack: a message is an array of its fields, integers in their
  smallest form, and (as msgpack-cxx does) a float whose value is integral and within the
  int64/uint64 range is written as an integer; other f32 values as float32, f64 values as float64.

numpy and msgpack are imported on first use, so importing a generated package stays cheap.
"""
from __future__ import annotations

import math
import operator
import struct

_NP = None
_MSGPACK = None


def _numpy():
    global _NP
    if _NP is None:
        import numpy
        _NP = numpy
    return _NP


def _msgpack():
    global _MSGPACK
    if _MSGPACK is None:
        import msgpack
        _MSGPACK = msgpack
    return _MSGPACK


class FieldError(ValueError):
    """A value that cannot be encoded or decoded; `path` says where inside the message it sits."""

    def __init__(self, reason: str, path: str = "") -> None:
        super().__init__(reason)
        self.reason = reason
        self.path = path

    def within(self, segment: str) -> "FieldError":
        if not self.path:
            self.path = segment
        elif self.path.startswith("["):
            self.path = segment + self.path
        else:
            self.path = segment + "." + self.path
        return self

    def __str__(self) -> str:
        return f"field '{self.path}': {self.reason}" if self.path else self.reason


# Errors a value of the wrong type or range raises from struct, numpy or the codecs below.
ENCODE_ERRORS = (FieldError, struct.error, TypeError, ValueError, OverflowError, AttributeError, IndexError)


def _kind(value) -> str:
    return type(value).__name__


# -- MessagePack writing --------------------------------------------------------------------------

_B = struct.Struct(">BB").pack
_H = struct.Struct(">BH").pack
_I = struct.Struct(">BI").pack
_Q = struct.Struct(">BQ").pack
_b = struct.Struct(">Bb").pack
_h = struct.Struct(">Bh").pack
_i = struct.Struct(">Bi").pack
_q = struct.Struct(">Bq").pack
_F32 = struct.Struct(">f")
_F64 = struct.Struct(">d").pack
_FIX = tuple(bytes((n,)) for n in range(256))
_TWO_64 = 18446744073709551616.0
_MINUS_TWO_63 = -9223372036854775808.0


def pack_int(out: list, v: int) -> None:
    if v >= 0:
        if v < 0x80:
            out.append(_FIX[v])
        elif v < 0x100:
            out.append(_B(0xCC, v))
        elif v < 0x10000:
            out.append(_H(0xCD, v))
        elif v < 0x100000000:
            out.append(_I(0xCE, v))
        else:
            out.append(_Q(0xCF, v))
    elif v >= -32:
        out.append(_FIX[v & 0xFF])
    elif v >= -0x80:
        out.append(_b(0xD0, v))
    elif v >= -0x8000:
        out.append(_h(0xD1, v))
    elif v >= -0x80000000:
        out.append(_i(0xD2, v))
    else:
        out.append(_q(0xD3, v))


def pack_array_header(out: list, n: int) -> None:
    if n < 16:
        out.append(_FIX[0x90 | n])
    elif n < 0x10000:
        out.append(_H(0xDC, n))
    else:
        out.append(_I(0xDD, n))


def _array_header(n: int) -> bytes:
    out: list = []
    pack_array_header(out, n)
    return b"".join(out)


def pack_str(out: list, text) -> None:
    if type(text) is not str:
        raise FieldError(f"expected str, got {_kind(text)}")
    data = text.encode("utf-8")
    n = len(data)
    if n < 32:
        out.append(_FIX[0xA0 | n])
    elif n < 0x100:
        out.append(_B(0xD9, n))
    elif n < 0x10000:
        out.append(_H(0xDA, n))
    else:
        out.append(_I(0xDB, n))
    out.append(data)


def _as_bytes(value) -> bytes:
    if type(value) is bytes:
        return value
    if isinstance(value, (bytearray, memoryview)):
        return bytes(value)
    np = _numpy()
    if isinstance(value, np.ndarray):
        if value.dtype != np.uint8:
            raise FieldError(f"expected bytes or a uint8 array, got an array of {value.dtype}")
        return value.tobytes()
    if isinstance(value, (str, int, float)) or value is None:
        raise FieldError(f"expected bytes, got {_kind(value)}")
    try:
        return bytes(value)
    except (TypeError, ValueError) as error:
        raise FieldError(f"expected bytes: {error}") from None


def pack_bin(out: list, data: bytes) -> None:
    n = len(data)
    if n < 0x100:
        out.append(_B(0xC4, n))
    elif n < 0x10000:
        out.append(_H(0xC5, n))
    else:
        out.append(_I(0xC6, n))
    out.append(data)


# -- log summaries (horus/log_summary.hpp) -------------------------------------------------------

MAX_NUMBERS_SHOWN = 8
MAX_ELEMENTS_SHOWN = 4


def fmt_g(x: float) -> str:
    """printf("%g") of a double, as glibc prints it (NaN keeps its sign: -nan)."""
    if x != x:
        return "-nan" if math.copysign(1.0, x) < 0 else "nan"
    return "%g" % x


def _numbers(values: list, label: str, show) -> str:
    count = len(values)
    if count == 0:
        return "[]"
    if count > MAX_NUMBERS_SHOWN:
        lo = hi = values[0]
        for e in values:  # the C++ loop, NaN and -0.0 included: not min()/max()
            if e < lo:
                lo = e
            if hi < e:
                hi = e
        return f"[{count} x {label}, min {fmt_g(float(lo))}, max {fmt_g(float(hi))}]"
    return "[" + ", ".join(show(e) for e in values) + "]"


def _elements(values, label: str, element: "Codec") -> str:
    count = len(values)
    if count == 0:
        return "[]"
    if count > MAX_ELEMENTS_SHOWN:
        return f"[{count} x {label}]"
    return "[" + ", ".join(element.summary(e, "") for e in values) + "]"


# -- codecs: one per field type, composed for arrays, Vec and Option ------------------------------

class Codec:
    """How one schema type is checked, written, read and summarised in both encodings."""
    __slots__ = ()
    numeric = False  # a number in log_summary's sense (not bool)
    size = 0  # bytes in a POD struct
    fmt = ""  # struct format of one value in a POD struct, when it has one

    def default(self):
        raise NotImplementedError

    def coerce(self, value):
        return value

    def eq(self, a, b) -> bool:
        return a == b

    # POD bytes of one value at `off` of `buf`, for views and for the generic (diagnostic) path.
    def raw_into(self, buf, off: int, value) -> None:
        struct.pack_into("<" + self.fmt, buf, off, self.raw(value))

    def raw(self, value):
        return value

    def raw_from(self, buf, off: int):
        return self.from_raw(struct.unpack_from("<" + self.fmt, buf, off)[0])

    def from_raw(self, value):
        return value

    def view_get(self, buf, off: int):
        return self.raw_from(buf, off)

    def np_format(self):
        return "<" + self.fmt


class Bool(Codec):
    __slots__ = ()
    size, fmt = 1, "?"

    def default(self):
        return False

    def pack(self, out: list, v) -> None:
        out.append(b"\xc3" if v else b"\xc2")

    def unpack(self, obj):
        if type(obj) is not bool:
            raise FieldError(f"expected bool, got {_kind(obj)}")
        return obj

    def summary(self, v, label: str) -> str:
        return "true" if v else "false"

    def np_format(self):
        return "?"


class Int(Codec):
    __slots__ = ("name", "lo", "hi", "size", "fmt")
    numeric = True

    def __init__(self, name: str, fmt: str, size: int, signed: bool) -> None:
        self.name, self.fmt, self.size = name, fmt, size
        bits = size * 8
        self.lo, self.hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)

    def default(self):
        return 0

    def value(self, v) -> int:
        try:
            v = operator.index(v)
        except TypeError:
            raise FieldError(f"expected an integer, got {_kind(v)}") from None
        if not self.lo <= v <= self.hi:
            raise FieldError(f"{v} is out of range for {self.name} ({self.lo}..{self.hi})")
        return v

    def pack(self, out: list, v) -> None:
        pack_int(out, self.value(v))

    def unpack(self, obj):
        if type(obj) is not int:
            raise FieldError(f"expected an integer ({self.name}), got {_kind(obj)}")
        if not self.lo <= obj <= self.hi:
            raise FieldError(f"{obj} is out of range for {self.name} ({self.lo}..{self.hi})")
        return obj

    def raw(self, v):
        return self.value(v)

    def summary(self, v, label: str) -> str:
        return str(int(v))

    def number(self, v):
        return int(v)

    def show(self, v) -> str:
        return str(v)


def _f32(v: float) -> float:
    try:
        return _F32.unpack(_F32.pack(v))[0]
    except OverflowError:
        return math.copysign(math.inf, v)


class Float(Codec):
    __slots__ = ("single", "size", "fmt", "name")
    numeric = True

    def __init__(self, single: bool) -> None:
        self.single = single
        self.size, self.fmt, self.name = (4, "f", "f32") if single else (8, "d", "f64")

    def default(self):
        return 0.0

    def value(self, v) -> float:
        if type(v) is not float:
            if isinstance(v, (str, bytes)) or v is None:
                raise FieldError(f"expected a number, got {_kind(v)}")
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise FieldError(f"expected a number, got {_kind(v)}") from None
        if self.single:
            try:
                v = _F32.unpack(_F32.pack(v))[0]
            except OverflowError:
                raise FieldError(f"{v!r} is out of range for f32") from None
        return v

    def pack(self, out: list, v) -> None:
        d = self.value(v)
        if d == d and _MINUS_TWO_63 <= d < _TWO_64 and d == int(d):
            pack_int(out, int(d))
        elif self.single:
            out.append(b"\xca" + _F32.pack(d))
        else:
            out.append(b"\xcb" + _F64(d))

    def unpack(self, obj):
        t = type(obj)
        if t is float:
            return _f32(obj) if self.single else obj
        if t is int:
            return _f32(float(obj)) if self.single else float(obj)
        raise FieldError(f"expected a number ({self.name}), got {_kind(obj)}")

    def raw(self, v):
        return self.value(v)

    def eq(self, a, b) -> bool:
        if self.single:
            try:
                return _f32(float(a)) == _f32(float(b))
            except (TypeError, ValueError):
                return False
        return a == b

    def summary(self, v, label: str) -> str:
        return fmt_g(self.number(v))

    def number(self, v):
        return _f32(float(v)) if self.single else float(v)

    def show(self, v) -> str:
        return fmt_g(v)


BOOL = Bool()
U8, U16, U32, U64 = (Int(f"u{8 * n}", f, n, False) for f, n in (("B", 1), ("H", 2), ("I", 4), ("Q", 8)))
I8, I16, I32, I64 = (Int(f"i{8 * n}", f, n, True) for f, n in (("b", 1), ("h", 2), ("i", 4), ("q", 8)))
F32, F64 = Float(True), Float(False)


class Enum(Codec):
    __slots__ = ("cls", "base", "members", "size", "fmt")

    def __init__(self, cls, base: Int) -> None:
        self.cls, self.base, self.members = cls, base, cls._value2member_map_
        self.size, self.fmt = base.size, base.fmt

    def default(self):
        return self.members.get(0, 0)

    def pack(self, out: list, v) -> None:
        pack_int(out, self.base.value(v))

    def unpack(self, obj):
        v = self.base.unpack(obj)
        return self.members.get(v, v)

    def raw(self, v):
        return self.base.value(v)

    def from_raw(self, v):
        return self.members.get(v, v)

    def summary(self, v, label: str) -> str:
        member = self.members.get(int(v))
        return member.name if member is not None else str(int(v))


class FixedStr(Codec):
    """string<N>: str in Python; N bytes NUL-padded in POD structs; a msgpack str."""
    __slots__ = ("size", "fmt")

    def __init__(self, capacity: int) -> None:
        self.size, self.fmt = capacity, f"{capacity}s"

    def default(self):
        return ""

    def raw(self, v) -> bytes:
        if type(v) is not str:
            raise FieldError(f"expected str, got {_kind(v)}")
        data = v.encode("utf-8")
        if len(data) > self.size:
            raise FieldError(f"{v!r} is {len(data)} bytes, string<{self.size}> holds at most {self.size}")
        if b"\0" in data:
            raise FieldError(f"{v!r} contains a NUL character, which string<{self.size}> cannot hold")
        return data

    def from_raw(self, data: bytes) -> str:
        try:
            return data.split(b"\0", 1)[0].decode("utf-8")
        except UnicodeDecodeError as error:
            raise FieldError(f"string<{self.size}> is not valid UTF-8 ({error.reason} at byte {error.start})") from None

    def pack(self, out: list, v) -> None:
        self.raw(v)
        pack_str(out, v)

    def unpack(self, obj):
        if type(obj) is not str:
            raise FieldError(f"expected str (string<{self.size}>), got {_kind(obj)}")
        n = len(obj.encode("utf-8"))
        if n > self.size:
            raise FieldError(f"a string of {n} bytes does not fit in string<{self.size}>")
        return obj.split("\0", 1)[0]

    def summary(self, v, label: str) -> str:
        return '"' + v + '"'

    def np_format(self):
        return f"S{self.size}"


class Str(Codec):
    __slots__ = ()

    def default(self):
        return ""

    def pack(self, out: list, v) -> None:
        pack_str(out, v)

    def unpack(self, obj):
        if type(obj) is str:
            return obj
        if type(obj) is bytes:  # msgpack-cxx reads a bin into std::string too
            try:
                return obj.decode("utf-8")
            except UnicodeDecodeError:
                raise FieldError("String is not valid UTF-8") from None
        raise FieldError(f"expected str, got {_kind(obj)}")

    def summary(self, v, label: str) -> str:
        return '"' + v + '"'


class Bytes(Codec):
    """bytes and Vec<u8>: bytes in Python, a msgpack bin."""
    __slots__ = ()

    def default(self):
        return b""

    def pack(self, out: list, v) -> None:
        pack_bin(out, _as_bytes(v))

    def unpack(self, obj):
        if type(obj) is bytes:
            return obj
        if type(obj) is str:  # msgpack-cxx reads a str into std::vector<std::uint8_t> too
            return obj.encode("utf-8")
        raise FieldError(f"expected bytes, got {_kind(obj)}")

    def eq(self, a, b) -> bool:
        try:
            return _as_bytes(a) == _as_bytes(b)
        except FieldError:
            return False

    def summary(self, v, label: str) -> str:
        return f"<{len(_as_bytes(v))} bytes>"


STR = Str()
BYTES = Bytes()


class NumArray(Codec):
    """[T; N] of numbers or bool (nested too): a numpy array of the C++ element type and shape."""
    __slots__ = ("element", "shape", "dtype_text", "count", "size", "initial", "_dtype", "bins", "kind")

    def __init__(self, element: Codec, shape: tuple, initial=None) -> None:
        self.element, self.shape, self.initial = element, shape, initial
        self.kind = "f" if isinstance(element, Float) else "b" if isinstance(element, Bool) else "i"
        self.dtype_text = element.np_format()
        self.count = math.prod(shape)
        self.size = self.count * element.size
        self.bins = element is U8  # msgpack-cxx writes std::array<std::uint8_t, N> as bin
        self._dtype = None

    @property
    def dtype(self):
        if self._dtype is None:
            self._dtype = _numpy().dtype(self.dtype_text)
        return self._dtype

    def default(self):
        np = _numpy()
        if self.initial is None:
            return np.zeros(self.shape, self.dtype)
        return self.coerce(self.initial)

    def coerce(self, value):
        np = _NP or _numpy()
        target = self._dtype or self.dtype
        if type(value) is np.ndarray:
            if value.dtype == target and value.shape == self.shape:
                return value.copy()
            a = value
        else:
            try:
                a = np.array(value)
            except (TypeError, ValueError) as error:
                raise FieldError(f"expected an array of shape {self.shape}: {error}") from None
        if a.shape != self.shape:
            raise FieldError(f"expected an array of shape {self.shape}, got shape {a.shape}")
        kind, have = self.kind, a.dtype.kind
        if kind == "f":
            if have not in "iufb":
                raise FieldError(f"expected numbers, got an array of {a.dtype}")
            if self.element.single and have == "f" and a.size:
                finite = a[np.isfinite(a)]
                if finite.size and float(np.abs(finite).max()) > 3.4028234663852886e38:
                    raise FieldError("a value is out of range for f32")
        elif kind == "b":
            if have not in "biu":
                raise FieldError(f"expected bools, got an array of {a.dtype}")
        else:
            if have not in "iub":
                raise FieldError(f"expected integers ({self.element.name}), got an array of {a.dtype}")
            if a.size and have != "b":
                lo, hi = int(a.min()), int(a.max())
                if lo < self.element.lo or hi > self.element.hi:
                    bad = lo if lo < self.element.lo else hi
                    raise FieldError(f"{bad} is out of range for {self.element.name} "
                                     f"({self.element.lo}..{self.element.hi})")
        if a is not value and a.dtype == target:
            return a  # already a fresh array of the right type: no second copy
        return a.astype(target)

    def raw(self, value) -> bytes:
        np = _NP or _numpy()
        if type(value) is np.ndarray and value.dtype == self.dtype and value.shape == self.shape:
            return value.tobytes()
        return self.coerce(value).tobytes()

    def raw_into(self, buf, off: int, value) -> None:
        buf[off:off + self.size] = self.raw(value)

    def raw_from(self, buf, off: int):
        a = (_NP or _numpy()).frombuffer(buf, self.dtype, self.count, off)
        return a.reshape(self.shape) if len(self.shape) > 1 else a

    def eq(self, a, b) -> bool:
        np = _numpy()
        try:
            return bool(np.array_equal(np.asarray(a, self.dtype), np.asarray(b, self.dtype)))
        except (TypeError, ValueError, OverflowError):
            return False

    def pack(self, out: list, value) -> None:
        a = self.coerce(value) if not (type(value) is (_NP or _numpy()).ndarray and value.dtype == self.dtype
                                       and value.shape == self.shape) else value
        self._pack_level(out, a, 0)

    def _pack_level(self, out: list, a, depth: int) -> None:
        if depth == len(self.shape) - 1:
            if self.bins:
                pack_bin(out, a.tobytes())
                return
            pack_array_header(out, self.shape[depth])
            element = self.element
            for v in a.tolist():
                element.pack(out, v)
            return
        pack_array_header(out, self.shape[depth])
        for row in a:
            self._pack_level(out, row, depth + 1)

    def unpack(self, obj):
        values = self._unpack_level(obj, 0)
        return (_NP or _numpy()).array(values, self.dtype).reshape(self.shape)

    def _unpack_level(self, obj, depth: int):
        n = self.shape[depth]
        if depth == len(self.shape) - 1 and self.bins:
            if type(obj) is not bytes:
                raise FieldError(f"expected bin of {n} bytes, got {_kind(obj)}")
            if len(obj) != n:
                raise FieldError(f"expected {n} bytes, got {len(obj)}")
            return list(obj)
        if type(obj) is not list:
            raise FieldError(f"expected an array of {n} elements, got {_kind(obj)}")
        if len(obj) != n:
            raise FieldError(f"expected {n} elements, got {len(obj)}")
        out = []
        for i, e in enumerate(obj):
            try:
                out.append(self.element.unpack(e) if depth == len(self.shape) - 1 else self._unpack_level(e, depth + 1))
            except FieldError as error:
                raise error.within(f"[{i}]") from None
        return out

    def summary(self, v, label: str) -> str:
        a = (_NP or _numpy()).asarray(v, self.dtype)
        return self._summary_level(a, label)

    def _summary_level(self, a, label: str) -> str:
        if a.ndim > 1:
            count = a.shape[0]
            if count == 0:
                return "[]"
            if count > MAX_ELEMENTS_SHOWN:
                return f"[{count} x {label}]"
            return "[" + ", ".join(self._summary_level(row, "") for row in a) + "]"
        if self.bins:
            return f"<{a.shape[0]} bytes>"
        if self.element.numeric:
            return _numbers(a.tolist(), label, self.element.show)
        return _elements(a.tolist(), label, self.element)

    def np_format(self):
        return (self.dtype_text, self.shape)


class ListArray(Codec):
    """[T; N] of strings, enums or messages: a list of N values."""
    __slots__ = ("element", "length", "size", "initial")

    def __init__(self, element: Codec, length: int, initial=None) -> None:
        self.element, self.length, self.initial = element, length, initial
        self.size = element.size * length

    def default(self):
        if self.initial is None:
            return [self.element.default() for _ in range(self.length)]
        return [self.element.coerce(v) for v in self.initial]

    def coerce(self, value):
        return list(value)

    def _check_length(self, value) -> None:
        try:
            n = len(value)
        except TypeError:
            raise FieldError(f"expected a sequence of {self.length} elements, got {_kind(value)}") from None
        if n != self.length:
            raise FieldError(f"expected {self.length} elements, got {n}")

    def eq(self, a, b) -> bool:
        try:
            return len(a) == len(b) and all(self.element.eq(x, y) for x, y in zip(a, b))
        except TypeError:
            return False

    def pack(self, out: list, value) -> None:
        self._check_length(value)
        pack_array_header(out, self.length)
        element = self.element
        for i, v in enumerate(value):
            try:
                element.pack(out, v)
            except FieldError as error:
                raise error.within(f"[{i}]") from None
            except ENCODE_ERRORS as error:
                raise FieldError(str(error)).within(f"[{i}]") from None

    def unpack(self, obj):
        if type(obj) is not list:
            raise FieldError(f"expected an array of {self.length} elements, got {_kind(obj)}")
        if len(obj) != self.length:
            raise FieldError(f"expected {self.length} elements, got {len(obj)}")
        return _unpack_list(self.element, obj)

    def raw_into(self, buf, off: int, value) -> None:
        self._check_length(value)
        step = self.element.size
        for i, v in enumerate(value):
            self.element.raw_into(buf, off + i * step, v)

    def raw_from(self, buf, off: int):
        step = self.element.size
        out = []
        for i in range(self.length):
            try:
                out.append(self.element.raw_from(buf, off + i * step))
            except FieldError as error:
                raise error.within(f"[{i}]") from None
        return out

    def view_get(self, buf, off: int):
        step = self.element.size
        return [self.element.view_get(buf, off + i * step) for i in range(self.length)]

    def summary(self, v, label: str) -> str:
        return _elements(v, label, self.element)

    def np_format(self):
        inner = self.element.np_format()
        if isinstance(inner, tuple):
            return (inner[0], (self.length,) + inner[1])
        return (inner, (self.length,))


def _unpack_list(element: Codec, obj: list) -> list:
    unpack = element.unpack
    try:
        return [unpack(e) for e in obj]
    except FieldError:
        for i, e in enumerate(obj):
            try:
                unpack(e)
            except FieldError as error:
                raise error.within(f"[{i}]") from None
        raise


class Vec(Codec):
    """Vec<T>: a list (any sequence, numpy arrays included, is accepted when writing)."""
    __slots__ = ("element",)

    def __init__(self, element: Codec) -> None:
        self.element = element

    def default(self):
        return []

    def eq(self, a, b) -> bool:
        try:
            return len(a) == len(b) and all(self.element.eq(x, y) for x, y in zip(a, b))
        except TypeError:
            return False

    def pack(self, out: list, value) -> None:
        if isinstance(value, (str, bytes)) or value is None:
            raise FieldError(f"expected a sequence, got {_kind(value)}")
        if _NP is not None and type(value) is _NP.ndarray:
            value = value.tolist()
        try:
            n = len(value)
        except TypeError:
            raise FieldError(f"expected a sequence, got {_kind(value)}") from None
        pack_array_header(out, n)
        element = self.element
        for i, v in enumerate(value):
            try:
                element.pack(out, v)
            except FieldError as error:
                raise error.within(f"[{i}]") from None
            except ENCODE_ERRORS as error:
                raise FieldError(str(error)).within(f"[{i}]") from None

    def unpack(self, obj):
        if type(obj) is not list:
            raise FieldError(f"expected an array, got {_kind(obj)}")
        return _unpack_list(self.element, obj)

    def summary(self, v, label: str) -> str:
        if _NP is not None and type(v) is _NP.ndarray:
            v = v.tolist()
        if self.element.numeric:
            return _numbers([self.element.number(e) for e in v], label, self.element.show)
        return _elements(v, label, self.element)


class Option(Codec):
    """Option<T>: the value or None (msgpack nil)."""
    __slots__ = ("element",)

    def __init__(self, element: Codec) -> None:
        self.element = element

    def default(self):
        return None

    def eq(self, a, b) -> bool:
        if a is None or b is None:
            return a is None and b is None
        return self.element.eq(a, b)

    def pack(self, out: list, value) -> None:
        if value is None:
            out.append(b"\xc0")
        else:
            self.element.pack(out, value)

    def unpack(self, obj):
        return None if obj is None else self.element.unpack(obj)

    def summary(self, v, label: str) -> str:
        return "none" if v is None else self.element.summary(v, label)


class Nested(Codec):
    """A nested message: an instance of its generated class."""
    __slots__ = ("cls", "size")

    def __init__(self, cls) -> None:
        self.cls = cls
        self.size = cls.__horus__.size or 0

    def default(self):
        return self.cls()

    def _instance(self, v):
        if not isinstance(v, self.cls):
            raise FieldError(f"expected {self.cls.__horus__.name}, got {_kind(v)}")
        return v

    def pack(self, out: list, v) -> None:
        self._instance(v)._horus_pack(out)

    def unpack(self, obj):
        return self.cls._horus_from_obj(obj)

    def raw_into(self, buf, off: int, v) -> None:
        self._instance(v)._horus_pack_into(buf, off)

    def raw_from(self, buf, off: int):
        return self.cls._horus_unpack_from(buf, off)

    def view_get(self, buf, off: int):
        return self.cls.view(buf, off)

    def summary(self, v, label: str) -> str:
        return v.log_summary()

    def np_format(self):
        return self.cls.__horus__.dtype


# -- type information -----------------------------------------------------------------------------

class TypeInfo:
    """`T.__horus__`: a generated message's identity and layout (generated-api.md), and what the
    generic methods below need: field names, their codecs and offsets, the summary parts."""
    __slots__ = ("name", "package", "fingerprint", "is_pod", "size", "alignment", "schema", "topic",
                 "fields", "codecs", "offsets", "summary", "header", "owner", "_dtype")

    def __init__(self, name: str, package: str, fingerprint: int, is_pod: bool, size: int | None,
                 alignment: int | None, schema: str, topic: str | None, fields: tuple, codecs: tuple,
                 offsets: tuple, summary: tuple) -> None:
        self.name, self.package, self.fingerprint, self.is_pod = name, package, fingerprint, is_pod
        self.size, self.alignment, self.schema, self.topic = size, alignment, schema, topic
        self.fields, self.codecs, self.offsets, self.summary = fields, codecs, offsets, summary
        self.header = _array_header(len(fields))
        self.owner = None
        self._dtype = None

    @property
    def dtype(self):
        """numpy structured dtype with the C++ field offsets and itemsize (POD messages only)."""
        if not self.is_pod:
            raise AttributeError(f"{self.name} is a serialized message: it has no fixed layout and no dtype")
        if self._dtype is None:
            self._dtype = _numpy().dtype({
                "names": list(self.fields),
                "formats": [codec.np_format() for codec in self.codecs],
                "offsets": list(self.offsets),
                "itemsize": self.size})
        return self._dtype

    def __repr__(self) -> str:
        return f"<horus type {self.name} fingerprint 0x{self.fingerprint:016x}>"


class EnumInfo:
    """`E.__horus__` of a generated enum."""
    __slots__ = ("name", "package", "fingerprint", "schema", "underlying")

    def __init__(self, name: str, package: str, fingerprint: int, schema: str, underlying: str) -> None:
        self.name, self.package, self.fingerprint = name, package, fingerprint
        self.schema, self.underlying = schema, underlying

    def __repr__(self) -> str:
        return f"<horus enum {self.name} fingerprint 0x{self.fingerprint:016x}>"


# -- the message base classes ---------------------------------------------------------------------

class Message:
    """Base of every generated message class: equality, repr, MessagePack, log summary."""
    __slots__ = ()
    __horus__: TypeInfo

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        info = cls.__dict__.get("__horus__")
        if info is not None:
            info.owner = cls

    def __eq__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        info = self.__horus__
        for name, codec in zip(info.fields, info.codecs):
            if not codec.eq(getattr(self, name), getattr(other, name)):
                return False
        return True

    __hash__ = None

    def __repr__(self) -> str:
        body = ", ".join(f"{name}={getattr(self, name)!r}" for name in self.__horus__.fields)
        return f"{type(self).__name__}({body})"

    def log_summary(self) -> str:
        """One line for logs, the same text C++'s log_summary() gives for the same values."""
        info = self.__horus__
        parts = []
        for text, index, label, unit in info.summary:
            if index is None:
                parts.append(text)
                continue
            parts.append(info.codecs[index].summary(getattr(self, info.fields[index]), label))
            if unit:
                parts.append(" " + unit)
        return "".join(parts)

    # MessagePack: an array of the fields in declaration order.
    def _horus_pack(self, out: list) -> None:
        info = self.__horus__
        out.append(info.header)
        for name, codec in zip(info.fields, info.codecs):
            try:
                codec.pack(out, getattr(self, name))
            except FieldError as error:
                raise error.within(name) from None
            except ENCODE_ERRORS as error:
                raise FieldError(str(error)).within(name) from None

    @classmethod
    def _horus_from_obj(cls, obj):
        info = cls.__horus__
        n = len(info.fields)
        if type(obj) is not list:
            raise FieldError(f"expected {info.name} as an array of {n} fields, got {_kind(obj)}")
        if len(obj) != n:
            raise FieldError(f"expected {info.name} as an array of {n} fields, got {len(obj)}")
        self = cls.__new__(cls)
        for name, codec, value in zip(info.fields, info.codecs, obj):
            try:
                setattr(self, name, codec.unpack(value))
            except FieldError as error:
                raise error.within(name) from None
        return self

    def _horus_encode_error(self, error: Exception) -> ValueError:
        """A clear error for a failed to_bytes(): which field, and what is wrong with it."""
        name = self.__horus__.name
        try:
            self._horus_pack([])
        except FieldError as found:
            return ValueError(f"{name}: cannot encode: {found}")
        return ValueError(f"{name}: cannot encode: {error}")


def _decode_msgpack(cls, data):
    name = cls.__horus__.name
    msgpack = _MSGPACK or _msgpack()
    try:
        obj = msgpack.unpackb(data, raw=False, use_list=True, strict_map_key=False)
    except msgpack.ExtraData as extra:
        raise ValueError(f"{name}: {len(extra.extra)} trailing bytes after the message") from None
    except (ValueError, TypeError, msgpack.UnpackException) as error:
        raise ValueError(f"{name}: not a valid MessagePack encoding ({error})") from None
    try:
        return cls._horus_from_obj(obj)
    except FieldError as error:
        raise ValueError(f"{name}: cannot decode: {error}") from None


class SerializedMessage(Message):
    """A message with a String, Vec, Option or bytes field: carried as MessagePack."""
    __slots__ = ()

    def to_bytes(self) -> bytes:
        """The MessagePack bytes horus::encode writes in C++ for the same values."""
        out: list = []
        try:
            self._horus_pack(out)
        except FieldError as error:
            raise ValueError(f"{self.__horus__.name}: cannot encode: {error}") from None
        return b"".join(out)

    @classmethod
    def from_bytes(cls, data):
        """The message `data` encodes; ValueError when it is not one."""
        return _decode_msgpack(cls, data)


class PodMessage(Message):
    """A message of fixed layout: its bytes are the C++ struct's, padding zeroed."""
    __slots__ = ()

    def to_bytes(self) -> bytes:
        """The C++ struct bytes (what horus::encode writes), padding zeroed."""
        buf = bytearray(self.__horus__.size)
        try:
            self._horus_pack_into(buf, 0)
        except ENCODE_ERRORS as error:
            raise self._horus_encode_error(error) from None
        return bytes(buf)

    @classmethod
    def from_bytes(cls, data):
        """The message whose C++ struct bytes are `data`; ValueError when the length is wrong."""
        try:
            buf = bytearray(memoryview(data).cast("B"))
        except TypeError:
            raise ValueError(f"{cls.__horus__.name}: expected a bytes-like object, got {_kind(data)}") from None
        if len(buf) != cls.__horus__.size:
            raise ValueError(f"{cls.__horus__.name}: expected {cls.__horus__.size} bytes, got {len(buf)}")
        try:
            return cls._horus_unpack_from(buf, 0)
        except FieldError:
            raise _raw_decode_error(cls, buf) from None

    @classmethod
    def view(cls, buffer, offset: int = 0):
        """A view whose attributes read and write `buffer` in place (zero copy): a shared-memory
        slot, a bytearray, a numpy array. Writes raise TypeError when the buffer is read-only."""
        return _view_class(cls)(buffer, offset)


def _raw_decode_error(cls, buf) -> ValueError:
    found = _raw_error(cls, buf, 0)
    return ValueError(f"{cls.__horus__.name}: cannot decode: {found if found else 'invalid bytes'}")


def _raw_error(cls, buf, base: int) -> FieldError | None:
    """The first field of `cls` at `base` of `buf` that does not decode, with its path."""
    info = cls.__horus__
    for name, codec, offset in zip(info.fields, info.codecs, info.offsets):
        if isinstance(codec, Nested):
            found = _raw_error(codec.cls, buf, base + offset)
        else:
            try:
                codec.raw_from(buf, base + offset)
                found = None
            except FieldError as error:
                found = error
        if found is not None:
            return found.within(name)
    return None


# -- zero-copy views ------------------------------------------------------------------------------

class View:
    """Base of the view classes made (once per message class) by `T.view(buffer)`."""
    __slots__ = ("_horus_buf", "_horus_off")
    _horus_message = None

    def __init__(self, buffer, offset: int = 0) -> None:
        cls = self._horus_message
        try:
            mv = memoryview(buffer)
        except TypeError:
            raise TypeError(f"{cls.__horus__.name}.view: expected a buffer (bytearray, memoryview, numpy "
                            f"array, shared memory), got {_kind(buffer)}") from None
        if mv.format != "B" or mv.ndim != 1:
            mv = mv.cast("B")
        size = cls.__horus__.size
        if offset < 0 or offset + size > mv.nbytes:
            raise ValueError(f"{cls.__horus__.name}.view: the buffer holds {mv.nbytes} bytes, the message "
                             f"needs {size} from offset {offset}")
        self._horus_buf, self._horus_off = mv, offset

    def to_message(self):
        """An owning copy of the viewed message."""
        cls = self._horus_message
        return cls.from_bytes(self._horus_buf[self._horus_off:self._horus_off + cls.__horus__.size])

    def assign(self, message) -> None:
        """Writes `message` into the viewed bytes (padding zeroed)."""
        cls = self._horus_message
        if not isinstance(message, cls):
            raise TypeError(f"{cls.__horus__.name}.view: cannot assign a {_kind(message)}")
        try:
            message._horus_pack_into(self._horus_buf, self._horus_off)
        except ENCODE_ERRORS as error:
            raise message._horus_encode_error(error) from None

    def log_summary(self) -> str:
        return self.to_message().log_summary()

    def __repr__(self) -> str:
        return f"<view of {self.to_message()!r}>"

    def __eq__(self, other):
        if isinstance(other, View):
            other = other.to_message()
        return self.to_message() == other

    __hash__ = None


class _ViewField:
    __slots__ = ("name", "codec", "offset")

    def __init__(self, name: str, codec: Codec, offset: int) -> None:
        self.name, self.codec, self.offset = name, codec, offset

    def __get__(self, view, owner=None):
        if view is None:
            return self
        try:
            return self.codec.view_get(view._horus_buf, view._horus_off + self.offset)
        except FieldError as error:
            raise ValueError(f"{view._horus_message.__horus__.name}: {error.within(self.name)}") from None

    def __set__(self, view, value) -> None:
        try:
            self.codec.raw_into(view._horus_buf, view._horus_off + self.offset, value)
        except FieldError as error:
            raise ValueError(f"{view._horus_message.__horus__.name}: {error.within(self.name)}") from None
        except struct.error as error:
            raise ValueError(f"{view._horus_message.__horus__.name}: field '{self.name}': {error}") from None


_VIEWS: dict = {}


def _view_class(cls):
    found = _VIEWS.get(cls)
    if found is None:
        body = {name: _ViewField(name, codec, offset)
                for name, codec, offset in zip(cls.__horus__.fields, cls.__horus__.codecs, cls.__horus__.offsets)}
        body.update(__slots__=(), _horus_message=cls, __doc__=f"A zero-copy view of {cls.__horus__.name}.")
        found = _VIEWS[cls] = type(cls.__name__ + "View", (View,), body)
    return found
