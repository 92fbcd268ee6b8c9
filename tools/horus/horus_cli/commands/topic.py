"""`horus topic`: list, info, hz, bw, echo and pub a namespace's topics."""
from __future__ import annotations

import json
import sys
import time

from horus_cli.common import (EXIT_OK, CommandFailed, emit, format_bytes, introspection,
                              names_or_table, positive_float, positive_int, utc)
from horus_cli.live import (ENOUGH_MESSAGES, best_rate, find_topic, is_internal, list_processes,
                            list_topics, missing_topic, read_traffic, stamped_rate)
from horus_cli.schemas import (PLAIN_VALUES, build_message, described_type, message_class,
                               parse_value, plain, plain_field, show_message)


def _measure_rates(args, topics: list[dict]) -> None:
    """Sets each topic's rate_hz from its send stamps; those whose stamps span too few messages
    while they still send are also counted over --window, one wait for all of them."""
    core = introspection()
    now = time.time()
    stamped, counting = {}, {}
    for topic in topics:
        traffic = read_traffic(core, args, topic["name"])
        if traffic is None:
            continue
        stamped[topic["name"]] = estimate = stamped_rate(traffic, now)
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
            traffic = read_traffic(core, args, name)
            before, since = counting[name]
            if traffic is not None and traffic["message_count"] >= before:
                messages = traffic["message_count"] - before
                counted = messages / (time.monotonic() - since), messages
        rate = best_rate(stamped.get(name), counted)
        topic["rate_hz"] = None if name not in stamped else round(rate or 0.0, 1)


def topic_list(args) -> int:
    topics = list_topics(args)
    if not args.include_hidden:
        topics = [topic for topic in topics if not is_internal(topic)]
    if args.verbose:
        _measure_rates(args, topics)

    render = names_or_table(
        args, ["TOPIC", "TYPE", "PUBS", "SUBS", "RATE_HZ", "MESSAGES"],
        lambda r: [r["name"], r["type_name"] or "-", r["publishers"], r["subscribers"],
                   "-" if r.get("rate_hz") is None else f"{r['rate_hz']:.1f}", r["message_count"]])
    emit(topics, args.json, render)
    return EXIT_OK


