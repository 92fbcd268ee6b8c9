"""Compiler-grade diagnostics: `path:line:col: error: message`, the source line, a caret, hints.

The reporter keeps going after an error so that one run shows every problem; stages check
`reporter.has_errors` only where continuing would produce nonsense.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Source:
    path: str
    text: str

    def line_text(self, line: int) -> str:
        lines = self.text.splitlines()
        return lines[line - 1] if 0 < line <= len(lines) else ""


@dataclass(frozen=True)
class Span:
    source: Source
    line: int
    col: int
    length: int = 1

    def __str__(self) -> str:
        return f"{self.source.path}:{self.line}:{self.col}"


@dataclass(frozen=True)
class Note:
    span: Span
    message: str


@dataclass(frozen=True)
class Diagnostic:
    span: Span
    message: str
    hint: str | None = None
    notes: tuple[Note, ...] = ()

    def render(self) -> str:
        parts = [_render_located(self.span, "error", self.message)]
        if self.hint:
            parts.append(f"      = hint: {self.hint}")
        for note in self.notes:
            parts.append(_render_located(note.span, "note", note.message))
        return "\n".join(parts)


def _render_located(span: Span, kind: str, message: str) -> str:
    text = span.source.line_text(span.line).expandtabs(1)
    gutter = f"{span.line:5d} | "
    caret = " " * (span.col - 1) + "^" + "~" * max(0, min(span.length, len(text) - span.col + 1) - 1)
    return f"{span}: {kind}: {message}\n{gutter}{text}\n{' ' * (len(gutter) - 2)}| {caret}"


@dataclass
class Reporter:
    """Collects every error of a run; nothing is printed until the run is over."""

    diagnostics: list[Diagnostic] = field(default_factory=list)

    def error(self, span: Span, message: str, hint: str | None = None,
              notes: tuple[Note, ...] = ()) -> None:
        diagnostic = Diagnostic(span, message, hint, notes)
        if diagnostic not in self.diagnostics:
            self.diagnostics.append(diagnostic)

    @property
    def has_errors(self) -> bool:
        return bool(self.diagnostics)

    def render(self) -> str:
        ordered = sorted(self.diagnostics, key=lambda d: (d.span.source.path, d.span.line, d.span.col))
        body = "\n".join(d.render() for d in ordered)
        count = len(self.diagnostics)
        return f"{body}\n{count} error{'s' if count != 1 else ''} generated.\n"


def near_miss(word: str, candidates: list[str] | set[str]) -> str | None:
    """The candidate a typo most likely meant, if any is close enough."""
    matches = difflib.get_close_matches(word, sorted(candidates), n=1, cutoff=0.6)
    if not matches:
        lowered = {c.lower(): c for c in candidates}
        return lowered.get(word.lower())
    return matches[0]


def did_you_mean(word: str, candidates: list[str] | set[str]) -> str | None:
    guess = near_miss(word, candidates)
    return f"did you mean '{guess}'?" if guess else None
