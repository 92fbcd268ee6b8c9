"""Actions: a `.haction` item as the messages and services it stands for.

An action `A` is three services and three topics of generated messages (docs/schema-language.md,
"Actions"): its blocks become the messages AGoal, AResult and AFeedback; the messages of the
services and topics wrap them with a goal id, a state, a stamp and a reason; the services are
ASendGoal, ACancelGoal and AGetResult, called as `A.send_goal`, `A.cancel_goal`, `A.get_result`.
Each is declared here as if the schema spelled it out, so it resolves, lays out, gets its
fingerprint and is emitted like any other type; the model's Action entry ties them together.
"""
from __future__ import annotations

from . import identity
from .diagnostics import Span
from .model import Action, Message, Model
from .syntax import ActionDecl, FieldDecl, Literal, MessageDecl, ServiceDecl, TypeExpr

# The goal id: the client's id and a count, each as 8 little-endian bytes (ROS 2's UUID shape).
GOAL_ID_BYTES = 16
# Room for a rejection, cancel or abort reason (the runtime truncates longer ones).
REASON_CAPACITY = 192

# The services an action generates: (suffix of the type names, wire name suffix).
SERVICE_PARTS = (("SendGoal", "send_goal"), ("CancelGoal", "cancel_goal"), ("GetResult", "get_result"))


# What the generated action type holds (C++ member types and static functions, Python class
# attributes): an action so named would declare a member named like its class, which C++ refuses.
MEMBERS = frozenset({"Goal", "Result", "Feedback", "SendGoal", "CancelGoal", "GetResult", "FeedbackMessage",
                     "Status", "ResultMessage", "name", "type_name", "feedback_topic", "status_topic",
                     "result_topic", "goal_type_name", "result_type_name", "feedback_type_name", "fingerprint"})


def generated_names(action: str) -> list[str]:
    """The unqualified names of everything `action` declares, in the order they are generated: each
    service after its request and response, the action last."""
    return [action + suffix for suffix in (
        "Goal", "Result", "Feedback", "SendGoalRequest", "SendGoalResponse", "SendGoal", "CancelGoalRequest",
        "CancelGoalResponse", "CancelGoal", "GetResultRequest", "ResultMessage", "GetResult", "FeedbackMessage",
        "Status")] + [action]


def _type(span: Span, name: str, *args: int) -> TypeExpr:
    return TypeExpr((name,), span, tuple(Literal("int", a, span) for a in args))


def _field(span: Span, name: str, type_expr: TypeExpr, doc: str) -> FieldDecl:
    return FieldDecl(name, span, type_expr, None, (), (doc,))


def _message(span: Span, name: str, doc: str, fields: list[FieldDecl]) -> MessageDecl:
    return MessageDecl(name, span, tuple(fields), (), (), (doc,))


def expand(item: ActionDecl) -> tuple[list[MessageDecl], list[tuple[ServiceDecl, str]]]:
    """The messages (blocks first) and the services (with their wire names) that `item` declares."""
    a, span = item.name, item.span
    u8 = TypeExpr(("u8",), span)
    goal_id = _field(span, "goal_id", TypeExpr(("[]",), span, element=u8, length=Literal("int", GOAL_ID_BYTES, span)),
                     "The goal: the client's id and a count, each 8 little-endian bytes.")
    state = _field(span, "state", u8, "The goal's state (horus::GoalState: 1 accepted ... 7 rejected).")
    stamp = _field(span, "stamp_ns", _type(span, "u64"), "When it happened, in ns of the system clock.")
    reason = _field(span, "reason", _type(span, "string", REASON_CAPACITY),
                    "Why the goal was rejected, aborted or canceled (empty otherwise).")

    def nested(name: str, suffix: str) -> FieldDecl:
        return _field(span, name, TypeExpr((a + suffix,), span), f"The action's {name}.")

    wrappers = [
        _message(span, a + "SendGoalRequest", f"A goal sent to the {a} action (service {a}.send_goal).",
                 [goal_id, nested("goal", "Goal")]),
        _message(span, a + "SendGoalResponse", f"Whether the {a} action accepted a goal.", [
            _field(span, "accepted", _type(span, "bool"), "Whether the server took the goal."),
            _field(span, "stamp_ns", _type(span, "u64"), "When it decided, in ns of the system clock."),
            _field(span, "reason", _type(span, "string", REASON_CAPACITY), "Why it rejected the goal.")]),
        _message(span, a + "CancelGoalRequest", f"A request to cancel a goal of the {a} action "
                 f"(service {a}.cancel_goal; an all-zero id cancels every live goal).", [goal_id]),
        _message(span, a + "CancelGoalResponse", f"What a cancel request of the {a} action did.", [
            _field(span, "return_code", u8, "horus::CancelCode: 0 accepted, 1 rejected, 2 unknown goal, "
                   "3 already done."),
            _field(span, "goals_canceling", _type(span, "u32"), "How many goals it is canceling.")]),
        _message(span, a + "GetResultRequest", f"A request for the outcome of a goal of the {a} action "
                 f"(service {a}.get_result).", [goal_id]),
        _message(span, a + "ResultMessage", f"How a goal of the {a} action ended (topic {a}.result, and "
                 f"the answer of {a}.get_result).", [goal_id, state, stamp, reason, nested("result", "Result")]),
        _message(span, a + "FeedbackMessage", f"Feedback of a goal of the {a} action (topic {a}.feedback).",
                 [goal_id, nested("feedback", "Feedback")]),
        _message(span, a + "Status", f"A goal of the {a} action changed state (topic {a}.status).",
                 [goal_id, state, stamp, reason]),
    ]
    by_name = {m.name: m for m in wrappers}
    services = [(ServiceDecl(a + part, span, by_name[f"{a}{part}Request"],
                             by_name[f"{a}ResultMessage" if part == "GetResult" else f"{a}{part}Response"], (),
                             (f"The {wire} service of the {a} action.",)), f"{a}.{wire}")
                for part, wire in SERVICE_PARTS]
    return [item.goal, item.result, item.feedback] + wrappers, services


def build(model: Model, item: ActionDecl, package: str, source: str) -> Action | None:
    """The model's entry of an action whose parts all resolved (else None: their errors were reported)."""
    q = f"{package}.{item.name}"
    messages = {suffix: model.types.get(q + suffix)
                for suffix in ("Goal", "Result", "Feedback", "FeedbackMessage", "Status", "ResultMessage")}
    services = {part: model.services.get(q + part) for part, _ in SERVICE_PARTS}
    if not all(isinstance(m, Message) for m in messages.values()) or not all(services.values()):
        return None
    goal, result, feedback = messages["Goal"], messages["Result"], messages["Feedback"]
    return Action(package=package, name=item.name, goal=goal, result=result, feedback=feedback,
                  send_goal=services["SendGoal"], cancel_goal=services["CancelGoal"],
                  get_result=services["GetResult"], feedback_message=messages["FeedbackMessage"],
                  status=messages["Status"], result_message=messages["ResultMessage"], docs=item.docs,
                  source=source, fingerprint=identity.fingerprint(identity.action_text(q, goal, result, feedback)))
