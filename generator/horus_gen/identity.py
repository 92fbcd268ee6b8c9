"""Canonical schema text and fingerprints.

A type's canonical text names its package, name, fields with their types in canonical spelling
(`[u8; 32]`, never `[u8;32]`), array lengths and enum values; a nested type appears as its
qualified name with its fingerprint, so a change anywhere below changes every type above it.
Comments, defaults, constants and attributes are not part of it. The fingerprint is the first
8 bytes (big-endian) of the SHA-256 of the canonical text.
"""
from __future__ import annotations

import hashlib

from .model import (Bytes, DynString, EnumRef, FixedArray, FixedString, MessageRef, Optional,
                    Primitive, Type, Vec)


def fingerprint(canonical: str) -> int:
    return int.from_bytes(hashlib.sha256(canonical.encode("utf-8")).digest()[:8], "big")


def spelling(t: Type, short: bool = False) -> str:
    """The schema spelling of a type: qualified names, or short names for log summaries."""
    if isinstance(t, Primitive):
        return t.name
    if isinstance(t, FixedString):
        return f"string<{t.capacity}>"
    if isinstance(t, FixedArray):
        return f"[{spelling(t.element, short)}; {t.length}]"
    if isinstance(t, DynString):
        return "String"
    if isinstance(t, Bytes):
        return "bytes"
    if isinstance(t, Vec):
        return f"Vec<{spelling(t.element, short)}>"
    if isinstance(t, Optional):
        return f"Option<{spelling(t.element, short)}>"
    if isinstance(t, (MessageRef, EnumRef)):
        return t.qualified.rsplit(".", 1)[-1] if short else t.qualified
    raise ValueError(t)


def _identity_spelling(t: Type, fingerprints: dict[str, int]) -> str:
    if isinstance(t, (MessageRef, EnumRef)):
        return f"{t.qualified}#{fingerprints[t.qualified]:016x}"
    if isinstance(t, FixedArray):
        return f"[{_identity_spelling(t.element, fingerprints)}; {t.length}]"
    if isinstance(t, Vec):
        return f"Vec<{_identity_spelling(t.element, fingerprints)}>"
    if isinstance(t, Optional):
        return f"Option<{_identity_spelling(t.element, fingerprints)}>"
    return spelling(t)


def message_texts(qualified: str, fields: list[tuple[str, Type]], fingerprints: dict[str, int]
                  ) -> tuple[str, str]:
    """(identity text, readable text) of a message."""
    identity = "".join(f"  {n}: {_identity_spelling(t, fingerprints)},\n" for n, t in fields)
    readable = "".join(f"  {n}: {spelling(t)},\n" for n, t in fields)
    return f"message {qualified} {{\n{identity}}}\n", f"message {qualified} {{\n{readable}}}\n"


def enum_text(qualified: str, underlying: str, variants: list[tuple[str, int]]) -> str:
    body = "".join(f"  {name} = {value},\n" for name, value in variants)
    return f"enum {qualified}: {underlying} {{\n{body}}}\n"


def service_text(qualified: str, request: tuple[str, int], response: tuple[str, int]) -> str:
    return (f"service {qualified} {{\n  request: {request[0]}#{request[1]:016x},\n"
            f"  response: {response[0]}#{response[1]:016x},\n}}\n")


def action_text(qualified: str, goal, result, feedback) -> str:
    """An action's identity: its three blocks' messages (goal, result, feedback), each with its
    fingerprint; the services and topics around them are fixed by these."""
    parts = "".join(f"  {role}: {m.qualified}#{m.fingerprint:016x},\n"
                    for role, m in (("goal", goal), ("result", result), ("feedback", feedback)))
    return f"action {qualified} {{\n{parts}}}\n"
