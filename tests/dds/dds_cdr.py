"""CDR (XCDR1, the encoding of @final structs) of HORUS messages, as DDS programs built from the IDL
`horus-gen generate --lang idl` emits read and write them (docs/generated-code.md "IDL"): the
Python reference the tests (tests/dds/) check the C++ bridge's conversions against and write raw
samples with; the bridge itself converts in C++ (bridges/dds/).

The mapping follows that IDL member by member, driven by a generated class's codecs (generated
by horus-gen, or made by horus.typedesc from a description):

    bool, integers, f32, f64   -> themselves, aligned to their size (8 at most)
    enum                       -> its underlying integer
    String, string<N>          -> uint32 length with the NUL, the UTF-8 bytes, the NUL
    bytes, Vec<u8>, Vec<T>     -> uint32 count, the elements
    Option<T>                  -> sequence<T, 1>: count 0 or 1, the element
    [T; N]                     -> N elements, no count
    nested message             -> its members in place
    message without fields     -> ROS 2's one uint8 member

A sample is a 4-byte encapsulation header (CDR_LE, options = the pad count) and the body, padded
to a multiple of 4 as Cyclone DDS pads it. Reading takes big-endian CDR too.

    codec = CdrCodec(cls)
    cdr = codec.encode(message)        # bytes for horus._core.dds.Writer.write
    message = codec.decode(cdr)        # ValueError when the bytes do not fit the type

For a POD type, horus._core.dds.CdrPlan.from_description(cls.__horus__.description) is the same
mapping as steps over the struct bytes (C++, bridges/dds/).

CdrWriter and CdrReader write and read a sample member by member.

A pool-backed type's descriptor (Image's ImageDescriptor, ...) crosses with the data of the block
it names in place of its PoolBlock field, a sequence<uint8> as the IDL says: PoolCodec(cls)
encodes the descriptor (its block zeroed) followed by the block's data, and decodes a sample back
to such bytes, as the C++ bridge's PoolFrames record and replay them.
"""
from __future__ import annotations

import struct

__all__ = ["CdrCodec", "CdrReader", "CdrWriter", "PoolCodec"]

_CDR_BE, _CDR_LE = b"\x00\x00", b"\x00\x01"


class CdrCodec:
    """Encodes instances of the generated class `cls` to CDR samples and decodes them back."""

    def __init__(self, cls) -> None:
        self.cls = cls

    def encode(self, message) -> bytes:
        writer = CdrWriter()
        _write_message(writer.out, message)
        return writer.sample()

    def decode(self, data) -> object:
        return CdrReader.read_sample(data, self.cls.__horus__.name,
                                     lambda reader: _read_message(reader, self.cls))


class PoolCodec:
    """Frames of a pool-backed type: a descriptor and its block's data, to CDR and back."""

    POOL_BLOCK = "horus.msg.PoolBlock"

    def __init__(self, cls) -> None:
        info = cls.__horus__
        self.cls, self.size = cls, info.size
        self.block = next((name for name, codec in zip(info.fields, info.codecs)
                           if type(codec).__name__ == "Nested"
                           and codec.cls.__horus__.name == self.POOL_BLOCK), None)
        if self.block is None:
            raise TypeError(f"{info.name} has no {self.POOL_BLOCK} field: it is no pool descriptor")

    def encode(self, recorded: bytes) -> bytes:
        """The sample of a recorded frame: the descriptor's `size` bytes, then the data."""
        message = self.cls.from_bytes(recorded[:self.size])
        info = self.cls.__horus__
        writer = CdrWriter()
        for name, codec in zip(info.fields, info.codecs):
            if name == self.block:
                data = recorded[self.size:]
                writer.number("I", len(data))
                writer.out += data
            else:
                _write(writer.out, codec, getattr(message, name))
        return writer.sample()

    def decode(self, data) -> bytes:
        """The recorded frame of a sample (its block zeroed); ValueError when it does not fit."""
        info = self.cls.__horus__

        def read(reader: CdrReader) -> bytes:
            message, block_data = self.cls(), b""
            for name, codec in zip(info.fields, info.codecs):
                if name == self.block:
                    block_data = reader.raw(reader.count())
                else:
                    setattr(message, name, _read(reader, codec))
            return message.to_bytes() + block_data

        return CdrReader.read_sample(data, info.name, read)


