"""The namespace as its live processes show it, for the commands that look at more than one kind
of thing (topic info names its processes, monitor its nodes and topics): topics, their traffic and
rates, the processes' presence announcements and the schedulers' nodes.
"""
from __future__ import annotations

import json

from horus_cli.common import CommandFailed, did_you_mean, introspection, namespace_name


def list_topics(args) -> list[dict]:
    return introspection().list_topics(args.namespace)


# The types of the topics a service runs on (runtime/src/service/README.md): its registration,
# its requests and its replies. `topic list` leaves them out unless --include-hidden.
SERVICE_TYPES = ("horus.ServiceRegistration", "horus.ServiceRequest<", "horus.ServiceResponse<")


def is_service_type(type_name: str) -> bool:
    """Whether a type is one only services use: a registration, a request or a response frame."""
    return type_name.startswith(SERVICE_TYPES)


def is_internal(topic: dict) -> bool:
    """Whether a topic is one a service runs on (by its type)."""
    return is_service_type(topic["type_name"])


def missing_topic(args, name: str, topics: list[dict], within: str = "",
                  hint: str = "") -> CommandFailed:
    """The one error of every command for a topic that does not exist."""
    return CommandFailed(f"no topic '{name}' in namespace '{namespace_name(args)}'{within}"
                         f"{did_you_mean(name, [t['name'] for t in topics])}{hint}")


def find_topic(args, name: str) -> dict:
    topics = list_topics(args)
    for topic in topics:
        if topic["name"] == name:
            return topic
    raise missing_topic(args, name, topics)


# A rate from fewer messages than this is off by more than a tenth (one message either way).
ENOUGH_MESSAGES = 10


def stamped_rate(traffic: dict, now: float) -> tuple[float, int] | None:
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


def best_rate(*estimates: tuple[float, int] | None) -> float | None:
    """The rate of the estimate that counted the most messages: the one least off."""
    known = [estimate for estimate in estimates if estimate is not None]
    return max(known, key=lambda estimate: estimate[1])[0] if known else None


def read_traffic(core, args, name: str) -> dict | None:
    """A topic's traffic over its whole ring, or None when it cannot be read (removed meanwhile,
    or its segment's error, which the listing shows)."""
    try:
        return core.topic_traffic(name, 0, args.namespace)
    except core.HorusError:
        return None


def announcements(args) -> list[tuple[dict, dict]]:
    """(presence entry: pid, started_wall_ns..., announcement) of the namespace's live processes:
    a scheduler's announcement (with "nodes") or a process's (with "process": its topics and
    services). Dead processes' announcements are never shown: `horus shm clean` removes them."""
    found = []
    for entry in introspection().list_presence(args.namespace):
        if entry["alive"] and not entry["error"]:
            found.append((entry, json.loads(entry["snapshot_json"])))
    return found


def list_processes(args) -> list[dict]:
    """The namespace's live processes, each with its schedulers' nodes, topics and services."""
    by_pid: dict[int, dict] = {}
    for entry, snapshot in announcements(args):
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


def live_nodes(args) -> list[dict]:
    """Every node of the namespace's live schedulers, with the process that runs it."""
    nodes = []
    for entry, snapshot in announcements(args):
        for node in snapshot.get("nodes", []):
            node["pid"] = entry["pid"]
            node["started_wall_ns"] = entry["started_wall_ns"]
            node["scheduler"] = snapshot["scheduler"]
            node["scheduler_deadline_misses"] = snapshot.get("deadline_misses")
            node["max_deadline_misses"] = snapshot.get("max_deadline_misses")
            nodes.append(node)
    nodes.sort(key=lambda n: (n["name"], n["pid"]))
    return nodes

