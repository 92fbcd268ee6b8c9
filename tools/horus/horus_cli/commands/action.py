"""`horus action`: list, inspect and send goals to a namespace's actions.

An action `A` is three services (`A.send_goal`, `A.cancel_goal`, `A.get_result`) and three topics
(`A.feedback`, `A.status`, `A.result`; runtime/src/action/README.md). Its message classes come from
what the live segments store (the services' request frames, the three topics), as `horus service
call` finds a service's; the two responses no topic may carry yet (send_goal's and cancel_goal's,
fixed by the wire) come from a reply topic, the schema folders (-I), or their fixed declaration
checked against the service's fingerprint. `send` then is a horus.ActionClient of those classes.
"""
from __future__ import annotations

import hashlib
import json
import signal
import time

from horus_cli.common import (EXIT_OK, CommandFailed, did_you_mean, emit, introspection,
                              namespace_name, positive_float, table)
from horus_cli.live import list_topics
from horus_cli.schemas import (build_message, described_types, jsonable, message_class,
                               parse_value, plain, used_class)

SERVICES = ("send_goal", "cancel_goal", "get_result")
TOPICS = ("feedback", "status", "result")
_CANCEL_WAIT = 2.0  # how long Ctrl+C waits for the canceled goal to end

# The two responses whose fields the wire fixes (the contract of every action's services).
_FIXED_RESPONSES = {
    "SendGoalResponse": "  accepted: bool,\n  stamp_ns: u64,\n  reason: string<192>,\n",
    "CancelGoalResponse": "  return_code: u8,\n  goals_canceling: u32,\n",
}


def _actions(args) -> list[dict]:
    """The namespace's actions: where `A.send_goal`, `A.cancel_goal` and topic `A.feedback` are."""
    services = {s["name"]: s for s in introspection().list_services(args.namespace)}
    topics = {t["name"]: t for t in list_topics(args)}
    found = []
    for name, send_goal in services.items():
        action = name.removesuffix(".send_goal")
        if action == name or f"{action}.cancel_goal" not in services or \
                f"{action}.feedback" not in topics:
            continue
        found.append({
            "name": action,
            "type": send_goal["request_type"].removesuffix("SendGoalRequest"),
            "server_pid": send_goal["server_pid"] if send_goal["servers"] else None,
            "services": {verb: services.get(f"{action}.{verb}") for verb in SERVICES},
            "topics": {part: topics.get(f"{action}.{part}") for part in TOPICS},
            "request_topics": {verb: topics.get(f"{action}.{verb}.request") for verb in SERVICES},
        })
    return sorted(found, key=lambda a: a["name"])


def _find_action(args) -> dict:
    actions = _actions(args)
    for action in actions:
        if action["name"] == args.name:
            return action
    raise CommandFailed(f"no action '{args.name}' in namespace '{namespace_name(args)}'"
                        f"{did_you_mean(args.name, [a['name'] for a in actions])}")


def _topic_class(topic: dict | None, what: str):
    if topic is None or not topic["type_name"] or topic["error"]:
        raise CommandFailed(f"the action has no typed {what} topic to learn its type from")
    return message_class(topic["type_name"], topic["schema"], topic["fingerprint"],
                         topic["description"])


def _request_class(action: dict, verb: str):
    """The request payload class of the action's service `verb`, from its request frames."""
    topic = action["request_topics"][verb]
    service = action["services"][verb]
    if service is None:
        raise CommandFailed(f"action '{action['name']}' has no service {action['name']}.{verb}")
    frame = _topic_class(topic, f"{action['name']}.{verb}.request")
    return used_class(frame, service["request_type"])


def _fingerprint(text: str) -> int:
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big")


def _response_class(args, action: dict, verb: str, request_class):
    """send_goal's or cancel_goal's response class: from a reply topic of the service, else the
    schema folders (-I), else the fixed declaration, each checked against the service's
    fingerprint (over both its messages)."""
    service = action["services"][verb]
    name = service["response_type"]
    prefix = f"{action['name']}.{verb}.response."
    candidates = []
    for topic in list_topics(args):
        if topic["name"].startswith(prefix) and topic["type_name"] and not topic["error"]:
            candidates.append(lambda t=topic: used_class(_topic_class(t, t["name"]), name))
            break
    if args.include:
        try:
            described = next((t for t in described_types(args) if t["name"] == name), None)
        except CommandFailed:  # no schema there that reads: the other sources may still tell
            described = None
        if described is not None:
            candidates.append(lambda: message_class(name, described["schema"],
                                                    int(described["fingerprint"], 16)))
    suffix = name[len(action["type"]):]
    if suffix in _FIXED_RESPONSES:
        from horus import typedesc
        candidates.append(lambda: typedesc.load_type(
            name, f"message {name} {{\n{_FIXED_RESPONSES[suffix]}}}\n", None))
    qualified = action["type"] + "".join(part.capitalize() for part in verb.split("_"))
    request = request_class.__horus__
    for make in candidates:
        cls = make()
        text = (f"service {qualified} {{\n  request: {request.name}#{request.fingerprint:016x},\n"
                f"  response: {name}#{cls.__horus__.fingerprint:016x},\n}}\n")
        if _fingerprint(text) == service["fingerprint"]:
            return cls
    raise CommandFailed(f"cannot tell the type {name} of the responses of service "
                        f"{action['name']}.{verb}: -I DIR, the folder of its .haction file, "
                        "lets it be")


