"""Tokens of the schema language, each with its exact span."""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from .diagnostics import Reporter, Source, Span


class Kind(Enum):
    IDENT = "identifier"
    INT = "integer"
    FLOAT = "number"
    STRING = "string"
    DOC = "doc comment"
    PUNCT = "punctuation"
    EOF = "end of file"


@dataclass(frozen=True)
class Token:
    kind: Kind
    text: str
    span: Span
    value: object = None

    def is_punct(self, text: str) -> bool:
        return self.kind is Kind.PUNCT and self.text == text

    def is_word(self, text: str) -> bool:
        return self.kind is Kind.IDENT and self.text == text

    def describe(self) -> str:
        if self.kind is Kind.EOF:
            return "end of file"
        return f"'{self.text}'"


_TWO_CHAR = ("::", "->", "#[")
_ONE_CHAR = "{}[]()<>:;,=.!-+"
_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "0": "\0", "\\": "\\", '"': '"', "'": "'"}


def tokenize(source: Source, reporter: Reporter) -> list[Token]:
    text = source.text
    tokens: list[Token] = []
    i, line, line_start = 0, 1, 0

    def span(start: int, end: int) -> Span:
        return Span(source, line, start - line_start + 1, max(1, end - start))

    while i < len(text):
        c = text[i]
        if c == "\n":
            i += 1
            line, line_start = line + 1, i
            continue
        if c in " \t\r":
            i += 1
            continue
        if text.startswith("///", i) and not text.startswith("////", i):
            end = text.find("\n", i)
            end = len(text) if end < 0 else end
            body = text[i + 3:end]
            tokens.append(Token(Kind.DOC, text[i:end], span(i, end), body[1:] if body.startswith(" ") else body))
            i = end
            continue
        if text.startswith("//", i) or (c == "#" and not text.startswith("#[", i)):
            end = text.find("\n", i)
            i = len(text) if end < 0 else end
            continue
        if text.startswith("/*", i):
            end = text.find("*/", i + 2)
            if end < 0:
                reporter.error(span(i, i + 2), "unterminated block comment",
                               "close it with '*/'")
                break
            chunk = text[i:end + 2]
            newlines = chunk.count("\n")
            if newlines:
                line += newlines
                line_start = i + chunk.rfind("\n") + 1
            i = end + 2
            continue
        if c.isalpha() or c == "_":
            j = i + 1
            while j < len(text) and (text[j].isalnum() or text[j] == "_"):
                j += 1
            tokens.append(Token(Kind.IDENT, text[i:j], span(i, j)))
            i = j
            continue
        if c.isdigit():
            i = _number(text, i, span, tokens, reporter)
            continue
        if c == '"':
            i = _string(text, i, span, tokens, reporter)
            continue
        two = text[i:i + 2]
        if two in _TWO_CHAR:
            tokens.append(Token(Kind.PUNCT, two, span(i, i + 2)))
            i += 2
            continue
        if c in _ONE_CHAR:
            tokens.append(Token(Kind.PUNCT, c, span(i, i + 1)))
            i += 1
            continue
        reporter.error(span(i, i + 1), f"unexpected character '{c}'")
        i += 1
    eof_line = text.count("\n") + 1
    last = text.rsplit("\n", 1)[-1]
    tokens.append(Token(Kind.EOF, "", Span(source, eof_line, len(last) + 1)))
    return tokens


def _number(text, i, span, tokens, reporter) -> int:
    j = i
    if text.startswith(("0x", "0X", "0b", "0B", "0o", "0O"), i):
        j = i + 2
        while j < len(text) and (text[j].isalnum() or text[j] == "_"):
            j += 1
        raw = text[i:j]
        try:
            tokens.append(Token(Kind.INT, raw, span(i, j), int(raw.replace("_", ""), 0)))
        except ValueError:
            reporter.error(span(i, j), f"malformed integer literal '{raw}'")
            tokens.append(Token(Kind.INT, raw, span(i, j), 0))
        return j
    while j < len(text) and (text[j].isdigit() or text[j] == "_"):
        j += 1
    is_float = False
    if j + 1 < len(text) and text[j] == "." and text[j + 1].isdigit():
        is_float = True
        j += 1
        while j < len(text) and (text[j].isdigit() or text[j] == "_"):
            j += 1
    if j < len(text) and text[j] in "eE":
        k = j + 1
        if k < len(text) and text[k] in "+-":
            k += 1
        if k < len(text) and text[k].isdigit():
            is_float = True
            j = k
            while j < len(text) and text[j].isdigit():
                j += 1
    raw = text[i:j]
    if j < len(text) and (text[j].isalpha() or text[j] == "_"):
        k = j
        while k < len(text) and (text[k].isalnum() or text[k] == "_"):
            k += 1
        reporter.error(span(j, k), f"unexpected suffix '{text[j:k]}' after number '{raw}'",
                       "write the number alone; the field's type gives its width")
        j = k
    clean = raw.replace("_", "")
    if is_float:
        tokens.append(Token(Kind.FLOAT, raw, span(i, j), float(clean)))
    else:
        tokens.append(Token(Kind.INT, raw, span(i, j), int(clean)))
    return j


def _string(text, i, span, tokens, reporter) -> int:
    j = i + 1
    out = []
    while j < len(text) and text[j] != '"':
        if text[j] == "\n":
            break
        if text[j] == "\\" and j + 1 < len(text):
            esc = text[j + 1]
            if esc not in _ESCAPES:
                reporter.error(span(j, j + 2), f"unknown escape '\\{esc}' in string",
                               "known escapes: \\n \\t \\r \\0 \\\\ \\\"")
            out.append(_ESCAPES.get(esc, esc))
            j += 2
            continue
        out.append(text[j])
        j += 1
    if j >= len(text) or text[j] != '"':
        reporter.error(span(i, j), "unterminated string", "close it with '\"' on the same line")
        tokens.append(Token(Kind.STRING, text[i:j], span(i, j), "".join(out)))
        return j
    tokens.append(Token(Kind.STRING, text[i:j + 1], span(i, j + 1), "".join(out)))
    return j + 1
