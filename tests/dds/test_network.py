"""horus.Network: the bridge inside a scheduler's own process. Two Python processes in two
namespaces that share no memory, each a scheduler with a Network and no `horus bridge` running:
a topic one publishes crosses to the other in order."""
from __future__ import annotations

import pytest

from processes import wait_line
from test_bridge import COUNT, assert_in_order, python_env

# Publishes cmd_vel from a node at 100 Hz, exporting it through the scheduler's Network (as
# ROS 2's Twist when argv[2:] names it in ros2_types).
TALKER = """
import sys, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "cmd_vel", capacity=512)
sent = [0]
def tick(node):
    topic.send(CmdVel(stamp_nanos=sent[0], linear=0.5 * sent[0]))
    sent[0] += 1
network = horus.Network(export=["cmd_*"], domain=int(sys.argv[1]), depth=1000,
                        ros2_types=sys.argv[2:])
horus.run(horus.Node(name="talker", tick=tick, rate=100), network=network)
"""

# Takes the first COUNT cmd_vel messages the scheduler's Network imports, prints their stamps.
LISTENER = """
import sys, horus
from horus.msg import CmdVel
count = int(sys.argv[2])
topic = horus.Topic(CmdVel, "cmd_vel", capacity=512)
seen = []
def tick(node):
    while (message := topic.try_recv()) is not None and len(seen) < count:
        seen.append(message.stamp_nanos if message.linear == 0.5 * message.stamp_nanos else -1)
    if len(seen) >= count:
        node.request_stop()
network = horus.Network(import_=["cmd_vel"], domain=int(sys.argv[1]), depth=1000)
with horus.Scheduler(network=network) as scheduler:
    scheduler.add(horus.Node(name="listener", tick=tick, rate=200))
    status = scheduler.run()
print("seen", *seen, flush=True)
sys.exit(status)
"""


def test_a_topic_crosses_between_two_schedulers_with_networks(
        dds_domain, worlds, children, generated):
    source, target = worlds
    listener = children.python(LISTENER, python_env(target, generated), str(dds_domain),
                               str(COUNT))
    wait_line(listener, "bridge on DDS domain")
    talker = children.python(TALKER, python_env(source, generated), str(dds_domain))
    wait_line(talker, "exporting 'cmd_vel'")
    out, errors = listener.communicate(timeout=120)
    assert listener.returncode == 0, errors
    assert "importing rt/cmd_vel" in out, out
    seen = [int(n) for n in out.splitlines()[-1].split()[1:]]
    assert_in_order("cmd_vel", seen)


def test_a_network_carries_a_topic_as_its_ros2_twin(dds_domain, worlds, children, generated,
                                                   dds_peer):
    peer = children.start([dds_peer, "read-twist", str(dds_domain), "3"])
    wait_line(peer, "ready")
    talker = children.python(TALKER, python_env(worlds[0], generated), str(dds_domain), "cmd_vel")
    assert wait_line(talker, "exporting 'cmd_vel'").endswith("(geometry_msgs::msg::dds_::Twist_)")
    out, errors = peer.communicate(timeout=60)
    assert peer.returncode == 0, errors
    assert len(out.splitlines()) == 3 and all(
        line.endswith(",0,0 angular=0,0,0") for line in out.splitlines()), out


def test_a_network_that_carries_nothing_is_refused():
    import horus
    with pytest.raises(ValueError, match="carries nothing"):
        horus.Network(domain=3)
    with pytest.raises(TypeError, match="list of topic name patterns"):
        horus.Network(export="cmd_vel")
    with pytest.raises(TypeError, match="takes a horus.Network"):
        horus.Scheduler(network="cmd_vel")
    with pytest.raises(TypeError, match="ros2_types takes a list of topic name patterns"):
        horus.Network(export=["cmd_vel"], ros2_types="cmd_vel")
    with pytest.raises(ValueError, match="service_timeout must be a number of seconds > 0"):
        horus.Network(export_services=["*"], service_timeout=0)