def _action_class(args, action: dict):
    """A class standing for the generated action class, made from the live segments."""
    name = action["name"]
    send_request = _request_class(action, "send_goal")
    cancel_request = _request_class(action, "cancel_goal")
    result_message = _topic_class(action["topics"]["result"], f"{name}.result")
    feedback_message = _topic_class(action["topics"]["feedback"], f"{name}.feedback")
    status = _topic_class(action["topics"]["status"], f"{name}.status")

    def service(verb, request, response):
        return type(f"{name}.{verb}", (), {
            "name": f"{name}.{verb}", "request_topic": f"{name}.{verb}.request",
            "response_topic": f"{name}.{verb}.response", "Request": request, "Response": response,
            "fingerprint": action["services"][verb]["fingerprint"]})

    verbs = {
        "SendGoal": service("send_goal", send_request,
                            _response_class(args, action, "send_goal", send_request)),
        "CancelGoal": service("cancel_goal", cancel_request,
                              _response_class(args, action, "cancel_goal", cancel_request)),
        "GetResult": service("get_result", _request_class(action, "get_result"), result_message),
    }
    return type(name, (), {
        **verbs, "name": name, "type_name": action["type"],
        "Goal": type(send_request().goal), "Result": type(result_message().result),
        "Feedback": type(feedback_message().feedback), "FeedbackMessage": feedback_message,
        "Status": status, "ResultMessage": result_message, "feedback_topic": f"{name}.feedback",
        "status_topic": f"{name}.status", "result_topic": f"{name}.result"})


def _last_status(action: dict, cls) -> str:
    """The newest status the action's server published: `<state> <goal id>`, or "-"."""
    topic = action["topics"]["status"]
    if topic is None or not topic["type_name"] or topic["error"] or not topic["message_count"]:
        return "-"
    from horus import GoalId, GoalState
    handle = introspection().open_topic(
        topic["name"], topic["type_name"], topic["fingerprint"], topic["schema"], topic["is_pod"],
        cls.__horus__.size if topic["is_pod"] else 0,
        cls.__horus__.alignment if topic["is_pod"] else 1, topic["capacity"],
        topic["max_message_size"], topic["single_publisher"], topic["description"])
    data = handle.read_latest()
    if data is None:
        return "-"
    status = cls.from_bytes(data)
    state = GoalState(status.state) if status.state <= max(GoalState) else status.state
    return f"{state} {GoalId.from_bytes(status.goal_id)}"


def action_list(args) -> int:
    rows = []
    for action in _actions(args):
        try:
            status = _topic_class(action["topics"]["status"], "status")
            last = _last_status(action, status)
        except CommandFailed:
            last = "-"
        rows.append({"name": action["name"], "type": action["type"],
                     "server_pid": action["server_pid"], "last_status": last})
    emit(rows, args.json, lambda items: table(
        ["ACTION", "TYPE", "SERVER", "LAST_STATUS"],
        [[r["name"], r["type"], r["server_pid"] or "-", r["last_status"]] for r in items]))
    return EXIT_OK


def action_info(args) -> int:
    action = _find_action(args)
    cls = _action_class(args, action)
    parts = {role: getattr(cls, role).__horus__ for role in ("Goal", "Result", "Feedback")}
    identity = "".join(f"  {role.lower()}: {info.name}#{info.fingerprint:016x},\n"
                       for role, info in parts.items())
    info = {
        "name": action["name"], "type": action["type"],
        "fingerprint": _fingerprint(f"action {action['type']} {{\n{identity}}}\n"),
        "server_pid": action["server_pid"],
        "services": {verb: {"name": f"{action['name']}.{verb}",
                            "request": service["request_type"],
                            "response": service["response_type"]}
                     for verb, service in action["services"].items() if service is not None},
        "topics": {part: {"name": topic["name"], "type": topic["type_name"]}
                   for part, topic in action["topics"].items() if topic is not None},
        "schemas": {role.lower(): part.schema for role, part in parts.items()},
    }

    def render(i):
        print(f"action: {i['name']}")
        print(f"type: {i['type']}")
        print(f"fingerprint: {i['fingerprint']:016x}")
        print(f"server: {'pid ' + str(i['server_pid']) if i['server_pid'] else 'none'}")
        print("services:")
        for service in i["services"].values():
            print(f"  {service['name']}: {service['request']} -> {service['response']}")
        print("topics:")
        for topic in i["topics"].values():
            print(f"  {topic['name']}: {topic['type']}")
        for role, schema in i["schemas"].items():
            print(f"{role}:")
            print("".join(f"  {line}\n" for line in schema.rstrip().splitlines()), end="")
    emit(info, args.json, render)
    return EXIT_OK