class CdrWriter:
    """A sample's body, member by member; sample() adds the encapsulation and the padding."""

    def __init__(self) -> None:
        self.out = bytearray()

    def number(self, fmt: str, value) -> None:
        """One number of struct format `fmt` ("d", "f", "I", "i", "Q", ...) at its alignment."""
        _put(self.out, fmt, struct.calcsize(fmt), value)

    def numbers(self, fmt: str, values) -> None:
        """An array of numbers (no count), or a sequence's elements after count()."""
        size = struct.calcsize(fmt)
        _align(self.out, size)
        self.out += struct.pack(f"<{len(values)}{fmt}", *values)

    def string(self, text: str) -> None:
        _write_string(self.out, text)

    def sample(self) -> bytes:
        padding = -len(self.out) % 4
        return _CDR_LE + bytes((0, padding)) + bytes(self.out) + bytes(padding)


# -- writing --------------------------------------------------------------------------------------

def _align(out: bytearray, size: int) -> None:
    out += bytes(-len(out) % min(size, 8))


def _put(out: bytearray, fmt: str, size: int, value) -> None:
    _align(out, size)
    out += struct.pack("<" + fmt, value)


def _write_message(out: bytearray, message) -> None:
    info = type(message).__horus__
    if not info.fields:
        out.append(0)  # structure_needs_at_least_one_member
        return
    for name, codec in zip(info.fields, info.codecs):
        _write(out, codec, getattr(message, name))


def _write_string(out: bytearray, text: str) -> None:
    data = text.encode("utf-8")
    _put(out, "I", 4, len(data) + 1)
    out += data + b"\0"


def _write(out: bytearray, codec, value) -> None:
    kind = type(codec).__name__  # the support module is the compiled type's private copy
    if kind == "Bool":
        out.append(1 if value else 0)
    elif kind in ("Int", "Float"):
        _put(out, codec.fmt, codec.size, value)
    elif kind == "Enum":
        _put(out, codec.base.fmt, codec.base.size, int(value))
    elif kind in ("Str", "FixedStr"):
        _write_string(out, value)
    elif kind == "Bytes":
        data = bytes(value)
        _put(out, "I", 4, len(data))
        out += data
    elif kind == "NumArray":
        _align(out, codec.element.size)
        out += codec.raw(value)  # little-endian, C order: CDR's array of arrays
    elif kind == "ListArray":
        for item in value:
            _write(out, codec.element, item)
    elif kind == "Vec":
        items = value.tolist() if hasattr(value, "tolist") else value
        _put(out, "I", 4, len(items))
        for item in items:
            _write(out, codec.element, item)
    elif kind == "Option":
        _put(out, "I", 4, 0 if value is None else 1)
        if value is not None:
            _write(out, codec.element, value)
    elif kind == "Nested":
        _write_message(out, value)
    else:
        raise TypeError(f"no CDR for the codec {kind}")


# -- reading --------------------------------------------------------------------------------------

