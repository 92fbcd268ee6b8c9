"""`horus remote`: a robot's namespace (A) reached from a laptop's (B) over loopback TCP with
mutual TLS. Topics mirrored A->B in order (POD and serialized), exported B->A where the policy
allows it, and every refusal (no certificate, another CA, a name outside the policy, a topic
outside it) made before any message flows and logged with the peer's address and name, saying
what happened: a peer outside the policy is told why and tries again less and less often; a
laptop that reaches the robot by address without --server-name, or trusts another CA, ends
naming the problem; a robot without a single rule warns that it refuses everyone. A client of
its own reads an image as remote.capnp says: its descriptor, block zeroed, then its pixels."""
from __future__ import annotations

import os
import socket
import ssl
import stat
import struct
import subprocess
import time

from conftest import HORUS, SINK_PEER, connect, serve
from peer_scripts import RECEIVE_IN_ORDER
from processes import wait_line

COUNT = 40
RING = "capacity = 512\n"

# Publishes an increasing sequence on cmd_vel (POD), generic (serialized) and secret (never
# allowed), 100 a second, until killed.
PUBLISHER = RING + """
import time, horus
from horus.msg import CmdVel, GenericMessage
cmd_vel = horus.Topic(CmdVel, "cmd_vel", capacity=capacity)
generic = horus.Topic(GenericMessage, "generic", capacity=capacity)
secret = horus.Topic(CmdVel, "secret", capacity=capacity)
print("ready", flush=True)
i = 0
while True:
    cmd_vel.send(CmdVel(stamp_nanos=i, linear=0.5 * i, angular=-1.0))
    generic.send(GenericMessage(data=bytes([i % 256]) * 100, metadata=f"n{i}"))
    secret.send(CmdVel(stamp_nanos=i))
    i += 1
    time.sleep(0.01)
"""

# Prints the first COUNT messages of each topic it is given: "<topic> <seq> ..." (-1: a message
# whose content does not match its number).
SUBSCRIBER = RING + """
import sys, time, horus
from horus.msg import CmdVel, GenericMessage
count = int(sys.argv[1])
def generic_key(m):
    number = int(m.metadata[1:])
    return number, m.data == bytes([number % 256]) * 100
wanted = {"cmd_vel": (CmdVel, lambda m: (m.stamp_nanos, m.linear == 0.5 * m.stamp_nanos)),
          "goal": (CmdVel, lambda m: (m.stamp_nanos, m.linear == 0.5 * m.stamp_nanos)),
          "generic": (GenericMessage, generic_key)}
""" + RECEIVE_IN_ORDER

# B's own topics: goal (exported when allowed) and private (whose export the robot refuses).
LAPTOP_PUBLISHER = RING + """
import time, horus
from horus.msg import CmdVel
goal = horus.Topic(CmdVel, "goal", capacity=capacity)
private = horus.Topic(CmdVel, "private", capacity=capacity)
print("ready", flush=True)
i = 0
while True:
    goal.send(CmdVel(stamp_nanos=i, linear=0.5 * i))
    private.send(CmdVel(stamp_nanos=i))
    i += 1
    time.sleep(0.01)
"""


def sequences(process) -> dict[str, list[int]]:
    out, _ = process.communicate(timeout=60)
    assert process.returncode == 0, process.errors.text()
    return {name: [int(n) for n in numbers] for name, *numbers in
            (line.split() for line in out.splitlines() if line and line != "ready")}


def assert_consecutive(seen: list[int]) -> None:
    assert len(seen) == COUNT
    assert seen == list(range(seen[0], seen[0] + COUNT)), seen


def topic_names(world) -> list[str]:
    listed = subprocess.run([HORUS, "topic", "list"], env=world.env(), capture_output=True,
                            text=True, check=True)
    return listed.stdout.split()


def test_keygen_makes_private_keys_and_names_certificates(certs):
    for name in ("ca", "robot", "laptop"):
        assert stat.S_IMODE(os.stat(certs / f"{name}.key").st_mode) == 0o600
    subject = subprocess.run([HORUS, "remote", "keygen", str(certs), "laptop"],
                             capture_output=True, text=True)
    assert subject.returncode == 1 and "laptop.crt exists" in subject.stderr
    from cryptography import x509
    certificate = x509.load_pem_x509_certificate((certs / "laptop.crt").read_bytes())
    assert certificate.subject.rfc4514_string() == "CN=laptop"