def topic_info(args) -> int:
    topic = find_topic(args, args.topic)
    topic["processes"] = [{"pid": p["pid"], "program": p["program"]} for p in list_processes(args)
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
            print(f"last send: {utc(t['last_send_s'])}")
        if t["schema"]:
            print("schema:")
            for line in t["schema"].splitlines():
                print(f"  {line}")
    emit(topic, args.json, render)
    return EXIT_OK


def _measure_traffic(args, on_window) -> None:
    """Samples a topic's slot headers every 20 ms (fast enough not to be lapped by the ring at a
    few kHz) and hands each window's figures to `on_window`, forever or once with --once. A
    topic removed meanwhile (its last user ended) counts nothing until it is created again."""
    core = introspection()
    find_topic(args, args.topic)
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
                if any(t["name"] == args.topic for t in list_topics(args)):
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


def topic_bw(args) -> int:
    def show(w):
        if args.json:
            print(json.dumps(w, sort_keys=True), flush=True)
        else:
            mean = "-" if w["mean_message_bytes"] is None else format_bytes(w["mean_message_bytes"])
            print(f"bandwidth: {format_bytes(w['bytes_per_s'])}/s, mean message {mean} "
                  f"({w['messages']} messages in {w['window_s']:.2f} s)", flush=True)
    _measure_traffic(args, show)
    return EXIT_OK


def _typed_topic(args, name: str) -> dict:
    topic = find_topic(args, name)
    if topic["error"]:
        raise CommandFailed(f"topic '{name}' cannot be read: {topic['error']}")
    if not topic["type_name"]:
        raise CommandFailed(f"topic '{name}' has no type yet: no handle has opened it with one")
    return topic


def _open_topic(topic: dict, cls):
    """A handle on a live topic with the identity its segment records (a topic `pub --type`
    creates gets the type description of its class)."""
    info = cls.__horus__
    description = topic.get("description") or (info.description if info.name == topic["type_name"]
                                               else b"")
    return introspection().open_topic(
        topic["name"], topic["type_name"], topic["fingerprint"], topic["schema"], topic["is_pod"],
        info.size if topic["is_pod"] else 0, info.alignment if topic["is_pod"] else 1,
        topic["capacity"], topic["max_message_size"], topic["single_publisher"], description)


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
                topics = list_topics(args)
                if not any(t["name"] == args.topic for t in topics):
                    raise missing_topic(args, args.topic, topics,
                                        within=f" within {args.timeout:g} s") from None
                raise failure from None
        time.sleep(0.05)


def topic_echo(args) -> int:
    deadline = None if args.timeout is None else time.monotonic() + args.timeout
    topic = _awaited_topic(args, deadline)
    cls = message_class(topic["type_name"], topic["schema"], topic["fingerprint"],
                        topic["description"])
    handle = _open_topic(topic, cls)
    # The newest message already sent comes first (a topic is latched), then each new one. Once
    # a message came after the handle opened, the newest one may be that or a later one, which
    # the handle receives in order anyway: then it is left out, never shown twice.
    data = handle.read_latest()
    if handle.has_msg():
        data = None
    if cls.__horus__.name != PLAIN_VALUES:  # a plain value has no fields to check beforehand
        plain_field(plain(cls()), args.field, topic["type_name"], checking=True)

    def show(data) -> None:
        try:
            message = cls.from_bytes(data)
        except ValueError as error:
            raise CommandFailed(f"topic '{args.topic}': a message does not decode: {error}") from None
        show_message(plain_field(plain(message), args.field, topic["type_name"]), args.json)

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
    described = described_type(args)
    if described["kind"] != "message":
        raise CommandFailed(f"'{described['name']}' is a {described['kind']}, not a message type")
    pod = described["tier"] == "pod"
    return {"name": args.topic, "type_name": described["name"], "schema": described["schema"],
            "fingerprint": int(described["fingerprint"], 16), "is_pod": pod, "capacity": 64,
            "max_message_size": 16 * 1024, "single_publisher": False, "error": ""}


def topic_pub(args) -> int:
    topics = list_topics(args)
    if args.type is None:
        if not any(t["name"] == args.topic for t in topics):
            raise missing_topic(args, args.topic, topics, hint=" (give --type TYPE to create it)")
        topic = _typed_topic(args, args.topic)
    else:
        topic = next((t for t in topics if t["name"] == args.topic and t["type_name"]), None)
        if topic is None:
            topic = _new_topic(args)
        elif args.type not in (topic["type_name"], topic["type_name"].rsplit(".", 1)[-1]):
            try:
                given = described_type(args)["name"]
            except CommandFailed:  # not in the schemas either: named as given
                given = args.type
            raise CommandFailed(f"topic '{args.topic}' carries {topic['type_name']}, not "
                                f"{given} (--type)")
    cls = message_class(topic["type_name"], topic["schema"], topic["fingerprint"],
                        topic.get("description", b""))
    message = build_message(cls, parse_value(args.value, f"value for {topic['type_name']}"))
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


def register(commands) -> None:
    topic = commands.group("topic", "topics: list, inspect, measure, echo, publish")
    sub = commands.action(topic, "list", "the namespace's topics", topic_list)
    sub.add_argument("-v", "--verbose", action="store_true",
                     help="with type, publishers, subscribers and rate")
    sub.add_argument("--window", type=positive_float, default=0.2,
                     help="seconds over which -v counts the messages of topics too fast for "
                          "their send stamps, which are whole seconds (default 0.2)")
    sub.add_argument("--include-hidden", action="store_true",
                     help="also the topics services run on (NAME.service, NAME.request, "
                          "NAME.response.N)")
    sub = commands.action(topic, "info", "one topic: type, schema, capacity, users, counters",
                          topic_info)
    sub.add_argument("topic")

    for name, handler, what in (("hz", topic_hz, "message rate"),
                                ("bw", topic_bw, "bandwidth (payload bytes per second)")):
        sub = commands.action(topic, name, f"a topic's {what}, from slot headers (nothing "
                                           "decoded), each window until Ctrl+C", handler)
        sub.add_argument("topic")
        sub.add_argument("--window", type=positive_float, default=1.0,
                         help="seconds per measurement (default 1)")
        sub.add_argument("--once", action="store_true", help="print one window and exit")

    sub = commands.action(topic, "echo", "print a topic's messages, decoded from its stored schema "
                                         "(any type), the newest one sent first", topic_echo)
    sub.add_argument("topic")
    sub.add_argument("--once", action="store_true", help="print one message and exit")
    sub.add_argument("--count", type=positive_int, metavar="N", help="print N messages and exit")
    sub.add_argument("--field", metavar="A.B", help="print only this field (dotted path; list "
                                                   "elements by index)")
    sub.add_argument("--timeout", type=positive_float, metavar="SECONDS",
                     help="exit 1 when no message came within SECONDS")
    sub = commands.action(topic, "pub", "publish a message given as YAML or JSON (any type, from "
                                        "the topic's stored schema), every 1/RATE s until Ctrl+C",
                          topic_pub, json_output=False)
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