class CdrReader:
    """A sample's body, member by member (read_sample gives one to a reading function)."""

    __slots__ = ("data", "position", "order")

    def __init__(self, data: bytes, order: str) -> None:
        self.data, self.position, self.order = data, 0, order

    @staticmethod
    def read_sample(data, type_name: str, read):
        """`read(reader)` over the body of the CDR sample `data`; ValueError naming `type_name`
        when the bytes do not fit."""
        data = bytes(data)
        if len(data) < 4:
            raise ValueError(f"a CDR sample of {len(data)} bytes has no encapsulation header")
        scheme = data[:2]
        if scheme[0] == 0 and 6 <= scheme[1] <= 11:
            raise ValueError(f"encapsulation {scheme.hex()} is XCDR2, and the bridge reads XCDR1 "
                             "(plain CDR) only: the writer must offer XCDR1 (its data "
                             "representation QoS)")
        if scheme not in (_CDR_LE, _CDR_BE):
            raise ValueError(f"encapsulation {scheme.hex()} is not plain CDR (XCDR1): the writer's "
                             "type is not a @final struct of the IDL horus-gen emits")
        reader = CdrReader(data[4:], "<" if scheme == _CDR_LE else ">")
        try:
            value = read(reader)
            # Up to 3 bytes pad a sample to a multiple of 4; more is not this type.
            if len(reader.data) - reader.position > 3:
                raise ValueError(f"{len(reader.data) - reader.position} bytes are left over")
        except (struct.error, ValueError) as error:
            raise ValueError(f"a CDR sample does not decode as {type_name}: {error}") from None
        return value

    def number(self, fmt: str):
        return self.take(fmt, struct.calcsize(fmt))

    def numbers(self, fmt: str, count: int) -> tuple:
        size = struct.calcsize(fmt)
        self.position += -self.position % min(size, 8)
        return struct.unpack(f"{self.order}{count}{fmt}", self.raw(count * size))

    def string(self) -> str:
        size = self.count()
        if size == 0:
            raise ValueError(f"a string at offset {self.position - 4} has length 0 (no NUL)")
        return self.raw(size)[:-1].decode("utf-8")

    def take(self, fmt: str, size: int):
        self.position += -self.position % min(size, 8)
        (value,) = struct.unpack_from(self.order + fmt, self.data, self.position)
        self.position += size
        return value

    def raw(self, size: int) -> bytes:
        if self.position + size > len(self.data):
            raise ValueError(f"{size} bytes wanted at offset {self.position} of a "
                             f"{len(self.data)}-byte body")
        chunk = self.data[self.position:self.position + size]
        self.position += size
        return chunk

    def count(self) -> int:
        value = self.take("I", 4)
        if value > len(self.data) - self.position:
            raise ValueError(f"a count of {value} at offset {self.position - 4} runs past the "
                             f"{len(self.data)}-byte body")
        return value


def _read_message(reader: CdrReader, cls):
    info = cls.__horus__
    message = cls()
    if not info.fields:
        reader.take("B", 1)
        return message
    for name, codec in zip(info.fields, info.codecs):
        setattr(message, name, _read(reader, codec))
    return message


def _read(reader: CdrReader, codec):
    kind = type(codec).__name__
    if kind == "Bool":
        return reader.take("B", 1) != 0
    if kind in ("Int", "Float"):
        return reader.take(codec.fmt, codec.size)
    if kind == "Enum":
        number = reader.take(codec.base.fmt, codec.base.size)
        return codec.members.get(number, number)
    if kind in ("Str", "FixedStr"):
        return reader.string()
    if kind == "Bytes":
        return reader.raw(reader.count())
    if kind == "NumArray":
        import numpy
        element = codec.element.size
        reader.position += -reader.position % min(element, 8)
        chunk = reader.raw(codec.count * element)
        dtype = codec.dtype if reader.order == "<" else codec.dtype.newbyteorder(">")
        return numpy.frombuffer(chunk, dtype).reshape(codec.shape).astype(codec.dtype)
    if kind == "ListArray":
        return [_read(reader, codec.element) for _ in range(codec.length)]
    if kind == "Vec":
        return [_read(reader, codec.element) for _ in range(reader.count())]
    if kind == "Option":
        present = reader.take("I", 4)
        if present > 1:
            raise ValueError(f"an Option (sequence<T, 1>) holds {present} elements")
        return _read(reader, codec.element) if present else None
    if kind == "Nested":
        return _read_message(reader, codec.cls)
    raise TypeError(f"no CDR for the codec {kind}")