def test_topics_mirrored_in_order_and_export_allowed_or_refused(children, worlds, certs,
                                                                tmp_path):
    robot, laptop = worlds
    children.python(PUBLISHER, robot.env())
    policy = tmp_path / "policy"
    policy.write_text("# what the laptop may do\nlaptop read generic\n\nlaptop  write  goal\n")
    server, port = serve(children, robot, certs, "laptop read cmd_vel", policy=policy)
    receiver = children.python(SUBSCRIBER, laptop.env(), str(COUNT), "cmd_vel", "generic")
    wait_line(receiver, "ready")
    children.python(LAPTOP_PUBLISHER, laptop.env())
    at_robot = children.python(SUBSCRIBER, robot.env(), str(COUNT), "goal")
    wait_line(at_robot, "ready")
    client = connect(children, laptop, certs, port, "--import", "*", "--export", "goal",
                     "--export", "private", "--queue", "1000")
    wait_line(client, "connected to")

    mirrored = sequences(receiver)
    assert_consecutive(mirrored["cmd_vel"])
    assert_consecutive(mirrored["generic"])
    assert_consecutive(sequences(at_robot)["goal"])

    # Only what the policy lets the laptop read is offered; what it may not write never
    # reaches the robot's namespace.
    client.errors.wait_for("the robot refused private")
    assert "secret" not in topic_names(laptop)
    assert "private" not in topic_names(robot)
    server.errors.wait_for("refused to let laptop write topic private")


# Prints, for each topic named, its type and its type description's bytes in hex (its segment's).
DESCRIPTIONS = """
import sys, horus
topics = {topic["name"]: topic for topic in horus._core.list_topics()}
for name in sys.argv[1:]:
    print(name, topics[name]["type_name"], topics[name]["description"].hex())
"""


def descriptions(children, world, *names: str) -> dict[str, tuple[str, str]]:
    """Each topic's (type, description in hex) in `world`."""
    out, _ = children.python(DESCRIPTIONS, world.env(), *names).communicate(timeout=60)
    return {name: (type_name, description) for name, type_name, description in
            (line.split() for line in out.splitlines())}


def test_a_mirrored_topic_has_the_type_description_of_its_origin(children, worlds, certs):
    # Only the link opens cmd_vel on the laptop and goal on the robot: their segments are made
    # from the type the wire carried.
    robot, laptop = worlds
    children.python(PUBLISHER, robot.env())
    children.python(LAPTOP_PUBLISHER, laptop.env())
    server, port = serve(children, robot, certs, "laptop read cmd_vel", "laptop write goal")
    client = connect(children, laptop, certs, port, "--import", "cmd_vel", "--export", "goal")
    client.errors.wait_for("importing cmd_vel")
    client.errors.wait_for("exporting goal")
    server.errors.wait_for("laptop publishes to goal")

    at_robot = descriptions(children, robot, "cmd_vel", "goal")
    at_laptop = descriptions(children, laptop, "cmd_vel", "goal")
    assert at_robot["cmd_vel"][0] == "horus.msg.CmdVel"
    assert at_robot["cmd_vel"][1] != ""  # the publisher's type has a description
    assert at_laptop["cmd_vel"] == at_robot["cmd_vel"]
    assert at_robot["goal"] == at_laptop["goal"]


def test_bad_arguments_exit_two_naming_the_problem_first(worlds):
    for args in (["serve", "--listen", "127.0.0.1:0", "--insecure", "--allow", "laptop peek *"],
                 ["serve", "--insecure"], ["connect", "--insecure"],
                 ["connect", "127.0.0.1:1"]):
        result = subprocess.run([HORUS, "remote", *args], env=worlds[0].env(),
                                capture_output=True, text=True)
        assert result.returncode == 2, (args, result.stderr)
        assert result.stderr.splitlines()[0].startswith("horus-remote: "), result.stderr


def test_type_mismatch_is_refused_naming_both_types(children, worlds, certs):
    robot, laptop = worlds
    children.python(PUBLISHER, robot.env())
    serve_process, port = serve(children, robot, certs, "laptop read *")
    # The laptop has its own cmd_vel of another type: mirroring into it is refused.
    clash = children.python(RING + """
import horus
from horus.msg import GenericMessage
topic = horus.Topic(GenericMessage, "cmd_vel", capacity=capacity)
print("ready", flush=True)
import time
time.sleep(60)
""", laptop.env())
    wait_line(clash, "ready")
    client = connect(children, laptop, certs, port, "--import", "cmd_vel")
    line = client.errors.wait_for("cannot import cmd_vel")
    assert "GenericMessage" in line and "CmdVel" in line


