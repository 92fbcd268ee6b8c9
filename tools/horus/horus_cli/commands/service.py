"""`horus service`: list, info and call a namespace's services."""
from __future__ import annotations

import time

from horus_cli.common import (EXIT_OK, CommandFailed, did_you_mean, emit, introspection,
                              names_or_table, namespace_name, positive_float)
from horus_cli.live import list_processes, list_topics
from horus_cli.schemas import (build_message, described_types, message_class, parse_value, plain,
                               show_message, used_class)


def service_list(args) -> int:
    services = introspection().list_services(args.namespace)
    if not args.include_hidden:
        # The services that carry writes to nodes' parameters are `horus param`'s to show.
        services = [s for s in services if not introspection().is_param_service(s["name"])]

    render = names_or_table(
        args, ["SERVICE", "REQUEST", "RESPONSE", "SERVERS", "SERVER_PID", "CLIENTS"],
        lambda r: [r["name"], r["request_type"], r["response_type"], r["servers"],
                   r["server_pid"] or "-", r["clients"]])
    emit(services, args.json, render)
    return EXIT_OK


def service_info(args) -> int:
    service = _find_service(args)
    service["client_processes"] = [
        {"pid": p["pid"], "program": p["program"]} for p in list_processes(args)
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
    emit(service, args.json, render)
    return EXIT_OK


def _find_service(args) -> dict:
    services = introspection().list_services(args.namespace)
    for service in services:
        if service["name"] == args.service:
            return service
    raise CommandFailed(f"no service '{args.service}' in namespace '{namespace_name(args)}'"
                        f"{did_you_mean(args.service, [s['name'] for s in services])}")


def _frame_payload(args, topic: dict, payload_type: str, response: bool):
    """The frames of a service frame topic around their payload class, both made from the topic's
    stored schema (the frame's declaration, then the payload's), checked against the frame's
    fingerprint."""
    frame_class = message_class(topic["type_name"], topic["schema"], topic["fingerprint"])
    frame = introspection().ServiceFrame(used_class(frame_class, payload_type), response=response)
    if frame.fingerprint != topic["fingerprint"] or frame.name != topic["type_name"]:
        raise CommandFailed(f"topic '{topic['name']}' carries {topic['type_name']}, not the "
                            f"frame of {payload_type} this command builds")
    return frame


def _reply_topics(args, service: dict) -> tuple[dict | None, int]:
    """(a typed reply topic of the service, to learn the response type from; the smallest
    reply index no live client receives on)."""
    prefix = f"{service['name']}.response."
    typed, taken = None, set()
    for topic in list_topics(args):
        suffix = topic["name"][len(prefix):]
        if not topic["name"].startswith(prefix) or not suffix.isdigit():
            continue
        if topic["subscribers"]:
            taken.add(int(suffix))
        if topic["type_name"] and not topic["error"] and typed is None:
            typed = topic
    return typed, next(index for index in range(len(taken) + 1) if index not in taken)


def _response_frames(args, service: dict, typed: dict | None):
    """The frame of the service's responses: from a typed reply topic, else from the schema
    folders (-I, else the installed schemas) when they declare the response type; None when
    neither tells it."""
    if typed is not None:
        return _frame_payload(args, typed, service["response_type"], response=True)
    try:
        types = described_types(args)
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
    try:
        cls = message_class(described["name"], described["schema"],
                            int(described["fingerprint"], 16))
    except CommandFailed:  # a schema that does not compile alone: left to the server, as before
        return None
    return introspection().ServiceFrame(cls, response=True)


def service_call(args) -> int:
    service = _find_service(args)
    if not service["servers"]:
        raise CommandFailed(f"service '{args.service}' has no live server")
    topics = {t["name"]: t for t in list_topics(args)}
    request_topic = topics.get(f"{args.service}.request")
    if request_topic is None or not request_topic["type_name"]:
        raise CommandFailed(f"service '{args.service}' has no request topic to learn its type from")
    requests = _frame_payload(args, request_topic, service["request_type"], response=False)
    request = build_message(requests.payload_type, parse_value(
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
    client_id, request_id = introspection().new_endpoint_id(), 1
    sender = requests.open(f"{args.service}.request")
    if not sender.send(requests.pack((client_id, request_id, index), request)):
        raise CommandFailed(f"service '{args.service}': the request does not fit its topic")

    deadline = time.monotonic() + args.timeout
    while True:
        data = None
        if replies is None:
            # The response type is not known here: the server creates the topic with it when it
            # answers, and its answer is then the topic's newest message.
            created = next((t for t in list_topics(args) if t["name"] == reply_name), None)
            if created is not None and created["type_name"]:
                responses = _frame_payload(args, created, service["response_type"], response=True)
                replies = responses.open(reply_name)
                data = replies.read_latest()
            else:
                time.sleep(0.01)
        else:
            data = replies.recv(min(0.01, max(0.0, deadline - time.monotonic())))
        if data is not None:
            # A forwarding server (the remote link's stand-in) answers a call it could not get
            # answered with the failure a caller beside the real server would get.
            (got_client, got_request, failure), response = responses.unpack_response(data)
            if (got_client, got_request) == (client_id, request_id):
                if failure is not None:
                    kind, error = failure
                    raise CommandFailed(f"service '{args.service}' failed ({kind}): {error}")
                show_message(plain(response), args.json)
                return EXIT_OK
            continue
        if not introspection().process_alive(service["server_pid"]):
            raise CommandFailed(f"the server of service '{args.service}' (pid "
                                f"{service['server_pid']}) died before answering")
        if time.monotonic() >= deadline:
            unknown = "" if responses is not None else (
                f" (nothing here knows {service['response_type']}, the response type, so a "
                "failure could not be told: -I DIR, the folder of its .hsrv file, lets it be)")
            raise CommandFailed(f"no response from service '{args.service}' within "
                                f"{args.timeout:g} s (Timeout){unknown}")


def register(commands) -> None:
    service = commands.group("service", "services: list, inspect, call")
    sub = commands.action(service, "list", "the namespace's services", service_list)
    sub.add_argument("-v", "--verbose", action="store_true", help="with types, server and clients")
    sub.add_argument("--include-hidden", action="store_true",
                     help="also the services that carry writes to nodes' parameters")
    sub = commands.action(service, "info", "one service: types, server, clients", service_info)
    sub.add_argument("service")

    sub = commands.action(service, "call", "call a service with a request given as YAML or JSON "
                                           "(any type, from the service's stored schemas)",
                          service_call)
    sub.add_argument("service")
    sub.add_argument("value", help="the request's fields, e.g. '{a: 1, b: 2}'; fields left out are zero")
    sub.add_argument("--timeout", type=positive_float, default=5.0, metavar="SECONDS",
                     help="how long to wait for the response (default 5)")
    sub.add_argument("-I", dest="include", action="append", metavar="DIR",
                     help="schema folder declaring the response type, when no reply topic of "
                          "the service tells it yet (default: the installed schemas)")
