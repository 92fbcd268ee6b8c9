"""The log summary of a message: the default `Name{field: value, ...}` or the `#[summary]`
template, a small language of literal text with `{{`/`}}` escapes and placeholders, turned into
the parts every language's code prints. A placeholder is `{field}` (the field as the default line
prints it, with its unit), `{field:.2}` (a number field with two decimals, and its unit), or
arithmetic on number fields and numbers (`{self.used / self.total * 100:.1}`, no unit), in the
spirit of Rust's `format!` arguments."""
from __future__ import annotations

import math
import re

from . import identity
from .diagnostics import Reporter, Span, did_you_mean
from .model import (PRIMITIVES, Bytes, EnumRef, Field, FixedArray, Message, Model, Optional, Primitive,
                    SummaryExpr, SummaryPart, Type, Vec)
from .syntax import Attribute, MessageDecl

# Digits after the point in `{x:.N}`: past 30 a log line shows nothing more of an f64.
MAX_PRECISION = 30
# Parentheses nest at most this deep in a placeholder (the parser of expressions is recursive).
MAX_DEPTH = 16
_TOKEN = re.compile(r"\s*(?:(?P<number>\d+(?:\.\d*)?(?:[eE][+-]?\d+)?)|(?P<name>(?:self\s*\.\s*)?[A-Za-z_]\w*)"
                    r"|(?P<op>[-+*/()]))")
_SPEC = re.compile(r"\.(\d{1,3})")


class _Bad(Exception):
    def __init__(self, offset: int, length: int, message: str, hint: str | None = None):
        super().__init__(message)
        self.offset, self.length, self.message, self.hint = offset, length, message, hint


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
    attribute = next(a for a in item.attributes if a.name == "summary")
    parts = []
    i, text = 0, ""
    while i < len(template):
        c = template[i]
        if template.startswith("{{", i) or template.startswith("}}", i):
            text += c
            i += 2
            continue
        if c == "}":
            reporter.error(_span(attribute, template, i, 1), "unmatched '}' in #[summary]",
                           "write '}}' for a literal brace")
            i += 1
            continue
        if c == "{":
            end = template.find("}", i)
            if end < 0:
                reporter.error(_span(attribute, template, i, 1), "unclosed '{' in #[summary]",
                               "write '{{' for a literal brace")
                break
            try:
                parts.append(SummaryPart(text=text))
                parts += _placeholder(template[i + 1:end], i + 1, item.name, by_name, part)
                text = ""
            except _Bad as bad:
                reporter.error(_span(attribute, template, bad.offset, bad.length), bad.message, bad.hint)
            i = end + 1
            continue
        text += c
        i += 1
    parts.append(SummaryPart(text=text))
    return _join_text(parts)


def _span(attribute: Attribute, template: str, offset: int, length: int) -> Span:
    """The place of template[offset:offset + length] in the schema: exact when the string has no
    escapes (the usual case), else the whole string."""
    literal = attribute.value
    assert literal is not None
    raw = literal.span.source.line_text(literal.span.line)[literal.span.col:literal.span.col - 1 + literal.span.length - 1]
    if raw == template:
        return Span(literal.span.source, literal.span.line, literal.span.col + 1 + offset, max(1, length))
    return literal.span


def _placeholder(body: str, at: int, owner: str, by_name: dict[str, Field], part) -> list[SummaryPart]:
    """The parts of one `{...}`: `body` is what the braces hold, `at` its offset in the template."""
    expression, colon, spec = body.partition(":")
    precision = None
    if colon:
        match = _SPEC.fullmatch(spec)
        if match is None:
            raise _Bad(at + len(expression), len(spec) + 1, f"unsupported format ':{spec}' in #[summary]",
                       "write ':.N' for N digits after the point (as Rust's {:.2}); without a format, "
                       "numbers print as printf's %g")
        precision = int(match.group(1))
        if precision > MAX_PRECISION:
            raise _Bad(at + len(expression) + 2, len(spec) - 1,
                       f"precision {precision} is more than {MAX_PRECISION}", "an f64 has 17 significant digits")
    tokens = _tokens(expression, at)
    if not tokens:
        raise _Bad(at - 1, len(body) + 2, "empty placeholder in #[summary]",
                   "name a field, as in {velocity}, or compute with fields, as in {self.ratio * 100:.1}")
    tree = _Expression(tokens, at + len(expression), owner, by_name, precision is None).parse()
    if tree.op == "field" and precision is None:
        return [part(by_name[tree.field])]
    unit = by_name[tree.field].unit if tree.op == "field" else ""
    return [SummaryPart(expression=tree, precision=precision), SummaryPart(text=" " + unit if unit else "")]


