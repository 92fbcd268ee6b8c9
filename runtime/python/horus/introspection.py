"""A running HORUS system seen from outside its processes: what the `horus` command reads.

Listings of a namespace's topics, services, processes (their presence announcements), log ring and
shared-memory objects; a topic's traffic from its slot headers; the clean-up of what dead processes
left; and handles that open a topic, or a service's request and reply topics, by name with bytes
in and bytes out, for types known only from what a segment stores (horus.typedesc makes their
classes). A thin layer over the runtime's binding (horus._core) alone: the service frames are the
C++ codec's. Every namespace argument may be empty: $HORUS_NAMESPACE, else "default".
"""
from __future__ import annotations

from . import _core

# What the runtime raises when a namespace's objects cannot be read (horus.HorusError).
HorusError = _core.HorusError

# A type-erased topic handle: send(bytes), recv(timeout), try_recv(), read_latest(), has_msg(),
# stats() and capacity, with the identity given by name, type, fingerprint and geometry.
RawTopic = _core.Topic



class ServiceFrame:
    """The request or response frames of a service around a payload class (a generated one, or
    one horus.typedesc made), as the runtime's own codec (horus::ServiceFrameCodec) writes and
    reads them: the frame type's name, schema, fingerprint and layout, a handle on a frame topic,
    and frames to and from (head, payload)."""

    def __init__(self, payload_type, response: bool) -> None:
        self.payload_type = payload_type
        self._codec = codec = _core.ServiceFrameCodec(payload_type, response)
        self.name, self.fingerprint, self.schema = codec.name, codec.fingerprint, codec.schema
        self.is_pod, self.size, self.alignment = codec.is_pod, codec.size, codec.alignment
        # A topic this creates carries the frame's type description, as the runtime's own frame
        # topics do: a forwarding server writes a failure into a reply topic from it.
        self.description = codec.description

    def open(self, topic_name: str) -> RawTopic:
        """A handle on a request or reply topic of this frame type (created with the runtime's
        default geometry when nobody has it open)."""
        return _core.Topic(topic_name, self.name, self.fingerprint, self.schema, self.is_pod,
                           self.size, self.alignment, 64, 16 * 1024, False, self.description)

    def pack(self, caller: tuple[int, int, int], payload) -> bytes:
        """The request frame from (client_id, request_id, reply_to) carrying `payload`."""
        return self._codec.request(_core.ServiceCaller(*caller), payload.to_bytes())

    def unpack_request(self, data: bytes):
        """((client_id, request_id, reply_to), payload message) of a request frame; ValueError
        when the bytes are not one."""
        read = self._codec.read_request(data)
        if read is None:
            raise ValueError(f"{self.name}: not a request frame")
        caller, payload = read
        return (caller.client_id, caller.request_id, caller.reply_to), \
            self.payload_type.from_bytes(payload)

    def unpack_response(self, data: bytes):
        """((client_id, request_id, failure), payload message) of a response frame: `failure`
        None for an answer, else (the kind the runtime names it: ServiceFailed, NoServer,
        Timeout or Transport; the error text); ValueError when the bytes are not a frame."""
        read = self._codec.read_response(data)
        if read is None:
            raise ValueError(f"{self.name}: not a response frame")
        client_id, request_id, status, kind, error, payload = read
        failure = None if status == 0 else (kind or f"status {status}", error)
        return (client_id, request_id, failure), self.payload_type.from_bytes(payload)


def current_namespace() -> str:
    """The namespace an empty namespace argument means here."""
    return _core.current_namespace()


def namespace_directory(namespace: str = "") -> str:
    """The folder holding a namespace's topic segments."""
    return _core.namespace_directory(namespace)


def list_topics(namespace: str = "") -> list[dict]:
    """The namespace's topics, sorted by name: type, fingerprint, schema, type description bytes
    (empty when the type carries none), geometry, publishers,
    subscribers, message count, last send, user pids, and the error of a segment that does not
    read."""
    return _core.list_topics(namespace)


