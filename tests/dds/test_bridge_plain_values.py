"""Plain-value topics (a Topic of f32, [f32; 3], Vec<u8> or String, no schema of their own)
cross DDS like messages: each is the one-field message its type description makes of it, in the
IDL module horus::plain, and arrives in the other namespace as the same plain value."""
from __future__ import annotations

from processes import wait_line
from test_bridge import python_env

TOPICS = {"speed": ("f32", [0.5, 1.5, 2.5]), "position": ("[f32; 3]", [[1.0, 2.0, 3.0]]),
          "blob": ("Vec<u8>", [b"\x00\x01\xff"]), "label": ("String", ["left wheel"])}
IDL_NAMES = {"speed": "f32_", "position": "f32_3_", "blob": "Vec_u8_", "label": "String_"}

# Publishes each topic's values again and again, exporting them through a Network.
TALKER = f"""
import sys, time, horus
values = {TOPICS!r}
topics = {{name: horus.Topic(kind, name) for name, (kind, _) in values.items()}}
network = horus.Network(export=list(values), domain=int(sys.argv[1]))
with horus.Scheduler(network=network):
    while True:
        for name, (_, sent) in values.items():
            for value in sent:
                topics[name].send(value)
        time.sleep(0.02)
"""

# Imports the topics and prints, once each has seen every value, "got <name> <repr of values>".
LISTENER = f"""
import sys, time, horus
values = {TOPICS!r}
topics = {{name: horus.Topic(kind, name) for name, (kind, _) in values.items()}}
seen = {{name: [] for name in values}}
network = horus.Network(import_=list(values), domain=int(sys.argv[1]))
with horus.Scheduler(network=network):
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and any(len(seen[n]) < len(v[1]) for n, v in values.items()):
        for name, (_, sent) in values.items():
            while (value := topics[name].try_recv()) is not None:
                value = value.tolist() if hasattr(value, "tolist") else value  # numpy arrays
                if value in sent and value not in seen[name]:
                    seen[name].append(value)
        time.sleep(0.01)
for name in values:
    print("got", name, repr(sorted(seen[name], key=repr)), flush=True)
"""


def test_plain_value_topics_cross_as_themselves(dds_domain, worlds, children, generated):
    source, target = worlds
    listener = children.python(LISTENER, python_env(target, generated), str(dds_domain))
    wait_line(listener, "bridge on DDS domain")
    talker = children.python(TALKER, python_env(source, generated), str(dds_domain))
    exported = {}
    while len(exported) < len(IDL_NAMES):  # in the order the bridge finds the topics
        line = wait_line(talker, "exporting '")
        exported[line.split("'")[1]] = line
    for name, idl in IDL_NAMES.items():
        assert exported[name].endswith(f"(horus::plain::dds_::{idl})"), exported[name]
    out, errors = listener.communicate(timeout=120)
    assert listener.returncode == 0, errors
    got = {line.split()[1]: line.split(" ", 2)[2] for line in out.splitlines()
           if line.startswith("got ")}
    for name, (_, sent) in TOPICS.items():
        assert got[name] == repr(sorted(sent, key=repr)), (name, out, errors)