class _Printer:
    """The lines `send` prints: text, or one JSON object a line with --json."""

    def __init__(self, as_json: bool) -> None:
        self.as_json = as_json

    def event(self, kind: str, text: str, **fields) -> None:
        if self.as_json:
            print(json.dumps({"event": kind, **jsonable(fields)}), flush=True)
        else:
            print(text, flush=True)


def _flow(value) -> str:
    """A message's fields on one line: `{step: 1, remaining_m: 4.75}`."""
    try:
        import yaml
    except ImportError:  # python3-yaml missing: JSON is YAML too
        return json.dumps(jsonable(value))
    return yaml.safe_dump(jsonable(value), default_flow_style=True, sort_keys=False,
                          width=1 << 20).strip()


def action_send(args) -> int:
    import horus

    action = _find_action(args)
    if action["server_pid"] is None:
        raise CommandFailed(f"action '{args.name}' has no live server")
    cls = _action_class(args, action)
    goal = build_message(cls.Goal, parse_value(args.goal, f"goal for {cls.Goal.__horus__.name}"))
    out = _Printer(args.json)
    client = horus.ActionClient(cls)
    try:
        try:
            handle = client.send_goal(goal, timeout=args.timeout)
        except horus.ServiceError as error:
            raise CommandFailed(f"action '{args.name}': {error}") from None
        if handle.state == horus.GoalState.Rejected:
            raise CommandFailed(f"goal {handle.goal_id} rejected: {handle.reason}")
        out.event("accepted", f"goal {handle.goal_id} accepted", goal_id=str(handle.goal_id))
        return _follow(args, handle, out)
    finally:
        client.close()


def _follow(args, handle, out: _Printer) -> int:
    import horus

    deadline = None if args.result_timeout is None else time.monotonic() + args.result_timeout
    shown = horus.GoalState.Accepted
    try:
        while not handle.done:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                handle.cancel()
                raise CommandFailed(f"goal {handle.goal_id} did not end within "
                                    f"{args.result_timeout:g} s: canceled")
            feedback = handle.next_feedback(0.05 if left is None else min(0.05, left))
            shown = _show_state(out, handle, shown)
            if feedback is not None and not args.no_feedback:
                out.event("feedback", f"feedback: {_flow(plain(feedback))}",
                          feedback=plain(feedback))
    except KeyboardInterrupt:
        # Ctrl+C: the goal is canceled, not left running on the server.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            handle.cancel()
        except horus.ServiceError as error:
            raise CommandFailed(f"goal {handle.goal_id}: the cancel got no answer ({error})") \
                from None
        try:
            handle.result(_CANCEL_WAIT)
        except horus.ServiceTimeout:
            raise CommandFailed(f"goal {handle.goal_id} still runs {_CANCEL_WAIT:g} s after "
                                "its cancel") from None
    while (feedback := handle.try_feedback()) is not None and not args.no_feedback:
        out.event("feedback", f"feedback: {_flow(plain(feedback))}", feedback=plain(feedback))
    _show_state(out, handle, shown)
    ended = handle.result(0)
    state = str(ended.state)
    if ended.succeeded:
        out.event("result", f"succeeded: {_flow(plain(ended.result))}", state=state,
                  reason=ended.reason, result=plain(ended.result))
        return EXIT_OK
    out.event("result", state, state=state, reason=ended.reason, result=plain(ended.result))
    raise CommandFailed(f"goal {handle.goal_id} {state}: {ended.reason or '(no reason given)'}")


def _show_state(out: _Printer, handle, shown):
    """Prints the goal's state when it moved on from `shown` and has not ended (the end is
    printed with the result); the state shown now."""
    state = handle.state
    if state != shown and not state.terminal:
        reason = handle.reason
        out.event("state", f"{state}" + (f": {reason}" if reason else ""), state=str(state),
                  reason=reason)
        return state
    return shown


def register(commands) -> None:
    action = commands.group("action", "actions: list, inspect, send goals")
    commands.action(action, "list", "the namespace's actions: type, server, newest status",
                    action_list)
    sub = commands.action(action, "info", "one action: type, fingerprint, server, services, "
                                          "topics, schemas", action_info)
    sub.add_argument("name", metavar="ACTION")
    sub.add_argument("-I", dest="include", action="append", metavar="DIR",
                     help="schema folder declaring the action, when no live topic tells a type")

    sub = commands.action(action, "send", "send a goal given as YAML or JSON, print its feedback "
                                          "and result (Ctrl+C cancels it)", action_send)
    sub.add_argument("name", metavar="ACTION")
    sub.add_argument("goal", help="the goal's fields, e.g. '{x: 2.0, y: 1.0}'; fields left out "
                                  "take their defaults")
    sub.add_argument("--timeout", type=positive_float, default=2.0, metavar="SECONDS",
                     help="how long to wait for the server to accept or reject (default 2)")
    sub.add_argument("--result-timeout", type=positive_float, default=None, metavar="SECONDS",
                     help="how long to wait for the result before canceling (default: as long "
                          "as it takes)")
    sub.add_argument("--no-feedback", action="store_true", help="print no feedback lines")
    sub.add_argument("-I", dest="include", action="append", metavar="DIR",
                     help="schema folder declaring the action, when no live topic tells a type")