def _tokens(expression: str, at: int) -> list[tuple[str, str, int]]:
    """(kind, text, offset in the template) of each token of a placeholder's expression."""
    tokens = []
    i = 0
    while expression[i:].strip():
        match = _TOKEN.match(expression, i)
        if match is None:
            start = len(expression) - len(expression[i:].lstrip())
            raise _Bad(at + start, 1, f"unexpected '{expression[start]}' in a #[summary] placeholder",
                       "a placeholder holds a field, or numbers and number fields with + - * / and parentheses")
        kind = match.lastgroup
        tokens.append((kind, match.group(kind), at + match.start(kind)))
        i = match.end()
    return tokens


class _Expression:
    """Recursive descent over one placeholder's tokens: sums of products of signed atoms."""

    def __init__(self, tokens: list[tuple[str, str, int]], end: int, owner: str, by_name: dict[str, Field],
                 any_type: bool):
        self.tokens, self.end, self.owner, self.by_name = tokens, end, owner, by_name
        self.any_type = any_type  # a field alone without a format prints whatever its type
        self.pos, self.depth = 0, 0

    def peek(self) -> tuple[str, str, int]:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else ("end", "", self.end)

    def parse(self) -> SummaryExpr:
        tree = self.sum()
        kind, text, offset = self.peek()
        if kind != "end":
            raise _Bad(offset, len(text), f"unexpected '{text}' in a #[summary] placeholder",
                       "join values with + - * /")
        return tree

    def sum(self) -> SummaryExpr:
        tree = self.product()
        while self.peek()[1] in ("+", "-") and self.peek()[0] == "op":
            op = self.tokens[self.pos][1]
            self.pos += 1
            tree = SummaryExpr(op, (tree, self.product()))
        return tree

    def product(self) -> SummaryExpr:
        tree = self.signed()
        while self.peek()[1] in ("*", "/") and self.peek()[0] == "op":
            op = self.tokens[self.pos][1]
            self.pos += 1
            tree = SummaryExpr(op, (tree, self.signed()))
        return tree

    def signed(self) -> SummaryExpr:
        kind, text, offset = self.peek()
        if kind == "op" and text == "-":
            self.pos += 1
            return SummaryExpr("neg", (self.deeper(offset, self.signed),))
        if kind == "op" and text == "(":
            self.pos += 1
            tree = self.deeper(offset, self.sum)
            kind, text, offset = self.peek()
            if text != ")" or kind != "op":
                raise _Bad(offset, max(1, len(text)), "expected ')' in a #[summary] placeholder")
            self.pos += 1
            return tree
        if kind == "number":
            self.pos += 1
            value = float(text)
            if math.isinf(value):
                raise _Bad(offset, len(text), f"number {text} is out of range for f64")
            return SummaryExpr("number", number=value)
        if kind == "name":
            self.pos += 1
            return self.field(text.split(".")[-1].strip(), offset, len(text))
        found = "the end of the placeholder" if kind == "end" else f"'{text}'"
        raise _Bad(offset, max(1, len(text)), f"expected a field or a number in a #[summary] placeholder, found {found}")

    def deeper(self, offset: int, parse):
        if self.depth >= MAX_DEPTH:
            raise _Bad(offset, 1, f"a #[summary] placeholder nests more than {MAX_DEPTH} deep")
        self.depth += 1
        try:
            return parse()
        finally:
            self.depth -= 1

    def field(self, name: str, offset: int, length: int) -> SummaryExpr:
        found = self.by_name.get(name)
        if found is None:
            raise _Bad(offset, length, f"#[summary] names '{name}', which is not a field of '{self.owner}'",
                       did_you_mean(name, list(self.by_name)))
        if self.any_type and self.pos == len(self.tokens) == 1:
            return SummaryExpr("field", field=name)
        if not (isinstance(found.type, Primitive) and not found.type.is_bool):
            raise _Bad(offset, length, f"#[summary] computes with '{name}', which is '{found.spelling}', not a number",
                       "arithmetic and formats take integer and float fields")
        return SummaryExpr("field", field=name)


def _element_label(t: Type) -> str:
    inner = t.element if isinstance(t, Optional) else t
    if isinstance(inner, (FixedArray, Vec)):
        return identity.spelling(inner.element, short=True)
    return ""


def _join_text(parts: list[SummaryPart]) -> tuple[SummaryPart, ...]:
    joined: list[SummaryPart] = []
    for p in parts:
        is_text = p.field is None and p.expression is None
        if is_text and not p.text:
            continue
        if is_text and joined and joined[-1].field is None and joined[-1].expression is None:
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
