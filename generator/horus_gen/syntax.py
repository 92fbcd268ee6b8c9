"""The syntax tree: what the parser read, with spans, before any name is resolved."""
from __future__ import annotations

from dataclasses import dataclass, field

from .diagnostics import Source, Span


@dataclass(frozen=True)
class Literal:
    kind: str  # "int" | "float" | "string" | "bool" | "path" | "list"
    value: object  # int, float, str, bool, tuple[str, ...] (path) or tuple[Literal, ...] (list)
    span: Span


@dataclass(frozen=True)
class TypeExpr:
    """`u32`, `a::b::Pose`, `[T; N]`, `string<N>`, `Vec<T>`, `Option<T>`."""
    path: tuple[str, ...]
    span: Span
    args: tuple["TypeExpr | Literal", ...] = ()
    element: "TypeExpr | None" = None  # set for fixed arrays
    length: Literal | None = None  # set for fixed arrays

    @property
    def name(self) -> str:
        return ".".join(self.path)


@dataclass(frozen=True)
class Attribute:
    name: str
    value: Literal | None
    span: Span


@dataclass(frozen=True)
class FieldDecl:
    name: str
    span: Span
    type: TypeExpr
    default: Literal | None
    attributes: tuple[Attribute, ...]
    docs: tuple[str, ...]


@dataclass(frozen=True)
class ConstDecl:
    name: str
    span: Span
    type: TypeExpr
    value: Literal
    attributes: tuple[Attribute, ...]
    docs: tuple[str, ...]


@dataclass(frozen=True)
class MessageDecl:
    name: str
    span: Span
    fields: tuple[FieldDecl, ...]
    constants: tuple[ConstDecl, ...]
    attributes: tuple[Attribute, ...]
    docs: tuple[str, ...]


@dataclass(frozen=True)
class EnumVariant:
    name: str
    span: Span
    value: Literal | None
    docs: tuple[str, ...]


@dataclass(frozen=True)
class EnumDecl:
    name: str
    span: Span
    underlying: TypeExpr | None
    variants: tuple[EnumVariant, ...]
    attributes: tuple[Attribute, ...]
    docs: tuple[str, ...]


@dataclass(frozen=True)
class ServiceDecl:
    name: str
    span: Span
    request: MessageDecl
    response: MessageDecl
    attributes: tuple[Attribute, ...]
    docs: tuple[str, ...]


@dataclass
class FileSyntax:
    source: Source
    package: tuple[str, Span] | None = None
    imports: list[tuple[str, Span]] = field(default_factory=list)
    items: list[MessageDecl | EnumDecl | ServiceDecl] = field(default_factory=list)
