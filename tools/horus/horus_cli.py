"""The `horus` command: see and clean a running HORUS system from the shell.

Every listing takes --json; exit status is 0 on success, 1 when something asked for is not found
(or a wait timed out) and 2 on a usage error. Errors are one line on stderr, never a traceback.
Imports of the runtime happen inside the subcommands, so `--help` and completion stay instant.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

EXIT_OK, EXIT_NOT_FOUND, EXIT_USAGE = 0, 1, 2

# Filled in by the launcher (bin/horus) with the horus-blackbox beside it.
BLACKBOX_PROGRAM = os.environ.get("HORUS_BLACKBOX_PROGRAM", "horus-blackbox")
# And with the horus-remote beside it (`horus remote serve|connect`).
REMOTE_PROGRAM = os.environ.get("HORUS_REMOTE_PROGRAM", "horus-remote")

# The installed schemas `horus msg` describes (set by the launcher, as is HORUS_GEN_PROGRAM, the
# schema compiler dynamic_types runs).
SCHEMA_DIR = os.environ.get("HORUS_SCHEMA_DIR", "")

LEVELS = ("debug", "info", "warn", "error")


def positive_float(text: str) -> float:
    """An argparse type: a number above 0 (a window, a rate, a timeout of 0 or less would
    busy-loop, divide by zero or never end)."""
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"needs a number above 0, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    """An argparse type: a finite number of 0 or more (an offset into a recording)."""
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"needs a number of 0 or more, got {text!r}")
    return value


def refresh_interval(text: str) -> float:
    """An argparse type: seconds between screen refreshes, at least 0.1 (curses waits for keys in
    whole milliseconds; shorter would redraw without pause and take a CPU)."""
    value = positive_float(text)
    if value < 0.1:
        raise argparse.ArgumentTypeError(f"needs at least 0.1 seconds, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An argparse type: a whole number above 0 (a count of 0 would mean forever)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value <= 0:
        raise argparse.ArgumentTypeError(f"needs a whole number above 0, got {text!r}")
    return value


class CommandFailed(Exception):
    """A failure reported as one line on stderr, with its exit status."""

    def __init__(self, message: str, status: int = EXIT_NOT_FOUND) -> None:
        super().__init__(message)
        self.status = status


def _core():
    from horus import _core  # deferred: loading the extension is most of the start-up time
    return _core


def _emit(rows, as_json: bool, render) -> None:
    if as_json:
        json.dump(rows, sys.stdout, indent=2, sort_keys=True)
        sys.stdout.write("\n")
    else:
        render(rows)


def _table(header: list[str], rows: list[list[str]]) -> None:
    widths = [max(len(str(row[i])) for row in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  ".join(str(cell).ljust(width) for cell, width in zip(row, widths)).rstrip())


def _names_or_table(args, header: list[str], row):
    """The renderer of a listing: names alone, or with -v a table of `row(item)`."""
    def render(items):
        if args.verbose:
            _table(header, [row(item) for item in items])
        else:
            for item in items:
                print(item["name"])
    return render


def _topics(args) -> list[dict]:
    return _core().list_topics(args.namespace)


def _namespace(args) -> str:
    return args.namespace or _core().current_namespace()


def _close_names(name: str, known) -> list[str]:
    """Those of `known` closest to a name that is not one of them, the closest first."""
    import difflib
    return difflib.get_close_matches(name, sorted(set(known)), n=3, cutoff=0.6)


def _suggestion(close: list[str]) -> str:
    return "; did you mean " + " or ".join(f"'{name}'" for name in close) + "?" if close else ""


def _did_you_mean(name: str, known) -> str:
    return _suggestion(_close_names(name, known))


# The types of the topics a service runs on (runtime/src/service/README.md): its registration,
# its requests and its replies. `topic list` leaves them out unless --include-hidden.
SERVICE_TYPES = ("horus.ServiceRegistration", "horus.ServiceRequest<", "horus.ServiceResponse<")


def _internal(topic: dict) -> bool:
    """Whether a topic is one a service runs on (by its type: only services use these)."""
    return topic["type_name"].startswith(SERVICE_TYPES)


def _missing_topic(args, name: str, topics: list[dict], within: str = "",
                   hint: str = "") -> CommandFailed:
    """The one error of every command for a topic that does not exist."""
    return CommandFailed(f"no topic '{name}' in namespace '{_namespace(args)}'{within}"
                         f"{_did_you_mean(name, [t['name'] for t in topics])}{hint}")


def _find_topic(args, name: str) -> dict:
    topics = _topics(args)
    for topic in topics:
        if topic["name"] == name:
            return topic
    raise _missing_topic(args, name, topics)


def _utc(seconds: float, digits: int = 0) -> str:
    """A wall-clock time as ISO 8601 UTC, with `digits` decimals of the second (rounded first,
    so that 12.999 with two decimals is 13.00, not 12.00)."""
    scale = 10 ** digits
    units = round(seconds * scale)
    text = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(units // scale))
    if digits:
        text += f".{units % scale:0{digits}d}"
    return text + "Z"


def _started(started_wall_ns: int) -> str:
    """When a process started (to the kernel's clock tick: two decimals), or "?"."""
    return _utc(started_wall_ns / 1e9, 2) if started_wall_ns else "?"


# A rate from fewer messages than this is off by more than a tenth (one message either way).
ENOUGH_MESSAGES = 10


def _stamped_rate(traffic: dict, now: float) -> tuple[float, int] | None:
    """(rate, messages it spans) from the whole-second send stamps of the messages still in the
    ring, from the first change of second to the last (each within one period of its stamp), or
    None while they hold fewer than two changes. 0 once two periods passed without a message:
    its publishers stopped."""
    first, last = traffic["first_new_second"], traffic["last_new_second"]
    if first is None or last["second"] <= first["second"]:
        return None
    messages = last["ticket"] - first["ticket"]
    rate = messages / (last["second"] - first["second"])
    # The newest message went out within the second its stamp names.
    if now - (traffic["newest"]["second"] + 1) > 2 / rate:
        return 0.0, messages
    return rate, messages


def _best_rate(*estimates: tuple[float, int] | None) -> float | None:
    """The rate of the estimate that counted the most messages: the one least off."""
    known = [estimate for estimate in estimates if estimate is not None]
    return max(known, key=lambda estimate: estimate[1])[0] if known else None


def _traffic(core, args, name: str) -> dict | None:
    """A topic's traffic over its whole ring, or None when it cannot be read (removed meanwhile,
    or its segment's error, which the listing shows)."""
    try:
        return core.topic_traffic(name, 0, args.namespace)
    except core.HorusError:
        return None


def _measure_rates(args, topics: list[dict]) -> None:
    """Sets each topic's rate_hz from its send stamps; those whose stamps span too few messages
    while they still send are also counted over --window, one wait for all of them."""
    core = _core()
    now = time.time()
    stamped, counting = {}, {}
    for topic in topics:
        traffic = _traffic(core, args, topic["name"])
        if traffic is None:
            continue
        stamped[topic["name"]] = estimate = _stamped_rate(traffic, now)
        newest = traffic["newest"]
        sending = newest is not None and newest["second"] + 2 >= now
        if sending and (estimate is None or estimate[1] < ENOUGH_MESSAGES):
            counting[topic["name"]] = (traffic["message_count"], time.monotonic())
    if counting:
        time.sleep(args.window)
    for topic in topics:
        name = topic["name"]
        counted = None
        if name in counting:
            traffic = _traffic(core, args, name)
            before, since = counting[name]
            if traffic is not None and traffic["message_count"] >= before:
                messages = traffic["message_count"] - before
                counted = messages / (time.monotonic() - since), messages
        rate = _best_rate(stamped.get(name), counted)
        topic["rate_hz"] = None if name not in stamped else round(rate or 0.0, 1)


def topic_list(args) -> int:
    topics = _topics(args)
    if not args.include_hidden:
        topics = [topic for topic in topics if not _internal(topic)]
    if args.verbose:
        _measure_rates(args, topics)

    render = _names_or_table(
        args, ["TOPIC", "TYPE", "PUBS", "SUBS", "RATE_HZ", "MESSAGES"],
        lambda r: [r["name"], r["type_name"] or "-", r["publishers"], r["subscribers"],
                   "-" if r.get("rate_hz") is None else f"{r['rate_hz']:.1f}", r["message_count"]])
    _emit(topics, args.json, render)
    return EXIT_OK


def topic_info(args) -> int:
    topic = _find_topic(args, args.topic)
    topic["processes"] = [{"pid": p["pid"], "program": p["program"]} for p in _processes(args)
                          if any(t["topic"] == args.topic for t in p["topics"])]

    def render(t):
        if t["error"]:
            print(f"error: {t['error']}")
        print(f"topic: {t['name']}")
        print(f"type: {t['type_name'] or '(not chosen yet)'}")
        print(f"fingerprint: {t['fingerprint']:016x}")
        print(f"encoding: {'POD' if t['is_pod'] else 'serialized'}")
        print(f"capacity: {t['capacity']} slots of {t['max_message_size']} bytes")
        print(f"single publisher: {'yes' if t['single_publisher'] else 'no'}")
        print(f"publishers: {t['publishers']}")
        print(f"subscribers: {t['subscribers']}")
        print(f"messages sent: {t['message_count']}")
        users = ", ".join(f"pid {p['pid']} ({p['program']})" for p in t["processes"]) or "none"
        print(f"open in: {users}")
        if t["last_send_s"] is not None:
            print(f"last send: {_utc(t['last_send_s'])}")
        if t["schema"]:
            print("schema:")
            for line in t["schema"].splitlines():
                print(f"  {line}")
    _emit(topic, args.json, render)
    return EXIT_OK


def _measure_traffic(args, on_window) -> None:
    """Samples a topic's slot headers every 20 ms (fast enough not to be lapped by the ring at a
    few kHz) and hands each window's figures to `on_window`, forever or once with --once. A
    topic removed meanwhile (its last user ended) counts nothing until it is created again."""
    core = _core()
    _find_topic(args, args.topic)
    since = core.topic_traffic(args.topic, 0, args.namespace)["message_count"]
    gone = False
    while True:
        start = time.monotonic()
        messages = counted = size = 0
        while time.monotonic() - start < args.window:
            time.sleep(0.02)
            try:
                traffic = core.topic_traffic(args.topic, since, args.namespace)
                if traffic["message_count"] < since:  # removed and created again meanwhile
                    since = 0
                    traffic = core.topic_traffic(args.topic, since, args.namespace)
            except core.HorusError as error:
                if any(t["name"] == args.topic for t in _topics(args)):
                    raise CommandFailed(str(error)) from None
                if not gone:
                    print(f"horus: topic '{args.topic}' was removed (its last user ended); "
                          "counting again once it is back", file=sys.stderr, flush=True)
                gone, since = True, 0
                continue
            gone = False
            messages += traffic["message_count"] - since
            counted += traffic["counted"]
            size += traffic["bytes"]
            since = traffic["message_count"]
        elapsed = time.monotonic() - start
        # Messages overwritten between two samples count with the mean size of the others.
        total_bytes = size * messages / counted if counted else 0
        window = {"topic": args.topic, "window_s": round(elapsed, 3), "messages": messages,
                  "rate_hz": round(messages / elapsed, 2), "bytes": int(total_bytes),
                  "bytes_per_s": round(total_bytes / elapsed, 1),
                  "mean_message_bytes": round(size / counted, 1) if counted else None}
        on_window(window)
        if args.once:
            return


def topic_hz(args) -> int:
    def show(w):
        if args.json:
            print(json.dumps(w, sort_keys=True), flush=True)
        else:
            print(f"average rate: {w['rate_hz']:.2f} Hz ({w['messages']} messages in "
                  f"{w['window_s']:.2f} s)", flush=True)
    _measure_traffic(args, show)
    return EXIT_OK


def _bytes(value: float) -> str:
    for unit in ("B", "KB", "MB"):
        if value < 1000 or unit == "MB":
            return f"{value:.1f} {unit}" if unit != "B" else f"{value:.0f} B"
        value /= 1000
    return ""


def topic_bw(args) -> int:
    def show(w):
        if args.json:
            print(json.dumps(w, sort_keys=True), flush=True)
        else:
            mean = "-" if w["mean_message_bytes"] is None else _bytes(w["mean_message_bytes"])
            print(f"bandwidth: {_bytes(w['bytes_per_s'])}/s, mean message {mean} "
                  f"({w['messages']} messages in {w['window_s']:.2f} s)", flush=True)
    _measure_traffic(args, show)
    return EXIT_OK


def _typed_topic(args, name: str) -> dict:
    topic = _find_topic(args, name)
    if topic["error"]:
        raise CommandFailed(f"topic '{name}' cannot be read: {topic['error']}")
    if not topic["type_name"]:
        raise CommandFailed(f"topic '{name}' has no type yet: no handle has opened it with one")
    return topic


def _message_class(type_name: str, schema: str, fingerprint: int):
    """The class of a type from its stored schema (dynamic_types), errors as one line."""
    import dynamic_types
    try:
        return dynamic_types.load_type(type_name, schema, fingerprint)
    except dynamic_types.SchemaError as error:
        raise CommandFailed(str(error)) from None


def _open_topic(topic: dict, cls):
    """A handle on a live topic with the identity its segment records."""
    info = cls.__horus__
    return _core().Topic(topic["name"], topic["type_name"], topic["fingerprint"], topic["schema"],
                         topic["is_pod"], info.size if topic["is_pod"] else 0,
                         info.alignment if topic["is_pod"] else 1, topic["capacity"],
                         topic["max_message_size"], topic["single_publisher"])


def _parse_value(text: str, what: str):
    """A YAML (or JSON, which YAML reads too) mapping given on the command line."""
    try:
        import yaml
    except ImportError:  # python3-yaml missing: JSON still works
        yaml = None
    try:
        value = yaml.safe_load(text) if yaml is not None else json.loads(text)
    except Exception as error:  # noqa: BLE001 (yaml and json raise their own error types)
        reason = " ".join(str(error).split()) or type(error).__name__
        raise CommandFailed(f"cannot parse the {what} {text!r}: {reason}", EXIT_USAGE) from None
    return {} if value is None else value


# The type of the Python runtime's dict topics: any plain value, as MessagePack in `data`.
# echo shows (and pub takes) that value rather than the bytes.
PLAIN_VALUES = "horus.msg.GenericMessage"


def _build(cls, value):
    import dynamic_types
    try:
        if cls.__horus__.name == PLAIN_VALUES:
            import msgpack
            return dynamic_types.from_plain(cls, {"data": msgpack.packb(value, use_bin_type=True)})
        return dynamic_types.from_plain(cls, value)
    except (ValueError, TypeError) as error:
        raise CommandFailed(str(error)) from None


def _plain(message):
    """What echo and call show of a message: its fields, or a plain-values message's value."""
    import dynamic_types
    plain = dynamic_types.to_plain(message)
    if type(message).__horus__.name == PLAIN_VALUES and plain["metadata"] is None:
        import msgpack
        try:
            return msgpack.unpackb(plain["data"], raw=False, strict_map_key=False)
        except (ValueError, msgpack.UnpackException):
            pass  # not one MessagePack value: shown as its fields
    return plain


def _plain_field(plain, path: str | None, type_name: str, checking: bool = False):
    """The field `path` (a.b, list elements by index) of a plain message. `checking` a default
    message, whose lists are empty and options None, what lies below them is not checked."""
    if not path:
        return plain
    value = plain
    for part in path.split("."):
        if checking and (value is None or isinstance(value, list)):
            return None
        if isinstance(value, dict) and part in value:
            value = value[part]
        elif isinstance(value, list) and part.isdigit() and int(part) < len(value):
            value = value[int(part)]
        else:
            known = ", ".join(value) if isinstance(value, dict) else f"indexes 0..{len(value) - 1}" \
                if isinstance(value, list) else "nothing (not a message)"
            raise CommandFailed(f"{type_name} has no field '{path}' ('{part}' is not one of: {known})")
    return value


def _jsonable(value):
    if isinstance(value, bytes):
        return list(value)
    if isinstance(value, dict):
        return {key: _jsonable(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_jsonable(item) for item in value]
    return value


def _show_message(value, as_json: bool) -> None:
    value = _jsonable(value)
    if as_json:
        print(json.dumps(value), flush=True)
    elif not isinstance(value, (dict, list)):
        print(value, flush=True)
    else:
        print(_yaml_text(value) + "---", flush=True)


def _yaml_text(value) -> str:
    """Block YAML with lists on one line each (as ros2 topic echo prints them, roughly)."""
    try:
        import yaml
    except ImportError:  # python3-yaml missing: JSON is YAML too
        return json.dumps(value, indent=2) + "\n"

    class Dumper(yaml.SafeDumper):
        pass
    Dumper.add_representer(list, lambda dumper, items: dumper.represent_sequence(
        "tag:yaml.org,2002:seq", items, flow_style=True))
    return yaml.dump(value, Dumper=Dumper, sort_keys=False, default_flow_style=False, width=100)


def _awaited_topic(args, deadline: float | None) -> dict:
    """The typed topic `args.topic`; with a deadline, waited for until then (its publisher may
    not have started yet)."""
    while True:
        try:
            return _typed_topic(args, args.topic)
        except CommandFailed as failure:
            if deadline is None:
                raise
            if time.monotonic() >= deadline:
                topics = _topics(args)
                if not any(t["name"] == args.topic for t in topics):
                    raise _missing_topic(args, args.topic, topics,
                                         within=f" within {args.timeout:g} s") from None
                raise failure from None
        time.sleep(0.05)


def topic_echo(args) -> int:
    deadline = None if args.timeout is None else time.monotonic() + args.timeout
    topic = _awaited_topic(args, deadline)
    cls = _message_class(topic["type_name"], topic["schema"], topic["fingerprint"])
    handle = _open_topic(topic, cls)
    # The newest message already sent comes first (a topic is latched), then each new one. Once
    # a message came after the handle opened, the newest one may be that or a later one, which
    # the handle receives in order anyway: then it is left out, never shown twice.
    data = handle.read_latest()
    if handle.has_msg():
        data = None
    if cls.__horus__.name != PLAIN_VALUES:  # a plain value has no fields to check beforehand
        _plain_field(_plain(cls()), args.field, topic["type_name"], checking=True)

    def show(data) -> None:
        try:
            message = cls.from_bytes(data)
        except ValueError as error:
            raise CommandFailed(f"topic '{args.topic}': a message does not decode: {error}") from None
        _show_message(_plain_field(_plain(message), args.field, topic["type_name"]), args.json)

    shown = 0
    while True:
        if data is not None:
            show(data)
            shown += 1
            if args.once or (args.count and shown >= args.count):
                return EXIT_OK
        wait = 0.1 if deadline is None else deadline - time.monotonic()
        if wait <= 0:
            raise CommandFailed(f"no message on topic '{args.topic}' within {args.timeout:g} s")
        data = handle.recv(min(wait, 0.1))


def _new_topic(args) -> dict:
    """What a topic nobody opened yet is given by `pub --type`: the type from the schemas (-I,
    else the installed ones), the runtime's default geometry."""
    described = _described_type(args)
    if described["kind"] != "message":
        raise CommandFailed(f"'{described['name']}' is a {described['kind']}, not a message type")
    pod = described["tier"] == "pod"
    return {"name": args.topic, "type_name": described["name"], "schema": described["schema"],
            "fingerprint": int(described["fingerprint"], 16), "is_pod": pod, "capacity": 64,
            "max_message_size": 16 * 1024, "single_publisher": False, "error": ""}


def topic_pub(args) -> int:
    topics = _topics(args)
    if args.type is None:
        if not any(t["name"] == args.topic for t in topics):
            raise _missing_topic(args, args.topic, topics, hint=" (give --type TYPE to create it)")
        topic = _typed_topic(args, args.topic)
    else:
        topic = next((t for t in topics if t["name"] == args.topic and t["type_name"]), None)
        if topic is None:
            topic = _new_topic(args)
        elif args.type not in (topic["type_name"], topic["type_name"].rsplit(".", 1)[-1]):
            try:
                given = _described_type(args)["name"]
            except CommandFailed:  # not in the schemas either: named as given
                given = args.type
            raise CommandFailed(f"topic '{args.topic}' carries {topic['type_name']}, not "
                                f"{given} (--type)")
    cls = _message_class(topic["type_name"], topic["schema"], topic["fingerprint"])
    message = _build(cls, _parse_value(args.value, f"value for {topic['type_name']}"))
    payload = message.to_bytes()
    if not topic["is_pod"] and len(payload) > topic["max_message_size"]:
        raise CommandFailed(f"the message is {len(payload)} bytes, topic '{args.topic}' holds at "
                            f"most {topic['max_message_size']}")
    handle = _open_topic(topic, cls)
    period = 1.0 / (args.rate or 1.0)
    sent = 0
    next_send = time.monotonic()
    while True:
        if not handle.send(payload):
            stats = {key: value for key, value in handle.stats().items() if value}
            raise CommandFailed(f"topic '{args.topic}' refused the message ({stats or 'no room'})")
        sent += 1
        if args.once or (args.count and sent >= args.count):
            print(f"published {sent} message{'s' if sent != 1 else ''} on '{args.topic}'", flush=True)
            return EXIT_OK
        if sent == 1 and not args.count:
            print(f"publishing on '{args.topic}' at {1 / period:g} Hz until Ctrl+C", flush=True)
        next_send += period
        time.sleep(max(0.0, next_send - time.monotonic()))


def service_list(args) -> int:
    services = _core().list_services(args.namespace)

    render = _names_or_table(
        args, ["SERVICE", "REQUEST", "RESPONSE", "SERVERS", "SERVER_PID", "CLIENTS"],
        lambda r: [r["name"], r["request_type"], r["response_type"], r["servers"],
                   r["server_pid"] or "-", r["clients"]])
    _emit(services, args.json, render)
    return EXIT_OK


def service_info(args) -> int:
    service = _find_service(args)
    service["client_processes"] = [
        {"pid": p["pid"], "program": p["program"]} for p in _processes(args)
        if any(s["service"] == args.service and s["role"] == "client" for s in p["services"])]

    def render(s):
        print(f"service: {s['name']}")
        print(f"request: {s['request_type']}")
        print(f"response: {s['response_type']}")
        print(f"fingerprint: {s['fingerprint']:016x}")
        server = f"pid {s['server_pid']}" if s["servers"] else "none (stopped or died)"
        print(f"server: {server}")
        callers = ", ".join(f"pid {p['pid']} ({p['program']})" for p in s["client_processes"])
        print(f"clients: {s['clients']}" + (f" in {callers}" if callers else ""))
    _emit(service, args.json, render)
    return EXIT_OK


def _find_service(args) -> dict:
    services = _core().list_services(args.namespace)
    for service in services:
        if service["name"] == args.service:
            return service
    raise CommandFailed(f"no service '{args.service}' in namespace '{_namespace(args)}'"
                        f"{_did_you_mean(args.service, [s['name'] for s in services])}")


def _frame_payload(args, topic: dict, payload_type: str, response: bool):
    """The payload class of a service frame topic, from its stored schema (the frame's own
    declaration, then the payload's), checked against the frame's fingerprint."""
    from horus._service import _Frame
    frame_text = topic["schema"]
    payload_text = frame_text[frame_text.find("\n}\n") + 3:]
    cls = _message_class(payload_type, payload_text, None)
    frame = _Frame(cls, response=response)
    if frame.fingerprint != topic["fingerprint"] or frame.name != topic["type_name"]:
        raise CommandFailed(f"topic '{topic['name']}' carries {topic['type_name']}, not the "
                            f"frame of {payload_type} this command builds")
    return frame


def _reply_topics(args, service: dict) -> tuple[dict | None, int]:
    """(a typed reply topic of the service, to learn the response type from; the smallest
    reply index no live client receives on)."""
    prefix = f"{service['name']}.response."
    typed, taken = None, set()
    for topic in _topics(args):
        suffix = topic["name"][len(prefix):]
        if not topic["name"].startswith(prefix) or not suffix.isdigit():
            continue
        if topic["subscribers"]:
            taken.add(int(suffix))
        if topic["type_name"] and not topic["error"] and typed is None:
            typed = topic
    return typed, next(index for index in range(len(taken) + 1) if index not in taken)


# A response frame's status (horus/detail/service_frame.hpp) as the kind of error a client
# raises: a forwarding server (the remote link's stand-in) answers a call it could not get
# answered with the kind a caller beside the real server would get.
_CALL_FAILURE_KINDS = {1: "ServiceFailed", 2: "NoServer", 3: "Timeout", 4: "Transport"}


def _response_frames(args, service: dict, typed: dict | None):
    """The frame of the service's responses: from a typed reply topic, else from the schema
    folders (-I, else the installed schemas) when they declare the response type; None when
    neither tells it."""
    if typed is not None:
        return _frame_payload(args, typed, service["response_type"], response=True)
    try:
        types = _described_types(args)
    except CommandFailed:  # no schema folder, or none that reads: the type is not known here
        return None
    # Only a declaration of this very service (its fingerprint covers both types): an older
    # schema of the response type would make a reply topic the server cannot open.
    if not any(t.get("kind") == "service" and t.get("response") == service["response_type"]
               and int(t["fingerprint"], 16) == service["fingerprint"] for t in types):
        return None
    described = next((t for t in types if t["name"] == service["response_type"]), None)
    if described is None:
        return None
    from horus._service import _Frame
    try:
        cls = _message_class(described["name"], described["schema"],
                             int(described["fingerprint"], 16))
    except CommandFailed:  # a schema that does not compile alone: left to the server, as before
        return None
    return _Frame(cls, response=True)


def service_call(args) -> int:
    from horus._service import _alive, _endpoint_id
    service = _find_service(args)
    if not service["servers"]:
        raise CommandFailed(f"service '{args.service}' has no live server")
    topics = {t["name"]: t for t in _topics(args)}
    request_topic = topics.get(f"{args.service}.request")
    if request_topic is None or not request_topic["type_name"]:
        raise CommandFailed(f"service '{args.service}' has no request topic to learn its type from")
    requests = _frame_payload(args, request_topic, service["request_type"], response=False)
    request = _build(requests.payload_type, _parse_value(
        args.value, f"request for {service['request_type']}"))

    typed, index = _reply_topics(args, service)
    reply_name = f"{args.service}.response.{index}"
    replies = None
    # With the response type known, the command receives on its reply topic from the start, as
    # a client does: a server that forwards the call elsewhere (`horus remote connect`'s
    # stand-in) can then always answer it, also with a failure that no server's answer ever
    # showed it the type for.
    responses = _response_frames(args, service, typed)
    if responses is not None:
        replies = responses.open(reply_name)
        replies.try_recv()  # marks this handle a subscriber: other clients leave the index alone
    client_id, request_id = _endpoint_id(), 1
    sender = requests.open(f"{args.service}.request")
    if not sender.send(requests.pack((client_id, request_id, index), request)):
        raise CommandFailed(f"service '{args.service}': the request does not fit its topic")

    deadline = time.monotonic() + args.timeout
    while True:
        data = None
        if replies is None:
            # The response type is not known here: the server creates the topic with it when it
            # answers, and its answer is then the topic's newest message.
            created = next((t for t in _topics(args) if t["name"] == reply_name), None)
            if created is not None and created["type_name"]:
                responses = _frame_payload(args, created, service["response_type"], response=True)
                replies = responses.open(reply_name)
                data = replies.read_latest()
            else:
                time.sleep(0.01)
        else:
            data = replies.recv(min(0.01, max(0.0, deadline - time.monotonic())))
        if data is not None:
            (got_client, got_request, status, error), response = responses.unpack(data, 4)
            if (got_client, got_request) == (client_id, request_id):
                if status != 0:
                    kind = _CALL_FAILURE_KINDS.get(status, f"status {status}")
                    raise CommandFailed(f"service '{args.service}' failed ({kind}): {error}")
                _show_message(_plain(response), args.json)
                return EXIT_OK
            continue
        if not _alive(service["server_pid"]):
            raise CommandFailed(f"the server of service '{args.service}' (pid "
                                f"{service['server_pid']}) died before answering")
        if time.monotonic() >= deadline:
            unknown = "" if responses is not None else (
                f" (nothing here knows {service['response_type']}, the response type, so a "
                "failure could not be told: -I DIR, the folder of its .hsrv file, lets it be)")
            raise CommandFailed(f"no response from service '{args.service}' within "
                                f"{args.timeout:g} s (Timeout){unknown}")


def _announcements(args) -> list[tuple[dict, dict]]:
    """(presence entry: pid, started_wall_ns..., announcement) of the namespace's live processes:
    a scheduler's announcement (with "nodes") or a process's (with "process": its topics and
    services). Dead processes' announcements are never shown: `horus shm clean` removes them."""
    found = []
    for entry in _core().list_presence(args.namespace):
        if entry["alive"] and not entry["error"]:
            found.append((entry, json.loads(entry["snapshot_json"])))
    return found


def _processes(args) -> list[dict]:
    """The namespace's live processes, each with its schedulers' nodes, topics and services."""
    by_pid: dict[int, dict] = {}
    for entry, snapshot in _announcements(args):
        process = by_pid.setdefault(entry["pid"], {
            "pid": entry["pid"], "started_wall_ns": entry["started_wall_ns"], "program": "?",
            "nodes": [], "topics": [], "services": []})
        if "process" in snapshot:
            process["program"] = snapshot["process"]
            process["topics"] += snapshot["topics"]
            process["services"] += snapshot["services"]
        else:
            process["nodes"] += [node["name"] for node in snapshot["nodes"]]
    return sorted(by_pid.values(), key=lambda p: p["pid"])


def process_list(args) -> int:
    processes = _processes(args)

    def render(rows):
        _table(["PID", "STARTED", "PROGRAM", "NODES", "TOPICS", "SERVICES"],
               [[p["pid"], _started(p["started_wall_ns"]), p["program"],
                 ",".join(p["nodes"]) or "-",
                 ",".join(t["topic"] for t in p["topics"]) or "-",
                 ",".join(f"{s['service']}({s['role']})" for s in p["services"]) or "-"]
                for p in rows])
    _emit(processes, args.json, render)
    return EXIT_OK


def _live_nodes(args) -> list[dict]:
    """Every node of the namespace's live schedulers, with the process that runs it."""
    nodes = []
    for entry, snapshot in _announcements(args):
        for node in snapshot.get("nodes", []):
            node["pid"] = entry["pid"]
            node["started_wall_ns"] = entry["started_wall_ns"]
            node["scheduler"] = snapshot["scheduler"]
            node["scheduler_deadline_misses"] = snapshot.get("deadline_misses")
            node["max_deadline_misses"] = snapshot.get("max_deadline_misses")
            nodes.append(node)
    nodes.sort(key=lambda n: (n["name"], n["pid"]))
    return nodes


def _rate(value) -> str:
    return "-" if value is None else f"{value:.1f}"


def node_list(args) -> int:
    nodes = _live_nodes(args)

    render = _names_or_table(
        args, ["NODE", "PID", "SCHEDULER", "RATE_HZ", "ACHIEVED_HZ", "TICKS", "AVG_US", "MISSES",
               "STATE", "HEALTH"],
        lambda n: [n["name"], n["pid"], n["scheduler"], _rate(n["rate_hz"]),
                   _rate(n["achieved_rate_hz"]), n["total_ticks"], f"{n['avg_tick_ns'] / 1e3:.1f}",
                   n["deadline_misses"], n["state"], n["health"]])
    _emit(nodes, args.json, render)
    return EXIT_OK


def node_info(args) -> int:
    nodes = _live_nodes(args)
    matches = [n for n in nodes if n["name"] == args.node]
    if not matches:
        raise CommandFailed(f"no running node '{args.node}' in namespace '{_namespace(args)}'"
                            f"{_did_you_mean(args.node, [n['name'] for n in nodes])}")

    def render(rows):
        for n in rows:
            print(f"node: {n['name']}")
            print(f"process: pid {n['pid']} (started {_started(n['started_wall_ns'])}), "
                  f"scheduler {n['scheduler']}")
            print(f"state: {n['state']}, health: {n['health']}")
            print(f"class: {n['class']}, order: {n['order']}")
            print(f"rate: {_rate(n['rate_hz'])} Hz requested, {_rate(n['achieved_rate_hz'])} Hz achieved")
            print(f"ticks: {n['total_ticks']} ({n['failed_ticks']} failed)")
            print(f"tick time: avg {n['avg_tick_ns'] / 1e3:.1f} us, max {n['max_tick_ns'] / 1e3:.1f} us, "
                  f"last {n['last_tick_ns'] / 1e3:.1f} us")
            print(f"misses: {n['deadline_misses']} deadline, {n['budget_overruns']} budget")
            if n.get("deadline_ns") is not None:
                print(f"deadline: {n['deadline_ns'] / 1e3:.1f} us")
            if n.get("scheduler_deadline_misses") is not None:
                total, limit = n["scheduler_deadline_misses"], n["max_deadline_misses"]
                print(f"scheduler misses: {total} (no max_deadline_misses: never stops)"
                      if limit is None else
                      f"scheduler misses: {total} of max_deadline_misses {limit}, where it stops")
            for key in ("publishers", "subscribers"):
                topics = ", ".join(f"{t['topic']} ({t['type'] or '?'})" for t in n[key]) or "-"
                print(f"{key}: {topics}")
    _emit(matches, args.json, render)
    return EXIT_OK


def _log_filter(args):
    minimum = LEVELS.index(args.level) if args.level else 0
    since_ns = None
    if args.since is not None:
        since_ns = int((time.time() - args.since) * 1e9)

    def keep(record: dict) -> bool:
        return (LEVELS.index(record["level"].lower()) >= minimum
                and (args.node is None or record["source"] == args.node)
                and (since_ns is None or record["wall_time_ns"] >= since_ns))
    return keep


def log(args) -> int:
    core = _core()
    keep = _log_filter(args)
    snapshot = core.read_log(args.namespace)
    records = [r for r in snapshot["records"] if keep(r)]
    if not args.follow:
        _emit(records, args.json, lambda rows: [print(r["text"]) for r in rows])
        return EXIT_OK
    seen = snapshot["written"]

    def show(rows):
        for row in rows:
            print(json.dumps(row, sort_keys=True) if args.json else row["text"], flush=True)
    show(records)
    while True:
        time.sleep(0.1)
        snapshot = core.read_log(args.namespace)
        show([r for r in snapshot["records"] if r["sequence"] >= seen and keep(r)])
        seen = snapshot["written"]


def _program(pid: int) -> str:
    """A process's program name as the kernel tells it, or "?" (gone, or not ours to read)."""
    try:
        with open(f"/proc/{pid}/comm", encoding="utf-8", errors="replace") as comm:
            return comm.read().strip() or "?"
    except OSError:
        return "?"


def _flock_holders(path: str) -> list[int]:
    """The pids holding a flock on `path` (those waiting for one left out), from /proc/locks."""
    try:
        status = os.stat(path)
        with open("/proc/locks", encoding="ascii", errors="replace") as locks:
            lines = locks.read().splitlines()
    except OSError:
        return []
    holders = set()
    for line in lines:
        fields = line.split()  # "1: FLOCK ADVISORY READ <pid> <major>:<minor>:<inode> 0 EOF"
        if len(fields) < 6 or fields[1] != "FLOCK":
            continue  # a POSIX lock, or a waiter ("1: -> FLOCK ...")
        major, minor, inode = fields[5].split(":")
        if (int(major, 16), int(minor, 16), int(inode)) == \
                (os.major(status.st_dev), os.minor(status.st_dev), status.st_ino):
            holders.add(int(fields[4]))
    return sorted(holders)


def shm_list(args) -> int:
    core = _core()
    folder = core.namespace_directory(args.namespace)
    rows = []
    for topic in core.list_topics(args.namespace):
        path = os.path.join(folder, topic["name"])
        try:
            size = os.stat(path).st_size
        except OSError:
            size = None
        rows.append({"name": topic["name"], "path": path, "size": size,
                     "pids": topic["user_pids"], "in_use": bool(topic["user_pids"]),
                     "error": topic["error"]})
    # The log ring and the presence folder: their users hold a lock on them.
    rows += [{"name": o["kind"], "path": o["path"], "size": o["size"],
              "pids": _flock_holders(o["path"]), "in_use": o["in_use"], "error": ""}
             for o in core.list_namespace_objects(args.namespace)]
    for row in rows:
        row["users"] = [{"pid": pid, "program": _program(pid)} for pid in row.pop("pids")]

    def users_text(row) -> str:
        if row["users"]:
            return ",".join(f"{u['pid']}({u['program']})" for u in row["users"])
        # A lock held by a process this one cannot see (another pid namespace).
        return "(in use)" if row["in_use"] else "-"

    def render(items):
        _table(["SEGMENT", "BYTES", "USERS", "PATH"],
               [[r["name"], "-" if r["size"] is None else r["size"], users_text(r), r["path"]]
                for r in items])
    _emit(rows, args.json, render)
    return EXIT_OK


def shm_clean(args) -> int:
    core = _core()
    removed = core.clean_namespace(args.namespace)
    announcements = core.clean_presence(args.namespace)
    pools = core.clean_pools(args.namespace)
    if args.json:
        print(json.dumps({"removed": removed, "announcements": announcements, "pools": pools}))
    else:
        print(f"removed {removed} segment{'s' if removed != 1 else ''}, {announcements} "
              f"announcement{'s' if announcements != 1 else ''} and {pools} "
              f"tensor pool{'s' if pools != 1 else ''} left by dead processes")
    return EXIT_OK


def _described_types(args) -> list[dict]:
    """Every type of the schema folders (-I, else the installed schemas), as `horus-gen describe
    --json` lays it out: fingerprint, tier, size, alignment, fields with offsets. The installed
    schemas also resolve what the -I folders' types use (horus.msg.Pose2D)."""
    import pathlib

    import dynamic_types
    folders = args.include or ([SCHEMA_DIR] if SCHEMA_DIR else [])
    files = sorted(str(path) for folder in folders for pattern in ("*.hmsg", "*.hsrv")
                   for path in pathlib.Path(folder).rglob(pattern))
    if not files:
        raise CommandFailed(f"no schema files (.hmsg, .hsrv) in {', '.join(folders) or '(none)'}")
    resolving = folders + ([SCHEMA_DIR] if SCHEMA_DIR and SCHEMA_DIR not in folders else [])
    try:
        described = dynamic_types.run_generator(
            ["describe", "--json", *[arg for folder in resolving for arg in ("-I", folder)],
             *files], "horus-gen describe failed")
    except dynamic_types.SchemaError as error:
        raise CommandFailed(str(error)) from None
    return json.loads(described)["types"]


def _described_type(args) -> dict:
    types = _described_types(args)
    for described in types:
        if described["name"] == args.type or described["name"].rsplit(".", 1)[-1] == args.type:
            return described
    # Matched on the bare names: qualified ones all share their package's prefix.
    package, _, bare = args.type.rpartition(".")
    close = _close_names(bare, [t["name"].rsplit(".", 1)[-1] for t in types])
    if package:
        close = [t["name"] for t in types if t["name"].rsplit(".", 1)[-1] in close]
    where = "the given schemas" if args.include else "the installed schemas"
    hint = "" if args.include else " (your own types: -I DIR, the folder of their .hmsg files)"
    raise CommandFailed(f"no message type '{args.type}' in {where}{_suggestion(close)}{hint}")


def msg_list(args) -> int:
    types = _described_types(args)
    _emit(types, args.json, lambda rows: [print(t["name"]) for t in rows])
    return EXIT_OK


def _layout_rows(described: dict) -> list[list]:
    """The field table of `msg show`: each field, and for a POD type each hole of padding
    between two fields and after the last (what the fields leave of `size`)."""
    rows, end = [], 0
    for field in described["fields"]:
        offset, size = field.get("offset"), field.get("size")
        if offset is not None and offset > end:
            rows.append(["(padding)", "-", end, offset - end])
        rows.append([field["name"], field["type"], "-" if offset is None else offset,
                     "-" if size is None else size])
        if offset is not None and size is not None:
            end = offset + size
    if described.get("size") and all(f.get("offset") is not None for f in described["fields"]) \
            and described["size"] > end:
        rows.append(["(padding)", "-", end, described["size"] - end])
    return rows


def msg_show(args) -> int:
    described = _described_type(args)

    def render(t):
        print(f"type: {t['name']} ({t['kind']})")
        print(f"fingerprint: {t['fingerprint']}")
        if "tier" in t:
            size, alignment = t.get("size"), t.get("alignment")
            print(f"tier: {t['tier']}, size {'-' if size is None else size}, alignment "
                  f"{'-' if alignment is None else alignment}")
        if t.get("fields"):
            _table(["FIELD", "TYPE", "OFFSET", "SIZE"], _layout_rows(t))
        if t["kind"] == "enum":
            print(f"underlying: {t['underlying']}")
            for name, value in t["values"].items():
                print(f"  {name} = {value}")
        if t["kind"] == "service":
            print(f"request: {t['request']} (topic {t['request_topic']})")
            print(f"response: {t['response']} (topic {t['response_topic']})")
        if t.get("schema"):
            # What a topic's segment stores: the definition, then every type it uses.
            print("schema:")
            for line in t["schema"].splitlines():
                print(f"  {line}")
    _emit(described, args.json, render)
    return EXIT_OK


def msg_hash(args) -> int:
    print(_described_type(args)["fingerprint"])
    return EXIT_OK


class _TopicRates:
    """Each topic's rate and bandwidth: from its send stamps, or counted between two refreshes,
    whichever spans more messages; the bandwidth is the rate times the mean size in the ring."""

    def __init__(self) -> None:
        self.previous: dict[str, tuple[int, float]] = {}

    def sample(self, core, args) -> list[dict]:
        topics = core.list_topics(args.namespace)
        topics = [topic for topic in topics if not _internal(topic)]
        now, counts = time.time(), {}
        for topic in topics:
            name = topic["name"]
            topic["rate_hz"] = topic["bytes_per_s"] = None
            traffic = _traffic(core, args, name)
            if traffic is None:
                continue
            count, stamp = counts[name] = traffic["message_count"], time.monotonic()
            previous, counted = self.previous.get(name), None
            # Not for a topic new since the last refresh, or created again (its count restarted).
            if previous is not None and count >= previous[0]:
                counted = (count - previous[0]) / (stamp - previous[1]), count - previous[0]
            rate = _best_rate(_stamped_rate(traffic, now), counted)
            topic["rate_hz"] = rate
            if rate is not None and traffic["counted"]:
                topic["bytes_per_s"] = rate * traffic["bytes"] / traffic["counted"]
        self.previous = counts
        return topics


def _monitor_lines(args, rates: _TopicRates) -> list[str]:
    core = _core()
    lines = [f"horus monitor  namespace {_namespace(args)}  "
             f"{time.strftime('%H:%M:%S')}   q: quit", ""]
    node_rows = [[n["name"], n["pid"], _rate(n["rate_hz"]), _rate(n["achieved_rate_hz"]),
                  f"{n['avg_tick_ns'] / 1e3:.1f}", f"{n['max_tick_ns'] / 1e3:.1f}",
                  n["deadline_misses"] + n["budget_overruns"], n["health"], n["state"]]
                 for n in _live_nodes(args)]
    topic_rows = [[t["name"], t["type_name"] or "-", t["publishers"], t["subscribers"],
                   _rate(t["rate_hz"]),
                   "-" if t["bytes_per_s"] is None else _bytes(t["bytes_per_s"]) + "/s"]
                  for t in rates.sample(core, args)]
    for title, header, rows in (
            ("NODES", ["NODE", "PID", "RATE_HZ", "ACHIEVED_HZ", "AVG_US", "MAX_US", "MISSES",
                       "HEALTH", "STATE"], node_rows),
            ("TOPICS", ["TOPIC", "TYPE", "PUBS", "SUBS", "RATE_HZ", "BANDWIDTH"], topic_rows)):
        lines.append(f"{title} ({len(rows)})")
        widths = [max(len(str(row[i])) for row in [header, *rows]) for i in range(len(header))]
        for row in [header, *rows]:
            lines.append("  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip())
        lines.append("")
    return lines


def monitor(args) -> int:
    if not (sys.stdin.isatty() and sys.stdout.isatty()):
        raise CommandFailed("horus monitor needs a terminal; use `node list -v` and "
                            "`topic list -v` in scripts", EXIT_USAGE)
    import curses

    def run(screen) -> None:
        curses.curs_set(0)
        screen.timeout(int(args.interval * 1000))
        rates = _TopicRates()
        while True:
            lines = _monitor_lines(args, rates)
            screen.erase()
            height, width = screen.getmaxyx()
            for row, line in enumerate(lines[:height - 1]):
                screen.addnstr(row, 0, line, width - 1)
            screen.refresh()
            if screen.getch() in (ord("q"), ord("Q")):
                return
    curses.wrapper(run)
    return EXIT_OK


def blackbox(args) -> int:
    try:
        os.execvp(BLACKBOX_PROGRAM, [BLACKBOX_PROGRAM, *args.blackbox_args])
    except OSError as error:
        raise CommandFailed(f"cannot run {BLACKBOX_PROGRAM}: {error.strerror}") from None


COMPLETION = """# bash completion for horus: `source <(horus completion)`
_horus() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[1]} words
  if [ "$COMP_CWORD" -eq 1 ]; then
    words="%(commands)s"
  elif [ "$COMP_CWORD" -eq 2 ]; then
    case "$prev" in
%(cases)s
    esac
  elif [ "$COMP_CWORD" -eq 3 ] && [ "$prev" = topic ]; then
    words=$(horus topic list 2>/dev/null)
  elif [ "$COMP_CWORD" -eq 3 ] && [ "$prev" = node ]; then
    words=$(horus node list 2>/dev/null)
  elif [ "$COMP_CWORD" -eq 3 ] && [ "$prev" = service ]; then
    words=$(horus service list 2>/dev/null)
  fi
  COMPREPLY=($(compgen -W "$words" -- "$cur"))
}
complete -F _horus horus
"""


def bridge(args) -> int:
    try:
        from horus import _dds
    except ImportError:
        raise CommandFailed("this horus was built without Cyclone DDS (Debian: cyclonedds-dev), "
                            "so it has no bridge") from None
    import horus_bridge
    if not (args.export or args.imports or args.export_service or args.import_service):
        raise CommandFailed("nothing to bridge: give --export and/or --import patterns", EXIT_USAGE)
    deadlines = []
    for given in args.deadline:
        pattern, _, milliseconds = given.rpartition("=")
        if not pattern or not milliseconds.isdigit() or int(milliseconds) < 1:
            raise CommandFailed(f"--deadline wants PATTERN=MS (a whole number of milliseconds, "
                                f"at least 1), got {given!r}", EXIT_USAGE)
        deadlines.append((pattern, int(milliseconds)))
    try:
        bridge = horus_bridge.Bridge(_core(), _dds, args.namespace, args.export, args.imports,
                                     args.domain, not args.best_effort, args.depth,
                                     args.export_service, args.import_service,
                                     args.transient_local, deadlines, args.service_timeout,
                                     args.ros2_types, args.accept_untyped_writers)
    except (RuntimeError, horus_bridge.BridgeError) as error:
        raise CommandFailed(str(error)) from None
    return bridge.run()


def remote_keygen(args) -> int:
    from horus_remote_keys import keygen
    try:
        refused = keygen(args.folder, args.names)
    except (OSError, ValueError) as error:
        raise CommandFailed(str(error)) from None
    if refused:
        raise CommandFailed("; ".join(refused))
    return EXIT_OK


def remote_status(args) -> int:
    """The streams of the namespace's horus-remote processes, from the status file each writes
    every second (tools/remote: status_path)."""
    namespace = args.namespace or _core().current_namespace()
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    folder = os.path.join(runtime, "horus-remote") if runtime else f"/tmp/horus-remote-{os.getuid()}"
    rows = []
    for name in sorted(os.listdir(folder)) if os.path.isdir(folder) else []:
        prefix, _, pid = name.removesuffix(".json").rpartition(".")
        if prefix != namespace or not name.endswith(".json") or not pid.isdigit():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:  # a process killed before it could remove its file
            os.remove(os.path.join(folder, name))
            continue
        except PermissionError:
            pass
        try:
            with open(os.path.join(folder, name)) as file:
                status = json.load(file)
        except (OSError, ValueError):
            continue
        rows += [{"pid": status["pid"], "role": status["role"], **stream}
                 for stream in status["streams"]]

    def render(rows):
        if not rows:
            print(f"no horus remote streams in namespace '{namespace}'")
            return
        _table(["PID", "ROLE", "STREAM", "SENT", "DROPPED"],
               [[r["pid"], r["role"], r["stream"], r["sent"], r["dropped"]] for r in rows])
    _emit(rows, args.json, render)
    return EXIT_OK


def remote_link(args) -> int:
    # The namespace reaches horus-remote through HORUS_NAMESPACE, which main() set.
    try:
        os.execvp(REMOTE_PROGRAM, [REMOTE_PROGRAM, args.action, *args.remote_args])
    except OSError as error:
        raise CommandFailed(f"cannot run {REMOTE_PROGRAM}: {error.strerror}") from None


def completion(args) -> int:
    parser = args.root_parser
    commands = parser._subparsers._group_actions[0].choices  # noqa: SLF001 (argparse has no API)
    cases = []
    for name, sub in commands.items():
        if sub._subparsers is not None:  # noqa: SLF001
            words = " ".join(sub._subparsers._group_actions[0].choices)  # noqa: SLF001
            cases.append(f'      {name}) words="{words}" ;;')
    # `record` parses its own arguments (an action, or the topics to record): no subparsers.
    from horus_record_cli import ACTIONS
    cases.append(f'      record) words="{" ".join(ACTIONS)} $(horus topic list 2>/dev/null)" ;;')
    print(COMPLETION % {"commands": " ".join(commands), "cases": "\n".join(cases)}, end="")
    return EXIT_OK


class _Parser(argparse.ArgumentParser):
    """argparse with the usage error on one line and exit status 2."""

    def error(self, message: str):
        self.exit(EXIT_USAGE, f"{self.prog}: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    common = _Parser(add_help=False)
    common.add_argument("--namespace", "-n", default=argparse.SUPPRESS,
                        help="the namespace to look at (default: $HORUS_NAMESPACE, else 'default')")
    listing = _Parser(add_help=False)
    listing.add_argument("--json", action="store_true", help="print JSON instead of text")

    parser = _Parser(prog="horus", parents=[common],
                     description="See, poke and clean a running HORUS system.")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    def group(name: str, help_text: str):
        sub = commands.add_parser(name, help=help_text, description=help_text, parents=[common])
        return sub.add_subparsers(dest="action", metavar="ACTION", parser_class=_Parser)

    def action(parent, name: str, help_text: str, handler, json_output: bool = True):
        sub = parent.add_parser(name, help=help_text, description=help_text,
                                parents=[common, listing] if json_output else [common])
        sub.set_defaults(handler=handler)
        return sub

    topic = group("topic", "topics: list, inspect, measure, echo, publish")
    sub = action(topic, "list", "the namespace's topics", topic_list)
    sub.add_argument("-v", "--verbose", action="store_true",
                     help="with type, publishers, subscribers and rate")
    sub.add_argument("--window", type=positive_float, default=0.2,
                     help="seconds over which -v counts the messages of topics too fast for "
                          "their send stamps, which are whole seconds (default 0.2)")
    sub.add_argument("--include-hidden", action="store_true",
                     help="also the topics services run on (NAME.service, NAME.request, "
                          "NAME.response.N)")
    sub = action(topic, "info", "one topic: type, schema, capacity, users, counters", topic_info)
    sub.add_argument("topic")

    process = group("process", "the processes using the namespace")
    sub = action(process, "list", "live processes with their nodes, open topics and services",
                 process_list)

    node = group("node", "nodes of the running schedulers: list, inspect")
    sub = action(node, "list", "the nodes of the namespace's live schedulers", node_list)
    sub.add_argument("-v", "--verbose", action="store_true",
                     help="with process, rates, ticks, tick time, misses, state and health")
    sub = action(node, "info", "one node: topics, rate, timing, misses, health, state", node_info)
    sub.add_argument("node")

    for name, handler, what in (("hz", topic_hz, "message rate"),
                                ("bw", topic_bw, "bandwidth (payload bytes per second)")):
        sub = action(topic, name, f"a topic's {what}, from slot headers (nothing decoded), "
                                  "each window until Ctrl+C", handler)
        sub.add_argument("topic")
        sub.add_argument("--window", type=positive_float, default=1.0,
                         help="seconds per measurement (default 1)")
        sub.add_argument("--once", action="store_true", help="print one window and exit")

    sub = action(topic, "echo", "print a topic's messages, decoded from its stored schema "
                                "(any type), the newest one sent first", topic_echo)
    sub.add_argument("topic")
    sub.add_argument("--once", action="store_true", help="print one message and exit")
    sub.add_argument("--count", type=positive_int, metavar="N", help="print N messages and exit")
    sub.add_argument("--field", metavar="A.B", help="print only this field (dotted path; list "
                                                   "elements by index)")
    sub.add_argument("--timeout", type=positive_float, metavar="SECONDS",
                     help="exit 1 when no message came within SECONDS")
    sub = action(topic, "pub", "publish a message given as YAML or JSON (any type, from the "
                               "topic's stored schema), every 1/RATE s until Ctrl+C", topic_pub,
                 json_output=False)
    sub.add_argument("topic")
    sub.add_argument("value", help="the fields, e.g. '{linear: 0.5}'; fields left out are zero")
    sub.add_argument("--rate", type=positive_float, metavar="HZ", help="messages per second (default 1)")
    sub.add_argument("--once", action="store_true", help="publish one message and exit")
    sub.add_argument("--count", type=positive_int, metavar="N", help="publish N messages and exit")
    sub.add_argument("--type", metavar="TYPE", help="the message type (qualified or bare name) "
                                                    "when nobody has opened the topic yet")
    sub.add_argument("-I", dest="include", action="append", metavar="DIR",
                     help="with --type: schema folder to find it in (default: the installed "
                          "schemas)")

    service = group("service", "services: list, inspect, call")
    sub = action(service, "list", "the namespace's services", service_list)
    sub.add_argument("-v", "--verbose", action="store_true", help="with types, server and clients")
    sub = action(service, "info", "one service: types, server, clients", service_info)
    sub.add_argument("service")

    sub = action(service, "call", "call a service with a request given as YAML or JSON (any "
                                  "type, from the service's stored schemas)", service_call)
    sub.add_argument("service")
    sub.add_argument("value", help="the request's fields, e.g. '{a: 1, b: 2}'; fields left out are zero")
    sub.add_argument("--timeout", type=positive_float, default=5.0, metavar="SECONDS",
                     help="how long to wait for the response (default 5)")
    sub.add_argument("-I", dest="include", action="append", metavar="DIR",
                     help="schema folder declaring the response type, when no reply topic of "
                          "the service tells it yet (default: the installed schemas)")

    message = group("msg", "message types of the installed (or given) schemas: list, show, hash")
    for name, handler, what in (
            ("list", msg_list, "every message type of the schemas"),
            ("show", msg_show, "a type's fingerprint, tier, size, field layout and schema text"),
            ("hash", msg_hash, "a type's fingerprint")):
        sub = action(message, name, what, handler, json_output=name != "hash")
        if name != "list":
            sub.add_argument("type", help="qualified (horus.msg.CmdVel) or bare (CmdVel) name")
        sub.add_argument("-I", dest="include", action="append", metavar="DIR",
                         help="schema folder to read, like horus-gen's -I: the folder of your "
                              "own .hmsg and .hsrv files (repeatable; default: the installed "
                              "schemas)")

    sub = commands.add_parser("log", help="the namespace's log ring",
                              description="Lines nodes logged, oldest first.",
                              parents=[common, listing])
    sub.set_defaults(handler=log)
    sub.add_argument("--node", help="only lines of this node (its name, '-' or '@<scheduler>')")
    sub.add_argument("--level", choices=LEVELS, help="only lines at this level or above")
    sub.add_argument("--since", type=positive_float, metavar="SECONDS",
                     help="only lines of the last SECONDS seconds")
    sub.add_argument("--follow", "-f", action="store_true",
                     help="keep printing new lines until Ctrl+C")

    shm = group("shm", "shared-memory segments: list, clean")
    action(shm, "list", "the namespace's segments, log ring and presence folder, and who uses them",
           shm_list)
    action(shm, "clean", "remove the segments, log ring, presence folder and tensor pools whose "
           "every user died (never a live one's)", shm_clean)

    sub = commands.add_parser("monitor", help="live view of nodes and topics (q quits)",
                              description="A live terminal view of the namespace's nodes (rate, "
                                          "tick time, misses, health) and topics (rate, "
                                          "bandwidth), until q or Ctrl+C.", parents=[common])
    sub.add_argument("--interval", type=refresh_interval, default=1.0,
                     help="seconds between refreshes (default 1, at least 0.1)")
    sub.set_defaults(handler=monitor)

    sub = commands.add_parser("blackbox", help="print a scheduler flight-recorder file",
                              description="Runs horus-blackbox with the given arguments.",
                              add_help=False)
    sub.add_argument("blackbox_args", nargs=argparse.REMAINDER)
    sub.set_defaults(handler=blackbox)

    commands.add_parser("record", add_help=False, help="record, inspect, repair, replay, compare "
                        "and export sessions (MCAP): horus record --help")  # horus_record_cli.py

    sub = commands.add_parser("bridge", help="carry topics to and from Cyclone DDS (other hosts, "
                              "ROS 2)", parents=[common],
                              description="Export local topics matching --export to DDS (as "
                                          "rt/<name>, each '.' a '/', in CDR) and import DDS "
                                          "topics matching --import into the namespace, until "
                                          "Ctrl+C. Nothing crosses that no pattern names "
                                          "(docs/dds-bridge.md).")
    sub.add_argument("--export", action="append", default=[], metavar="PATTERN",
                     help="local topics to write to DDS (a glob; repeatable)")
    sub.add_argument("--import", dest="imports", action="append", default=[], metavar="PATTERN",
                     help="DDS topics to publish locally, by their local name (rt/arm/state "
                          "is arm.state; a glob; repeatable)")
    sub.add_argument("--export-service", action="append", default=[], metavar="PATTERN",
                     help="local services to serve on DDS (rq/<name>Request, rr/<name>Reply)")
    sub.add_argument("--import-service", action="append", default=[], metavar="PATTERN",
                     help="services on DDS to serve locally (calls forwarded to their server)")
    sub.add_argument("--domain", type=int, default=0, help="the DDS domain id (default 0)")
    sub.add_argument("--best-effort", action="store_true",
                     help="best-effort DDS endpoints (default: reliable)")
    sub.add_argument("--depth", type=positive_int, default=100,
                     help="DDS history depth of each writer and reader (default 100)")
    sub.add_argument("--transient-local", action="append", default=[], metavar="PATTERN",
                     help="latched topics: a DDS reader that joins later gets the last message "
                          "(default: volatile; an importing bridge follows the writer)")
    sub.add_argument("--deadline", action="append", default=[], metavar="PATTERN=MS",
                     help="topics that must carry a message every MS milliseconds; each missed "
                          "deadline is said on stderr (default: none; an importing bridge "
                          "follows the writer)")
    sub.add_argument("--service-timeout", type=positive_float, default=10.0, metavar="SECONDS",
                     help="how long an exported service's local server has to answer a call "
                          "from DDS (default 10); the caller then gets Timeout")
    sub.add_argument("--ros2-types", action="append", default=[], metavar="PATTERN",
                     help="topics that cross as their standard type's ROS 2 twin (CmdVel as "
                          "geometry_msgs/msg/Twist, Imu, LaserScan, Odometry, ...), both ways")
    sub.add_argument("--accept-untyped-writers", action="store_true",
                     help="import from DDS writers that announce no XTypes type information "
                          "(ROS 2 nodes), whose type DDS cannot check (default: refused)")
    sub.set_defaults(handler=bridge)

    remote = group("remote", "reach a robot from afar over Cap'n Proto RPC with mutual TLS "
                             "(docs/remote.md)")
    sub = action(remote, "keygen", "make a CA in DIR (once) and a key and certificate signed by "
                 "it per NAME (the certificate's name)", remote_keygen, json_output=False)
    sub.add_argument("folder", metavar="DIR")
    sub.add_argument("names", metavar="NAME", nargs="+")
    action(remote, "status", "the streams of this namespace's horus remote processes: messages "
           "sent and dropped (latest wins on a slow link)", remote_status)
    for name, help_text in (("serve", "serve this namespace to authenticated peers (runs "
                                      "horus-remote serve; --help lists its options)"),
                            ("connect", "mirror a robot's topics here and send ours to it (runs "
                                        "horus-remote connect; --help lists its options)")):
        # '+' as the prefix: every argument, options too, goes to horus-remote as it is.
        sub = remote.add_parser(name, help=help_text, description=help_text, prefix_chars="+",
                                add_help=False)
        sub.add_argument("remote_args", nargs=argparse.REMAINDER)
        sub.set_defaults(handler=remote_link)

    sub = commands.add_parser("completion", help="print the bash completion script",
                              description="Print the bash completion script: "
                                          "source <(horus completion)")
    sub.set_defaults(handler=completion)
    return parser


def main(argv: list[str] | None = None) -> int:
    from horus_record_cli import parse_record  # `record` parses its own arguments
    parser = build_parser()
    words = sys.argv[1:] if argv is None else argv
    args = parse_record(words)
    if args is None:
        args, unknown = parser.parse_known_args(words)
        if getattr(args, "handler", None) is blackbox:
            # Everything after `blackbox` is horus-blackbox's, its options (--help) first too,
            # which argparse's REMAINDER would not take.
            args.blackbox_args = words[words.index("blackbox") + 1:]
        elif unknown:
            parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    if getattr(args, "handler", None) is None:
        parser.parse_args([*words, "--help"])
    args.root_parser = parser
    args.namespace = getattr(args, "namespace", None) or ""
    if args.namespace:
        # Handles the command opens (echo, pub, call) read the namespace from the environment.
        os.environ["HORUS_NAMESPACE"] = args.namespace
    try:
        return args.handler(args)
    except CommandFailed as failure:
        print(f"horus: {failure}", file=sys.stderr)
        return failure.status
    except KeyboardInterrupt:
        return EXIT_OK
    except BrokenPipeError:
        return EXIT_OK
    except Exception as error:  # noqa: BLE001 (any failure is one line, never a traceback)
        if type(error).__name__ == "HorusError":  # the runtime's refusal: a problem of the input
            print(f"horus: {error}", file=sys.stderr)
            return EXIT_NOT_FOUND
        if os.environ.get("HORUS_DEBUG") == "1":
            raise
        reason = " ".join(str(error).split())
        print(f"horus: internal error: {type(error).__name__}: {reason} (HORUS_DEBUG=1 shows "
              "the traceback)", file=sys.stderr)
        return EXIT_NOT_FOUND


if __name__ == "__main__":
    sys.exit(main())
