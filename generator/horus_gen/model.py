"""The resolved model: the single source of truth every emitter reads.

Types are resolved (every name bound), every POD message carries its layout (offsets, size,
alignment, padding), and every type its canonical schema text and fingerprint. Emitters only
spell what is here in their language; they never compute layout or identity themselves.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

from .diagnostics import Span


@dataclass(frozen=True)
class Primitive:
    name: str  # bool u8 u16 u32 u64 i8 i16 i32 i64 f32 f64
    size: int

    @property
    def is_integer(self) -> bool:
        return self.name[0] in "ui"

    @property
    def is_signed(self) -> bool:
        return self.name[0] == "i"

    @property
    def is_float(self) -> bool:
        return self.name[0] == "f"

    @property
    def is_bool(self) -> bool:
        return self.name == "bool"


PRIMITIVES = {p.name: p for p in (
    Primitive("bool", 1), Primitive("u8", 1), Primitive("u16", 2), Primitive("u32", 4), Primitive("u64", 8),
    Primitive("i8", 1), Primitive("i16", 2), Primitive("i32", 4), Primitive("i64", 8),
    Primitive("f32", 4), Primitive("f64", 8))}


@dataclass(frozen=True)
class FixedString:
    capacity: int


@dataclass(frozen=True)
class FixedArray:
    element: "Type"
    length: int


@dataclass(frozen=True)
class DynString:
    pass


@dataclass(frozen=True)
class Bytes:
    pass


@dataclass(frozen=True)
class Vec:
    element: "Type"


@dataclass(frozen=True)
class Optional:
    element: "Type"


@dataclass(frozen=True)
class MessageRef:
    qualified: str  # "pkg.Name": look up in Model.types


@dataclass(frozen=True)
class EnumRef:
    qualified: str


Type = Union[Primitive, FixedString, FixedArray, DynString, Bytes, Vec, Optional, MessageRef, EnumRef]


@dataclass(frozen=True)
class EnumValue:
    """A default or constant that names an enumerator."""
    enum: str
    variant: str
    number: int


Value = Union[bool, int, float, str, EnumValue, tuple]


@dataclass(frozen=True)
class SummaryExpr:
    """Arithmetic on number fields in a #[summary] placeholder (`{self.x * 100:.1}`), computed in
    f64 by every language: `op` is "field" (a number field, as f64), "number", "neg", or one of
    "+", "-", "*", "/" applied to its two operands."""
    op: str
    operands: tuple["SummaryExpr", ...] = ()
    field: str | None = None
    number: float = 0.0


@dataclass(frozen=True)
class SummaryPart:
    """One piece of a log summary line: literal text, a field's value (and unit), or a computed
    number (`expression`, printed as printf `%.<precision>f`, or `%g` without a precision)."""
    text: str = ""
    field: str | None = None
    label: str = ""  # element type spelling for "[N x label]" summaries of sequences
    unit: str = ""
    expression: SummaryExpr | None = None
    precision: int | None = None


@dataclass(frozen=True)
class Field:
    name: str
    type: Type
    spelling: str  # canonical schema spelling of the type, e.g. "[f32; 360]"
    default: Value | None
    unit: str
    docs: tuple[str, ...]
    span: Span
    offset: int | None = None  # POD messages only
    size: int | None = None


@dataclass(frozen=True)
class Constant:
    name: str
    type: Type
    spelling: str
    value: Value
    docs: tuple[str, ...]


@dataclass(frozen=True)
class Padding:
    offset: int
    size: int


@dataclass(frozen=True)
class Mixin:
    source_path: str  # absolute path of the hand-written file
    relative: str  # its path relative to the schema's folder (each language names the copy)


@dataclass(frozen=True)
class Message:
    package: str
    name: str
    fields: tuple[Field, ...]
    constants: tuple[Constant, ...]
    docs: tuple[str, ...]
    source: str
    is_pod: bool
    size: int | None  # POD only
    alignment: int | None
    padding: tuple[Padding, ...]
    canonical: str  # this type alone, nested types named with their fingerprints (hashed)
    definition: str  # this type alone, readable
    schema: str  # the definitions of this type and of every type it uses
    fingerprint: int
    summary: tuple[SummaryPart, ...]
    topic: str | None = None
    cpp_mixin: Mixin | None = None
    cpp_includes: tuple[str, ...] = ()
    py_mixin: Mixin | None = None
    uses: tuple[str, ...] = ()  # qualified names of the types its fields name, in first-use order
    service: str | None = None  # set on a service's Request/Response
    action: str | None = None  # set on the messages an action generates (qualified action name)

    @property
    def qualified(self) -> str:
        return f"{self.package}.{self.name}"


@dataclass(frozen=True)
class Variant:
    name: str
    value: int
    docs: tuple[str, ...]


@dataclass(frozen=True)
class Enum:
    package: str
    name: str
    underlying: Primitive
    variants: tuple[Variant, ...]
    docs: tuple[str, ...]
    source: str
    canonical: str
    definition: str
    schema: str
    fingerprint: int

    @property
    def qualified(self) -> str:
        return f"{self.package}.{self.name}"


@dataclass(frozen=True)
class Service:
    package: str
    name: str
    request: Message
    response: Message
    docs: tuple[str, ...]
    source: str
    fingerprint: int
    # The name the service is called by (its topics' prefix): its own name, or `Action.send_goal`
    # for the services an action generates.
    wire_name: str = ""
    action: str | None = None  # the qualified action that generated it

    def __post_init__(self) -> None:
        if not self.wire_name:
            object.__setattr__(self, "wire_name", self.name)

    @property
    def qualified(self) -> str:
        return f"{self.package}.{self.name}"

    @property
    def request_topic(self) -> str:
        return f"{self.wire_name}.request"

    @property
    def response_topic(self) -> str:
        return f"{self.wire_name}.response"


@dataclass(frozen=True)
class Action:
    """An action: three services (send_goal, cancel_goal, get_result) and three topics (feedback,
    status, result) of messages generated from its goal, result and feedback blocks. Every one of
    them is an ordinary entry of Model.types / Model.services; this ties them together."""
    package: str
    name: str
    goal: Message
    result: Message
    feedback: Message
    send_goal: Service
    cancel_goal: Service
    get_result: Service
    feedback_message: Message
    status: Message
    result_message: Message
    docs: tuple[str, ...]
    source: str
    fingerprint: int

    @property
    def qualified(self) -> str:
        return f"{self.package}.{self.name}"

    @property
    def feedback_topic(self) -> str:
        return f"{self.name}.feedback"

    @property
    def status_topic(self) -> str:
        return f"{self.name}.status"

    @property
    def result_topic(self) -> str:
        return f"{self.name}.result"

    @property
    def services(self) -> tuple[Service, Service, Service]:
        return (self.send_goal, self.cancel_goal, self.get_result)

    @property
    def topics(self) -> tuple[tuple[str, Message], ...]:
        """(topic, message) of the three topics, in the order feedback, status, result."""
        return ((self.feedback_topic, self.feedback_message), (self.status_topic, self.status),
                (self.result_topic, self.result_message))


@dataclass(frozen=True)
class NodeTopic:
    """A topic a node subscribes to or publishes: its member, topic name and message type."""
    member: str
    topic: str
    message: str  # qualified name of the message it carries
    capacity: int | None  # #[capacity = N]: slots when this node creates the topic
    docs: tuple[str, ...]
    span: Span


@dataclass(frozen=True)
class NodeService:
    """A service a node calls (client) or serves (server)."""
    member: str
    service: str  # qualified name
    docs: tuple[str, ...]
    span: Span


@dataclass(frozen=True)
class NodeParam:
    """A parameter of a node (its `params` block): the runtime declares it when the node is built
    (horus::ParamDeclaration), holds it in shared memory and writes it only through the node."""
    name: str
    type: Type  # bool, an integer, f32, f64, String, an enum, or a fixed array of numbers or bool
    spelling: str  # canonical schema spelling of the type, e.g. "[f64; 3]"
    default: Value  # the declared value, or the type's zero when none is given
    minimum: float | int | None  # #[min = N]: inclusive, of a number or of each element of an array
    maximum: float | int | None
    choices: tuple[Value, ...]  # #[choices = [...]]: the only values allowed, when not empty
    unit: str
    docs: tuple[str, ...]
    read_only: bool
    span: Span


@dataclass(frozen=True)
class FailurePolicy:
    kind: str  # Fatal | Restart | Skip | Ignore
    arguments: tuple[tuple[str, int], ...] = ()  # max_restarts / max_failures: count; *_backoff, cooldown: ns


@dataclass(frozen=True)
class NodeSettings:
    """How the scheduler runs the node; None (or False) leaves the runtime's default."""
    order: int | None = None
    rate_hz: float | None = None
    budget_ns: int | None = None
    deadline_ns: int | None = None
    watchdog_ns: int | None = None
    on_miss: str | None = None  # Warn | Skip | SafeMode | Stop
    failure_policy: FailurePolicy | None = None
    compute: bool = False
    async_io: bool = False
    on: str | None = None  # event node: the topic whose messages wake it
    priority: int | None = None
    core: int | None = None