def refused(children, worlds, certs, *connect_args, name: str = "laptop", folder=None):
    """Connects a peer the robot must refuse; the robot's log line about it."""
    robot, laptop = worlds
    children.python(PUBLISHER, robot.env())
    server, port = serve(children, robot, certs, "laptop read *")
    client = connect(children, laptop, folder or certs, port, "--import", "*", *connect_args,
                     name=name)
    line = server.errors.wait_for("refused")
    client.errors.wait_for("connection to")
    assert "importing" not in client.errors.text()
    assert "cmd_vel" not in topic_names(laptop)
    assert "127.0.0.1:" in line
    return line


def test_peer_without_certificate_is_refused(children, worlds, certs):
    line = refused(children, worlds, certs, "--insecure")
    assert "(no name: it does not speak TLS: a peer run with --insecure?)" in line


def test_tls_peer_presenting_no_certificate_is_refused(children, worlds, certs):
    server, port = serve(children, worlds[0], certs, "laptop read *")
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    context.load_verify_locations(certs / "ca.crt")
    with socket.create_connection(("127.0.0.1", port), timeout=10) as raw:
        try:
            with context.wrap_socket(raw, server_hostname="robot") as peer:
                peer.sendall(b"hello")
                peer.recv(1)
        except OSError:  # the robot's alert: a certificate is required
            pass
    line = server.errors.wait_for("refused 127.0.0.1:")
    assert "(no name: it presented no certificate)" in line, line


def test_peer_of_another_ca_is_refused(children, worlds, certs):
    line = refused(children, worlds, certs, name="intruder", folder=certs.parent / "intruder")
    assert "(no name: its certificate does not verify against our CA)" in line


def test_peer_outside_the_policy_is_refused(children, worlds, certs):
    line = refused(children, worlds, certs, name="stranger")
    assert "refused stranger at 127.0.0.1:" in line


def test_peer_outside_the_policy_is_told_why_and_backs_off(children, worlds, certs):
    robot, laptop = worlds
    server, port = serve(children, robot, certs, "laptop read *")
    client = connect(children, laptop, certs, port, "--import", "*", name="stranger")
    client.errors.wait_for("(the robot refused this peer: no policy line of this robot names "
                           "peer 'stranger'); trying again in 0.2 s")
    time.sleep(6)
    # 0.2, 0.4, 0.8, 1.6, 3.2 s apart, then 5: about 5 attempts in 6 s (it was 5 a second).
    attempts = server.errors.text().count("refused stranger at")
    assert 2 <= attempts <= 10, server.errors.text()
    assert "trying again in 1.6 s" in client.errors.text(), client.errors.text()
    assert client.poll() is None, "it gave up: the robot's policy may change"
    client.kill()
    assert "connected to" not in client.stdout.read()


def connect_without_server_name(children, world, certs, port: int, folder=None, name="laptop"):
    """`horus remote connect 127.0.0.1:PORT` as `name`: the robot's certificate is named robot."""
    client = children.start([HORUS, "--namespace", world.namespace, "remote", "connect",
                             f"127.0.0.1:{port}", "--certs", str(folder or certs), "--name", name],
                            world.env())
    client.wait(timeout=30)
    client.errors.wait_closed()
    return client


def test_connecting_by_address_without_the_robots_name_ends_saying_so(children, worlds, certs):
    robot, laptop = worlds
    server, port = serve(children, robot, certs, "laptop read *")
    client = connect_without_server_name(children, laptop, certs, port)
    assert client.returncode == 1, client.errors.text()
    assert client.errors.lines[-1] == ("horus-remote: the robot's certificate is named 'robot', "
                                       "not '127.0.0.1': pass --server-name robot"), \
        client.errors.text()
    assert "trying again" not in client.errors.text()
    line = server.errors.wait_for("refused 127.0.0.1:")
    assert "(no name: it did not accept our certificate, named 'robot': a peer that connects " \
           "by address needs --server-name robot)" in line, line


def test_a_laptop_trusting_another_ca_ends_saying_so(children, worlds, certs):
    robot, laptop = worlds
    server, port = serve(children, robot, certs, "intruder read *")
    other = certs.parent / "other"  # the intruder's own CA, not the robot's
    client = connect_without_server_name(children, laptop, certs, port, folder=other,
                                         name="intruder")
    assert client.returncode == 1, client.errors.text()
    assert client.errors.lines[-1].startswith(
        f"horus-remote: the robot's certificate (named 'robot') does not verify against "
        f"{other}/ca.crt: "), client.errors.text()
    line = server.errors.wait_for("refused 127.0.0.1:")
    assert "(no name: it does not trust our CA: its ca.crt is another's)" in line, line


