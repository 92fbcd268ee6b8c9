"""Pool-backed topics across `horus bridge`: an Image published in namespace A (its pixels in A's
tensor pool) reaches namespace B with its pixels, in a block of B's own pool; on DDS it is the
descriptor with the block's bytes in place of the block (dds_cdr.PoolCodec)."""
from __future__ import annotations

import horus
import pytest
from dds_cdr import PoolCodec
from horus.msg import ImageDescriptor, ImageEncoding, PoolBlock

from processes import wait_line
from test_bridge import bridge, python_env

COUNT = 20

# The i-th image: 6x8 RGB, every byte a function of i and its place.
PIXELS = """
import numpy
def pixels(i):
    return ((numpy.arange(6 * 8 * 3, dtype=numpy.uint32) * 7 + i) % 251).astype(
        numpy.uint8).reshape(6, 8, 3)
"""

# Publishes the i-th image, stamped i, 20 a second until killed.
PUBLISHER = PIXELS + """
import time, horus
topic = horus.Topic(horus.Image, "camera")
print("ready", flush=True)
i = 0
while True:
    image = horus.Image.from_numpy(pixels(i))
    image.timestamp_ns, image.frame_id = i, "camera_link"
    topic.send(image)
    i += 1
    time.sleep(0.05)
"""

# Takes COUNT images and prints, for each, its stamp, whether its pixels are the stamp's, and its
# frame, shape and pool: "<stamp> <ok> <frame> <height>x<width>x<channels> <pool id>".
SUBSCRIBER = PIXELS + f"""
import horus
topic = horus.Topic(horus.Image, "camera")
print("ready", flush=True)
for _ in range({COUNT}):
    image = topic.recv(timeout=60)
    pixels_here = numpy.asarray(image)
    print(image.timestamp_ns, numpy.array_equal(pixels_here, pixels(image.timestamp_ns)),
          image.frame_id, "x".join(map(str, pixels_here.shape)), image.pool.id, flush=True)
print("pool", horus.TensorPool.default().id, flush=True)
"""


def test_an_image_crosses_with_its_pixels_into_a_block_of_the_other_namespace(
        dds_domain, worlds, children, generated):
    source, target = worlds
    subscriber = children.python(SUBSCRIBER, python_env(target, generated))
    wait_line(subscriber, "ready")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    bridge(children, target, generated, dds_domain, "--import", "camera")
    exporter = bridge(children, source, generated, dds_domain, "--export", "camera")
    assert wait_line(exporter, "exporting") == (
        "exporting 'camera' (horus.msg.ImageDescriptor) as rt/camera "
        "(horus::msg::dds_::ImageDescriptor_)")
    out, errors = subscriber.communicate(timeout=90)
    assert subscriber.returncode == 0, errors
    lines = out.splitlines()
    own_pool = lines[-1].split()[1]
    images = [line.split() for line in lines[:-1]]
    assert len(images) == COUNT, out
    stamps = [int(image[0]) for image in images]
    assert stamps == list(range(stamps[0], stamps[0] + COUNT)), out
    assert all(image[1:] == ["True", "camera_link", "6x8x3", own_pool] for image in images), out


def test_a_pool_descriptor_crosses_as_its_fields_with_the_data_in_place_of_its_block():
    codec = PoolCodec(ImageDescriptor)
    descriptor = ImageDescriptor(width=2, height=1, encoding=ImageEncoding.Rgb8, channels=3,
                                 step=6, data_size=6, block=PoolBlock(), frame_id="cam",
                                 timestamp_ns=42)
    data = bytes(range(10, 16))
    cdr = codec.encode(descriptor.to_bytes() + data)
    # width, height, encoding, channels, step, data_size, then the data as sequence<uint8>.
    assert cdr[4:28] == (b"\x02\0\0\0\x01\0\0\0\x02\x03\0\0\x06\0\0\0"
                         + (6).to_bytes(8, "little"))
    assert cdr[28:38] == (6).to_bytes(4, "little") + data
    assert codec.decode(cdr) == descriptor.to_bytes() + data
    with pytest.raises(ValueError, match="does not decode as horus.msg.ImageDescriptor"):
        codec.decode(cdr[:30])
    with pytest.raises(TypeError, match="has no horus.msg.PoolBlock field"):
        PoolCodec(horus.msg.CmdVel)


def test_a_plain_dds_program_reads_an_image_with_its_pixels(
        dds_domain, worlds, children, generated, dds_peer):
    """The IDL horus-gen writes for ImageDescriptor (the data in place of the block) is what the
    bridge sends: a program built with idlc from it gets the pixels."""
    source = worlds[0]
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    peer = children.start([dds_peer, "read-image", str(dds_domain), "3"])
    wait_line(peer, "ready")
    bridge(children, source, generated, dds_domain, "--export", "camera")
    out, errors = peer.communicate(timeout=60)
    assert peer.returncode == 0, errors
    made = {}
    exec(PIXELS, made)  # the publisher's pixels(i)
    for line in out.splitlines():
        fields = dict(field.split("=") for field in line.split())
        stamp = int(fields.pop("timestamp_ns"))
        assert fields == {"width": "8", "height": "6", "encoding": "2", "channels": "3",
                          "step": "24", "data_size": "144", "frame_id": "camera_link",
                          "data": made["pixels"](stamp).tobytes().hex()}, line


@pytest.mark.parametrize("exporter", ["c++", "python"])
def test_an_image_crosses_through_a_cpp_schedulers_bridge_with_its_pixels(
        dds_domain, worlds, children, generated, exporter):
    # The C++ bridge (bridges/dds/, in a C++ scheduler's process: network_peer.cpp) carries a
    # pool-backed topic as the Python one does: the importing program fills blocks of B's pool
    # from the frames of a C++ or a Python exporter (which reads A's blocks).
    from test_network_cpp import NETWORK_PEER
    source, target = worlds
    subscriber = children.python(SUBSCRIBER, python_env(target, generated))
    wait_line(subscriber, "ready")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    importing = children.start([NETWORK_PEER, "relay", str(dds_domain), "import", "camera"],
                               python_env(target, generated))
    wait_line(importing, "bridge on DDS domain")
    if exporter == "python":
        exporting = bridge(children, source, generated, dds_domain, "--export", "camera")
    else:
        exporting = children.start([NETWORK_PEER, "relay", str(dds_domain), "export", "camera"],
                                   python_env(source, generated))
    assert wait_line(exporting, "exporting") == (
        "exporting 'camera' (horus.msg.ImageDescriptor) as rt/camera "
        "(horus::msg::dds_::ImageDescriptor_)")
    out, errors = subscriber.communicate(timeout=90)
    assert subscriber.returncode == 0, errors
    lines = out.splitlines()
    own_pool = lines[-1].split()[1]
    images = [line.split() for line in lines[:-1]]
    assert len(images) == COUNT, out
    stamps = [int(image[0]) for image in images]
    assert stamps == list(range(stamps[0], stamps[0] + COUNT)), out
    assert all(image[1:] == ["True", "camera_link", "6x8x3", own_pool] for image in images), out