@dataclass(frozen=True)
class Node:
    package: str
    name: str  # the declaration's name; the generated base class is `base`
    node_name: str  # the name the node runs under (name(), `horus node list`)
    subs: tuple[NodeTopic, ...]
    pubs: tuple[NodeTopic, ...]
    clients: tuple[NodeService, ...]
    servers: tuple[NodeService, ...]
    data: tuple[Field, ...]
    settings: NodeSettings
    docs: tuple[str, ...]
    source: str
    uses: tuple[str, ...]  # qualified messages, services and enums it names, in first-use order
    params: tuple[NodeParam, ...] = ()

    @property
    def qualified(self) -> str:
        return f"{self.package}.{self.name}"

    @property
    def base(self) -> str:
        return base_class_name(self.name)


def base_class_name(node: str) -> str:
    """The generated class a user derives from: MotorController -> MotorControllerBase."""
    return node + "Base"


@dataclass
class Model:
    """Every type known to the run, and which of them this run generates."""
    types: dict[str, Message | Enum] = field(default_factory=dict)
    services: dict[str, Service] = field(default_factory=dict)
    actions: dict[str, Action] = field(default_factory=dict)
    nodes: dict[str, Node] = field(default_factory=dict)
    generated: list[str] = field(default_factory=list)  # qualified names, in source order
    inputs: list[str] = field(default_factory=list)  # every file read: schemas, imports, mixins

    def message(self, qualified: str) -> Message:
        found = self.types[qualified]
        assert isinstance(found, Message)
        return found

    def generated_items(self) -> list[Message | Enum | Service | Action | Node]:
        return [self.services.get(q) or self.actions.get(q) or self.nodes.get(q) or self.types[q]
                for q in self.generated]

    def generated_nodes(self) -> list[Node]:
        return [self.nodes[q] for q in self.generated if q in self.nodes]