def test_serve_without_a_rule_warns_that_it_refuses_everyone(children, worlds, certs, tmp_path):
    robot = worlds[0]
    nobody = tmp_path / "policy"
    nobody.write_text("# nobody yet\n")
    for extra in ([], ["--policy", str(nobody)]):
        server = children.start([HORUS, "remote", "serve", "--listen", "127.0.0.1:0", "--certs",
                                 str(certs), "--name", "robot", *extra], robot.env())
        wait_line(server, "serving namespace")
        server.errors.wait_for("WARNING: no --allow or --policy rule: every peer will be refused")
    server, _ = serve(children, robot, certs, "laptop read *")
    server.kill()
    server.wait()
    server.errors.wait_closed()
    assert "WARNING" not in server.errors.text()


def test_insecure_link_only_when_both_sides_ask_and_both_warn(children, worlds, certs):
    robot, laptop = worlds
    children.python(PUBLISHER, robot.env())
    server = children.start([HORUS, "remote", "serve", "--insecure", "--listen", "127.0.0.1:0",
                             "--allow", "insecure read cmd_vel"], robot.env())
    port = int(wait_line(server, "serving namespace").rsplit(" ", 1)[1])
    server.errors.wait_for("WARNING: --insecure")
    receiver = children.python(SUBSCRIBER, laptop.env(), str(COUNT), "cmd_vel")
    wait_line(receiver, "ready")
    client = children.start([HORUS, "remote", "connect", f"127.0.0.1:{port}", "--insecure",
                             "--import", "*"], laptop.env())
    client.errors.wait_for("WARNING: --insecure")
    assert_consecutive(sequences(receiver)["cmd_vel"])
    server.errors.wait_for("insecure connected from 127.0.0.1:")
    # A peer that speaks TLS to it is not let in: nothing falls back to plain TCP silently.
    secure = connect(children, laptop, certs, port, "--import", "*")
    secure.errors.wait_for("connection to")
    assert "importing" not in secure.errors.text()


BIG = 10 << 20  # over the 8 MiB a connection reads at first

# Publishes on `sys.argv[1]` (a topic it makes now, with room for BIG-byte messages) a BIG-byte
# GenericMessage a few times a second, every byte the message's number modulo 256.
BIG_PUBLISHER = f"BIG = {BIG}\n" + """
import sys, time, horus
from horus.msg import GenericMessage
topic = horus.Topic(GenericMessage, sys.argv[1], capacity=4, max_message_size=BIG + 4096)
print("ready", flush=True)
i = 0
while True:
    topic.send(GenericMessage(data=bytes([i % 256]) * BIG, metadata=f"n{i}"))
    i += 1
    time.sleep(0.2)
"""

# Prints the numbers of the first 3 messages of `sys.argv[1]` (-1 for one not BIG bytes of its
# number).
BIG_SUBSCRIBER = f"BIG = {BIG}\n" + """
import sys, time, horus
from horus.msg import GenericMessage
topic = horus.Topic(GenericMessage, sys.argv[1], capacity=4, max_message_size=BIG + 4096)
seen = []
while len(seen) < 3:
    message = topic.recv(timeout=30)
    assert message is not None, "nothing came"
    number = int(message.metadata[1:])
    seen.append(number if message.data == bytes([number % 256]) * BIG else -1)
print(*seen, flush=True)
"""


def test_topics_larger_than_the_first_limit_made_after_connecting(children, worlds, certs):
    robot, laptop = worlds
    _, port = serve(children, robot, certs, "laptop read big_*", "laptop write big_goal")
    client = connect(children, laptop, certs, port, "--import", "big_*", "--export", "big_goal")
    wait_line(client, "connected to")
    # Both topics appear only now, after the connection was made with its first limit.
    wait_line(children.python(BIG_PUBLISHER, robot.env(), "big_camera"), "ready")
    wait_line(children.python(BIG_PUBLISHER, laptop.env(), "big_goal"), "ready")
    client.errors.wait_for("importing big_camera")
    client.errors.wait_for("exporting big_goal")
    for world, name in ((laptop, "big_camera"), (robot, "big_goal")):
        receiver = children.python(BIG_SUBSCRIBER, world.env(), name)
        out, _ = receiver.communicate(timeout=90)
        assert receiver.returncode == 0, receiver.errors.text()
        numbers = [int(n) for n in out.split()]
        assert len(numbers) == 3 and -1 not in numbers, numbers
        assert numbers == sorted(set(numbers)), numbers
    assert "disconnected" not in client.errors.text()
    assert "trying again" not in client.errors.text()


