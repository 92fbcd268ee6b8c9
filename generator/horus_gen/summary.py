"""The log summary of a message: the default `Name{field: value, ...}` or the `#[summary]`
template, a small language of literal text with `{field}` placeholders and `{{`/`}}` escapes,
turned into the parts every language's code prints."""
from __future__ import annotations

from . import identity
from .diagnostics import Reporter, did_you_mean
from .model import (PRIMITIVES, Bytes, EnumRef, Field, FixedArray, Message, Model, Optional, SummaryPart,
                    Type, Vec)
from .syntax import MessageDecl


def summary_parts(reporter: Reporter, item: MessageDecl, fields: list[Field],
                  template: str | None) -> tuple[SummaryPart, ...]:
    by_name = {f.name: f for f in fields}

    def part(f: Field) -> SummaryPart:
        return SummaryPart(field=f.name, label=_element_label(f.type), unit=f.unit)

    if template is None:
        parts = [SummaryPart(text=f"{item.name}{{")]
        for i, f in enumerate(fields):
            parts.append(SummaryPart(text=(", " if i else "") + f"{f.name}: "))
            parts.append(part(f))
        parts.append(SummaryPart(text="}"))
        return _join_text(parts)
    parts = []
    i, text = 0, ""
    span = next(a.span for a in item.attributes if a.name == "summary")
    while i < len(template):
        c = template[i]
        if template.startswith("{{", i) or template.startswith("}}", i):
            text += c
            i += 2
            continue
        if c == "{":
            end = template.find("}", i)
            if end < 0:
                reporter.error(span, "unclosed '{' in #[summary]", "write '{{' for a literal brace")
                break
            name = template[i + 1:end]
            if name not in by_name:
                reporter.error(span, f"#[summary] names '{name}', which is not a field of '{item.name}'",
                                    did_you_mean(name, list(by_name)))
            else:
                parts.append(SummaryPart(text=text))
                parts.append(part(by_name[name]))
                text = ""
            i = end + 1
            continue
        text += c
        i += 1
    parts.append(SummaryPart(text=text))
    return _join_text(parts)


def _element_label(t: Type) -> str:
    inner = t.element if isinstance(t, Optional) else t
    if isinstance(inner, (FixedArray, Vec)):
        return identity.spelling(inner.element, short=True)
    return ""


def _join_text(parts: list[SummaryPart]) -> tuple[SummaryPart, ...]:
    joined: list[SummaryPart] = []
    for p in parts:
        if p.field is None and not p.text:
            continue
        if p.field is None and joined and joined[-1].field is None:
            joined[-1] = SummaryPart(text=joined[-1].text + p.text)
        else:
            joined.append(p)
    return tuple(joined)


def printed_types(model: Model, messages: list[Message]) -> list[Type]:
    """Every type whose values the summaries of `messages` print, once, each after the types it
    holds (an enum after its underlying integer type, bytes after u8): the table a language's one
    summary formatter reads, in an order in which each entry can name the ones it holds."""
    ordered: dict[Type, None] = {}

    def visit(t: Type) -> None:
        if t in ordered:
            return
        if isinstance(t, (FixedArray, Vec, Optional)):
            visit(t.element)
        elif isinstance(t, Bytes):
            visit(PRIMITIVES["u8"])
        elif isinstance(t, EnumRef):
            visit(model.types[t.qualified].underlying)
        ordered[t] = None

    for message in messages:
        by_name = {f.name: f for f in message.fields}
        for part in message.summary:
            if part.field is not None:
                visit(by_name[part.field].type)
    return list(ordered)