def topic_traffic(topic: str, since: int, namespace: str = "") -> dict:
    """A topic's message count, and the messages from ticket `since` still in its ring with their
    payload bytes and the send stamps where the second changes (slot headers only, nothing
    decoded). Raises HorusError when the topic is gone or unreadable."""
    return _core.topic_traffic(topic, since, namespace)


def open_topic(name: str, type_name: str, fingerprint: int, schema: str, is_pod: bool, size: int,
               alignment: int, capacity: int, max_message_size: int,
               single_publisher: bool, description: bytes = b"") -> RawTopic:
    """A bytes-in, bytes-out handle on a topic, created with this identity (and the type
    description bytes, when known) and geometry when nobody has it open (an existing segment keeps
    its own geometry and description, and refuses another type)."""
    return _core.Topic(name, type_name, fingerprint, schema, is_pod, size, alignment, capacity,
                       max_message_size, single_publisher, description)


def list_services(namespace: str = "") -> list[dict]:
    """The namespace's services, sorted by name: request and response types, fingerprint, live
    servers (and the server's pid) and clients."""
    return _core.list_services(namespace)


def is_param_service(name: str) -> bool:
    """Whether a service is one that carries writes to a node's parameters (param_service_name):
    the service listings leave them out, as `topic list` leaves out the topics services run on."""
    # The name of a node no name can contain, split where it went in.
    marker = "\x00"
    prefix, _, suffix = _core.param_service_name(marker).partition(marker)
    return (name.startswith(prefix) and name.endswith(suffix)
            and len(name) > len(prefix) + len(suffix))


def list_presence(namespace: str = "") -> list[dict]:
    """The processes' presence announcements (dead processes' too, with alive False): pid, start
    time and the announcement as JSON (a scheduler's nodes, or a process's topics and services)."""
    return _core.list_presence(namespace)


def read_log(namespace: str = "") -> dict:
    """The namespace's log ring: its retained records oldest first, and its counters."""
    return _core.read_log(namespace)


def list_namespace_objects(namespace: str = "") -> list[dict]:
    """The namespace's log ring ("@logs") and presence folder ("@presence"), those that exist:
    path, size, and whether a live process uses it."""
    return _core.list_namespace_objects(namespace)


def clean_namespace(namespace: str = "") -> int:
    """Unlinks the topic segments whose every user died (and the log ring and presence folder
    once no live process uses them); returns how many segments."""
    return _core.clean_namespace(namespace)


def clean_presence(namespace: str = "") -> int:
    """Removes the presence announcements dead processes left; returns how many."""
    return _core.clean_presence(namespace)


def clean_pools(namespace: str = "") -> int:
    """Removes the tensor pool files no live process maps; returns how many."""
    return _core.clean_pools(namespace)


def replay_frames(type_name: str, fingerprint: int, namespace: str, keep: int):
    """Frames of a recorded Image, DepthImage, PointCloud or Tensor topic made again in the
    namespace's pool (replay(recorded) -> the bytes to send); the last `keep` stay alive."""
    return _core.ReplayFrames(type_name, fingerprint, namespace, keep)


def process_alive(pid: int) -> bool:
    """Whether a process runs (a zombie does not; pid 0 never)."""
    return not _core.service_server_gone(pid)


def new_endpoint_id() -> int:
    """An id no other service client or server of any process uses (this pid, then a count)."""
    return _core.new_service_endpoint_id()


def has_dds() -> bool:
    """Whether this horus was built with Cyclone DDS: `horus bridge` and horus.Network need it."""
    return hasattr(_core, "dds")


def has_view() -> bool:
    """Whether this horus was built with the live view (Cap'n Proto): `horus record replay
    --view` needs it."""
    return hasattr(_core, "view")


def live_view(namespace: str, listen: str, port: int):
    """The namespace served over the Foxglove WebSocket protocol (bridges/view), not started:
    start(), stop(), port, status_json(), and set_time(ns), the time told to viewers and stamped
    on what they are sent from then on (the wall clock until the first call)."""
    return _core.view.LiveView(namespace, listen, port)