# Publishes on camera a 640x480 RGB image 30 times a second, numbered by its timestamp, whose
# pixels are a pattern shifted by its number.
IMAGE_PUBLISHER = """
import time, horus, numpy
camera = horus.Topic(horus.Image, "camera")
base = numpy.arange(480 * 640 * 3, dtype=numpy.uint32).reshape(480, 640, 3)
print("ready", flush=True)
i = 0
while True:
    image = horus.Image.from_numpy(((base + i) % 251).astype(numpy.uint8), horus.ImageEncoding.Rgb8)
    image.timestamp_ns = i
    image.frame_id = "camera_link"
    camera.send(image)
    i += 1
    time.sleep(1 / 30)
"""

# Prints the numbers of the first 20 images on camera (-1 for one whose pixels, size, encoding
# or frame are not its number's), then the first and last pixel bytes of the last.
IMAGE_SUBSCRIBER = """
import horus, numpy
camera = horus.Topic(horus.Image, "camera")
base = numpy.arange(480 * 640 * 3, dtype=numpy.uint32).reshape(480, 640, 3)
seen = []
while len(seen) < 20:
    image = camera.recv(timeout=30)
    assert image is not None, "no image came"
    number = image.timestamp_ns
    pixels = numpy.asarray(image)
    intact = (image.width, image.height, image.encoding, image.frame_id) == (
        640, 480, horus.ImageEncoding.Rgb8, "camera_link") and numpy.array_equal(
        pixels.reshape(480, 640, 3), (base + number) % 251)
    seen.append(number if intact else -1)
print(*seen, flush=True)
flat = pixels.reshape(-1)
print(number, int(flat[0]), int(flat[-1]), flush=True)
"""


def test_images_mirrored_with_their_pixels(children, worlds, certs):
    robot, laptop = worlds
    wait_line(children.python(IMAGE_PUBLISHER, robot.env()), "ready")
    _, port = serve(children, robot, certs, "laptop read camera")
    client = connect(children, laptop, certs, port, "--import", "camera")
    client.errors.wait_for("importing camera")
    receiver = children.python(IMAGE_SUBSCRIBER, laptop.env())
    out, _ = receiver.communicate(timeout=90)
    assert receiver.returncode == 0, receiver.errors.text()
    numbers_line, pixels_line = out.splitlines()
    numbers = [int(n) for n in numbers_line.split()]
    assert -1 not in numbers, numbers
    # In order, none twice (a slow link drops images, latest wins; it never repeats them).
    assert numbers == sorted(set(numbers)), numbers
    number, first, last = (int(n) for n in pixels_line.split())
    assert (first, last) == (number % 251, (480 * 640 * 3 - 1 + number) % 251)


def test_a_frame_crosses_as_its_descriptor_and_its_data(children, worlds, certs, tmp_path):
    import numpy
    robot, _ = worlds
    wait_line(children.python(IMAGE_PUBLISHER, robot.env()), "ready")
    _, port = serve(children, robot, certs, "laptop read camera")
    dump = tmp_path / "frame"
    peer = children.start([SINK_PEER, str(port), str(certs), "camera", "4", "0", str(dump)],
                          robot.env())
    wait_line(peer, "")  # printed once the first frame's data is in `dump`
    data = dump.read_bytes()
    # horus.msg.ImageDescriptor (`horus msg show`): 80 bytes, block (16) at 24, stamp at 72.
    width, height, encoding, channels, _step, data_size = struct.unpack_from("<IIBB2xIQ", data)
    number = struct.unpack_from("<Q", data, 72)[0]
    assert (width, height, encoding, channels) == (640, 480, 2, 3)  # Rgb8
    assert data_size == 640 * 480 * 3 and len(data) == 80 + data_size, (data_size, len(data))
    assert data[24:40] == bytes(16), "the block of the sender's pool went out"
    base = numpy.arange(480 * 640 * 3, dtype=numpy.uint32)
    assert data[80:] == ((base + number) % 251).astype(numpy.uint8).tobytes()
