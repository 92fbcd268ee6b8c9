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


@dataclass(frozen=True)
class ActionDecl:
    """An action: its goal, result and feedback blocks, each read as a message (`NavigateGoal`...)."""
    name: str
    span: Span
    goal: MessageDecl
    result: MessageDecl
    feedback: MessageDecl
    attributes: tuple[Attribute, ...]
    docs: tuple[str, ...]


@dataclass
class FileSyntax:
    source: Source
    package: tuple[str, Span] | None = None
    imports: list[tuple[str, Span]] = field(default_factory=list)
    items: list["MessageDecl | EnumDecl | ServiceDecl | ActionDecl | NodeDecl"] = field(default_factory=list)


@dataclass(frozen=True)
class NodeEndpointDecl:
    """One entry of a node's `sub`/`pub` block (`cmd: CmdVel -> "cmd_vel"`) or of its
    `client`/`server` block (`pose: GetRobotPose`, no topic)."""
    name: str
    span: Span
    type: TypeExpr
    topic: Literal | None
    attributes: tuple[Attribute, ...]
    docs: tuple[str, ...]


@dataclass(frozen=True)
class NodeSettingDecl:
    """`rate: 100 hz`, `budget: 300 us`, `on_miss: SafeMode`, `failure_policy: Restart { ... }`:
    a value with an optional unit word, or a variant with named arguments."""
    name: str
    span: Span
    value: Literal
    unit: tuple[str, Span] | None = None
    arguments: tuple["NodeSettingDecl", ...] | None = None  # set for `Variant { key: value, ... }`


@dataclass(frozen=True)
class NodeDecl:
    name: str
    span: Span
    settings: tuple[NodeSettingDecl, ...]
    blocks: tuple[tuple[str, Span, tuple[NodeEndpointDecl, ...]], ...]  # ("sub", span, entries)...
    data: tuple[FieldDecl, ...]
    attributes: tuple[Attribute, ...]
    docs: tuple[str, ...]
    params: tuple[FieldDecl, ...] = ()
