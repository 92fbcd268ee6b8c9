"""Compiler-grade diagnostics: `path:line:col: error: message`, the source line, a caret, hints.

The reporter keeps going after an error so that one run shows every problem; stages check
`reporter.has_errors` only where continuing would produce nonsense.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from functools import cached_property

# More errors than this in one run are counted, not shown: past it they are noise, and rendering
# each costs a look-up in its file.
MAX_SHOWN_ERRORS = 100


@dataclass(frozen=True)
class Source:
    path: str
    text: str

    def line_text(self, line: int) -> str:
        """Line `line` as the lexer counts lines (at '\n' only), kept once per file."""
        lines = self.lines
        return lines[line - 1].removesuffix("\r") if 0 < line <= len(lines) else ""

    @cached_property
    def lines(self) -> list[str]:
        return self.text.split("\n")


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
    severity: str = "error"  # or "warning": reported, but the run still succeeds

    def render(self) -> str:
        parts = [_render_located(self.span, self.severity, self.message)]
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
    warnings: list[Diagnostic] = field(default_factory=list)
    seen: set[tuple] = field(default_factory=set)  # the same error reached twice is reported once

    def error(self, span: Span, message: str, hint: str | None = None,
              notes: tuple[Note, ...] = ()) -> None:
        key = (str(span), span.length, message, hint, tuple((str(n.span), n.message) for n in notes))
        if key not in self.seen:
            self.seen.add(key)
            self.diagnostics.append(Diagnostic(span, message, hint, notes))

    def warning(self, span: Span, message: str, hint: str | None = None) -> None:
        self.warnings.append(Diagnostic(span, message, hint, severity="warning"))

    @property
    def has_errors(self) -> bool:
        return bool(self.diagnostics)

    def render(self) -> str:
        """Errors and warnings by position; the last line counts each kind."""
        everything = self.diagnostics + self.warnings
        ordered = sorted(everything, key=lambda d: (d.span.source.path, d.span.line, d.span.col))
        shown = ordered[:MAX_SHOWN_ERRORS]
        body = "\n".join(d.render() for d in shown)
        if len(everything) > len(shown):
            body += f"\n({len(everything) - len(shown)} more errors not shown)"
        counts = [f"{n} {kind}{'s' if n != 1 else ''}" for n, kind in
                  ((len(self.diagnostics), "error"), (len(self.warnings), "warning")) if n or kind == "error"]
        if not self.diagnostics:
            counts = counts[1:]
        return f"{body}\n{' and '.join(counts)} generated.\n"


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
