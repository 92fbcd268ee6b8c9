"""POD layout: the x86-64 / aarch64 Linux C++ layout of a generated struct, computed here once.

Fields keep declaration order, each at its natural alignment; the size is rounded up to the
largest alignment; an empty struct has size 1 (as in C++). The emitters turn these numbers into
static_asserts (C++) and numpy dtypes (Python); they never recompute them.
"""
from __future__ import annotations

from typing import Callable

from .model import EnumRef, FixedArray, FixedString, MessageRef, Optional, Padding, Primitive, Type, Vec

# Limits (docs/schema-language.md, "Limits"): a POD message is one shared-memory slot, and its
# padding is listed range by range in the generated code of both languages.
MAX_POD_SIZE = 1 << 30
MAX_PADDING_RANGES = 1 << 16


class LayoutTooLarge(ValueError):
    """A POD layout past MAX_POD_SIZE or MAX_PADDING_RANGES; the message says which."""


# (size, alignment, padding ranges inside the value) of a nested POD message, by qualified name.
NestedLayout = Callable[[str], tuple[int, int, tuple[Padding, ...]]]


def type_layout(t: Type, nested: NestedLayout, enum_underlying: Callable[[str], Primitive]
                ) -> tuple[int, int, tuple[Padding, ...]]:
    """Size, alignment and inner padding of a POD type."""
    if isinstance(t, Primitive):
        return t.size, t.size, ()
    if isinstance(t, FixedString):
        return t.capacity, 1, ()
    if isinstance(t, EnumRef):
        underlying = enum_underlying(t.qualified)
        return underlying.size, underlying.size, ()
    if isinstance(t, MessageRef):
        return nested(t.qualified)
    if isinstance(t, FixedArray):
        size, align, holes = type_layout(t.element, nested, enum_underlying)
        if size * t.length > MAX_POD_SIZE:
            raise LayoutTooLarge(f"[{t.length} elements of {size} bytes] is more than the {MAX_POD_SIZE} bytes "
                                 "a POD message may hold")
        if len(holes) * t.length > MAX_PADDING_RANGES:
            raise LayoutTooLarge(f"{t.length} elements with {len(holes)} padding range(s) each make more than "
                                 f"{MAX_PADDING_RANGES} padding ranges")
        repeated = tuple(Padding(i * size + h.offset, h.size) for i in range(t.length) for h in holes) if holes else ()
        return size * t.length, align, repeated
    raise ValueError(f"{t!r} has no POD layout")


def counted_size(t: Type, pod_size: Callable[[Type], int | None]) -> int:
    """Bytes of a value of `t` as the array limit counts them: POD types at their layout size
    (`pod_size`; None for a serialized type), anything serialized at one byte. Raises
    LayoutTooLarge for a fixed-size array past MAX_POD_SIZE anywhere in `t`: inside Vec<…>,
    Option<…> or a serialized message such an array would not compile in C++ or fit a numpy shape
    any more than in a POD message."""
    if isinstance(t, FixedArray):
        element = counted_size(t.element, pod_size)
        if element * t.length > MAX_POD_SIZE:
            raise LayoutTooLarge(f"[{t.length} elements of {element} bytes] is more than the {MAX_POD_SIZE} bytes "
                                 "a fixed-size array may hold")
        return element * t.length
    if isinstance(t, (Vec, Optional)):
        counted_size(t.element, pod_size)
        return 1
    return pod_size(t) or 1


def struct_layout(members: list[tuple[int, int, tuple[Padding, ...]]]
                  ) -> tuple[list[int], int, int, tuple[Padding, ...]]:
    """Offsets, size, alignment and merged padding of a struct with the given member layouts."""
    offsets: list[int] = []
    holes: list[Padding] = []
    offset, alignment = 0, 1
    for size, align, inner in members:
        aligned = (offset + align - 1) // align * align
        if aligned > offset:
            holes.append(Padding(offset, aligned - offset))
        offsets.append(aligned)
        holes.extend(Padding(aligned + h.offset, h.size) for h in inner)
        offset = aligned + size
        alignment = max(alignment, align)
    size = max(1, (offset + alignment - 1) // alignment * alignment)
    if size > MAX_POD_SIZE:
        raise LayoutTooLarge(f"its {size} bytes are more than the {MAX_POD_SIZE} bytes a POD message may hold")
    if size > offset:  # an empty struct's one byte too: no field writes it
        holes.append(Padding(offset, size - offset))
    return offsets, size, alignment, _merge(holes)


def _merge(holes: list[Padding]) -> tuple[Padding, ...]:
    merged: list[Padding] = []
    for hole in sorted(holes, key=lambda h: h.offset):
        if merged and merged[-1].offset + merged[-1].size == hole.offset:
            merged[-1] = Padding(merged[-1].offset, merged[-1].size + hole.size)
        else:
            merged.append(hole)
    return tuple(merged)
