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
_DIGITS = frozenset("0123456789")
_NAME_START = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ_")
_NAME_CHARS = _NAME_START | _DIGITS
# Limits (docs/schema-language.md, "Limits"): a name becomes a file name, so it stays well under
# the 255 bytes a file name may have; a number longer than this is no value any type holds.
MAX_NAME_LENGTH = 100
MAX_NUMBER_LENGTH = 100
# Characters no schema may hold, even in a comment or string: C++ and Python would read them as
# line ends or refuse them (NUL), so a doc comment holding one would break the generated code.
_FORBIDDEN = frozenset(chr(c) for c in (*range(0x00, 0x09), 0x0B, 0x0C, *range(0x0E, 0x20), 0x7F,
                                         0x85, 0x2028, 0x2029))


def tokenize(source: Source, reporter: Reporter) -> list[Token]:
    text = source.text
    tokens: list[Token] = []
    i, line, line_start = 0, 1, 0

    def span(start: int, end: int) -> Span:
        return Span(source, line, start - line_start + 1, max(1, end - start))

    _check_characters(source, reporter)

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
        if c in _NAME_START or c.isalpha():
            j = i + 1
            while j < len(text) and (text[j] in _NAME_CHARS or text[j].isalnum()):
                j += 1
            word = text[i:j]
            if not word.isascii():
                reporter.error(span(i, j), f"name '{word}' is not ASCII",
                               "names are ASCII letters, digits and '_' (C++, Python and file names agree on those)")
            elif len(word) > MAX_NAME_LENGTH:
                reporter.error(span(i, j), f"name of {len(word)} characters is longer than {MAX_NAME_LENGTH}")
            tokens.append(Token(Kind.IDENT, word, span(i, j)))
            i = j
            continue
        if c in _DIGITS:
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
        if c not in _FORBIDDEN:  # those were reported above
            reporter.error(span(i, i + 1), f"unexpected character '{c}'")
        i += 1
    eof_line = text.count("\n") + 1
    last = text.rsplit("\n", 1)[-1]
    tokens.append(Token(Kind.EOF, "", Span(source, eof_line, len(last) + 1)))
    return tokens


def _check_characters(source: Source, reporter: Reporter) -> None:
    """Reports each line holding a character no schema may hold. (Files are read with universal
    newlines: a lone carriage return has already become a line end.)"""
    for number, line in enumerate(source.text.split("\n"), start=1):
        bad = next((k for k, c in enumerate(line) if c in _FORBIDDEN), None)
        if bad is not None:
            reporter.error(Span(source, number, bad + 1),
                           f"character U+{ord(line[bad]):04X} is not allowed in a schema",
                           "remove it: schemas hold printable text, tabs and line ends only")


def _number(text, i, span, tokens, reporter) -> int:
    j = i
    if text.startswith(("0x", "0X", "0b", "0B", "0o", "0O"), i):
        j = i + 2
        while j < len(text) and (text[j] in _NAME_CHARS or text[j].isalnum()):
            j += 1
        raw = text[i:j]
        if len(raw) > MAX_NUMBER_LENGTH:
            reporter.error(span(i, j), f"number of {len(raw)} characters is longer than {MAX_NUMBER_LENGTH}",
                           "no field type holds it")
            tokens.append(Token(Kind.INT, raw, span(i, j), 0))
            return j
        try:
            tokens.append(Token(Kind.INT, raw, span(i, j), int(raw.replace("_", ""), 0)))
        except ValueError:
            reporter.error(span(i, j), f"malformed integer literal '{raw}'")
            tokens.append(Token(Kind.INT, raw, span(i, j), 0))
        return j
    while j < len(text) and (text[j] in _DIGITS or text[j] == "_"):
        j += 1
    is_float = False
    if j + 1 < len(text) and text[j] == "." and text[j + 1] in _DIGITS:
        is_float = True
        j += 1
        while j < len(text) and (text[j] in _DIGITS or text[j] == "_"):
            j += 1
    if j < len(text) and text[j] in "eE":
        k = j + 1
        if k < len(text) and text[k] in "+-":
            k += 1
        if k < len(text) and text[k] in _DIGITS:
            is_float = True
            j = k
            while j < len(text) and text[j] in _DIGITS:
                j += 1
    raw = text[i:j]
    if j < len(text) and (text[j] in _NAME_START or text[j].isalpha()):
        k = j
        while k < len(text) and (text[k] in _NAME_CHARS or text[k].isalnum()):
            k += 1
        reporter.error(span(j, k), f"unexpected suffix '{text[j:k]}' after number '{raw}'",
                       "write the number alone; the field's type gives its width")
        j = k
    clean = raw.replace("_", "")
    if len(clean) > MAX_NUMBER_LENGTH:
        reporter.error(span(i, j), f"number of {len(clean)} characters is longer than {MAX_NUMBER_LENGTH}",
                       "no field type holds it")
        tokens.append(Token(Kind.INT, raw, span(i, j), 0))
    elif is_float:
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
