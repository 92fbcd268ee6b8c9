"""The tensor pool from Python: Image, DepthImage and PointCloud exchanged with a C++ process both
ways (1080p RGB, 720p depth in metres and in millimetres, a million points), values equal and the
receiver's array inside the pool, read_latest() the same frame; numpy and DLPack views without
copies, read-only when received; references back to zero."""
from __future__ import annotations

import ctypes
import os
import stat
import subprocess
import time

import numpy as np
import pytest

import horus

POOL_PEER = os.environ.get("HORUS_PY_POOL_PEER", "")


@pytest.fixture(autouse=True)
def pools(namespace):
    yield
    horus._core.remove_pools(namespace)


def image_bytes() -> np.ndarray:
    index = np.arange(1080 * 1920 * 3, dtype=np.uint64)
    return ((index * 7 + index // 4099) & 0xFF).astype(np.uint8).reshape(1080, 1920, 3)


def depth_meters() -> np.ndarray:
    y, x = np.mgrid[0:720, 0:1280]
    return (np.float32(0.25) + x.astype(np.float32) * np.float32(0.001)
            + y.astype(np.float32) * np.float32(0.0001))


def depth_millimeters() -> np.ndarray:
    y, x = np.mgrid[0:720, 0:1280]
    return (300 + x + 2 * y).astype(np.uint16)


def cloud_points() -> np.ndarray:
    index = np.arange(1_000_000)
    return np.stack([index.astype(np.float32), index.astype(np.float32) * np.float32(0.5),
                     -(index % 1000).astype(np.float32)], axis=1)


def pool_peer(*args: str) -> subprocess.Popen:
    assert POOL_PEER, "HORUS_PY_POOL_PEER names the C++ peer; run this suite through ctest"
    return subprocess.Popen([POOL_PEER, *args], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def tell(proc: subprocess.Popen, line: str) -> None:
    proc.stdin.write(line + "\n")
    proc.stdin.flush()


KINDS = {
    "image": (horus.Image, image_bytes, lambda a: horus.Image.from_numpy(a)),
    "depth": (horus.DepthImage, depth_meters, lambda a: horus.DepthImage.from_numpy(a)),
    "depth_mm": (horus.DepthImage, depth_millimeters, lambda a: horus.DepthImage.from_numpy(a)),
    "cloud": (horus.PointCloud, cloud_points, lambda a: horus.PointCloud.from_numpy(a)),
}


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_cpp_sends_python_reads_in_place(kind):
    value_type, expected, _ = KINDS[kind]
    proc = pool_peer("send", kind, "xpool")
    try:
        assert proc.stdout.readline().strip() == "open"
        topic = horus.Topic(value_type, "xpool")
        tell(proc, "ready")
        value = topic.recv(30.0)
        assert value is not None
        assert not value.writable
        array = np.asarray(value)
        assert not array.flags.writeable
        assert value.pool.contains(array.ctypes.data)
        assert array.ctypes.data == value.data_address
        np.testing.assert_array_equal(array, expected())
        if kind == "image":
            assert value.frame_id == "cpp"
        if kind.startswith("depth"):
            assert value.is_millimeters() == (kind == "depth_mm")
        latest = topic.read_latest()
        assert latest is not None and latest.data_address == value.data_address
        with pytest.raises(ValueError):
            array.flat[0] = 1
        tell(proc, "done")
        assert proc.wait(timeout=30) == 0, proc.stderr.read()
    finally:
        proc.kill()
        proc.wait()


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_python_sends_cpp_reads_in_place(kind):
    value_type, values, make = KINDS[kind]
    topic = horus.Topic(value_type, "xpool")
    value = make(values())
    if kind == "image":
        value.frame_id = "python"
    proc = pool_peer("recv", kind, "xpool")
    try:
        assert proc.stdout.readline().strip() == "ready"
        assert topic.send(value)
        assert proc.wait(timeout=60) == 0, proc.stderr.read()
    finally:
        proc.kill()
        proc.wait()
    block = value.block
    pool = value.pool
    del value
    del topic
    assert pool.references(block) == 0
    assert pool.stats()["blocks_in_use"] == 0


NODE_FRAMES = 3  # fewer than a pool topic's 4 slots: the sender keeps every frame alive


def test_a_cpp_node_sends_images_to_a_python_node_and_its_references_return_to_zero():
    expected = image_bytes()
    seen = []

    def view(node):
        while (image := node.recv("camera")) is not None:
            array = np.asarray(image)
            seen.append((image.timestamp_ns, image.frame_id, not image.writable,
                         image.pool.contains(array.ctypes.data),
                         bool(np.array_equal(array, expected))))

    viewer = horus.Node(name="py_viewer", tick=view, subs={"camera": horus.Image})
    scheduler = horus.Scheduler(tick_rate=1000)
    scheduler.add(viewer)
    proc = pool_peer("node-send", "image", "camera", str(NODE_FRAMES))
    try:
        assert proc.stdout.readline().strip() == "open"
        scheduler.tick_once()  # opens the subscription before the C++ node starts sending
        tell(proc, "ready")
        deadline = time.monotonic() + 30
        while len(seen) < NODE_FRAMES and time.monotonic() < deadline:
            scheduler.tick_once()
            time.sleep(0.001)
        del scheduler, viewer
        tell(proc, "done")
        out, err = proc.communicate(timeout=30)
        assert proc.returncode == 0, err
    finally:
        proc.kill()
        proc.wait()
    assert seen == [(i, "cpp", True, True, True) for i in range(1, NODE_FRAMES + 1)]
    assert out.split() == ["references", "0"]


def test_a_python_node_sends_images_to_a_cpp_node():
    pixels = image_bytes()
    sent = []

    def film(node):
        if len(sent) < NODE_FRAMES:
            image = horus.Image.from_numpy(pixels)
            image.frame_id = "python"
            image.timestamp_ns = len(sent) + 1
            assert node.send("camera", image)
            sent.append(image.block)

    camera = horus.Node(name="py_camera", tick=film, pubs={"camera": horus.Image})
    scheduler = horus.Scheduler(tick_rate=1000)
    scheduler.add(camera)
    proc = pool_peer("node-recv", "image", "camera", str(NODE_FRAMES))
    try:
        assert proc.stdout.readline().strip() == "ready"
        for _ in range(NODE_FRAMES):
            scheduler.tick_once()
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 0, err
    finally:
        proc.kill()
        proc.wait()
    assert out.split() == [str(i) for i in range(1, NODE_FRAMES + 1)]
    pool = horus.TensorPool.default()
    del scheduler, camera
    assert [pool.references(block) for block in sent] == [0] * NODE_FRAMES
    assert pool.stats()["blocks_in_use"] == 0


def test_numpy_and_dlpack_views_share_the_pool_memory():
    image = horus.Image(480, 640, horus.ImageEncoding.Rgb8)
    array = np.asarray(image)
    assert array.shape == (480, 640, 3) and array.dtype == np.uint8
    assert array.flags.writeable
    array[10, 20] = (1, 2, 3)
    assert image.pixel(20, 10) == bytes([1, 2, 3])
    dl = np.from_dlpack(image)
    assert dl.ctypes.data == array.ctypes.data
    pool = image.pool
    assert pool.references(image.block) == 2  # the image and the DLPack export
    del dl
    assert pool.references(image.block) == 1

    depth = horus.DepthImage.millimeters(4, 5)
    assert np.asarray(depth).dtype == np.uint16 and np.asarray(depth).shape == (4, 5)
    tensor = horus.Tensor.from_numpy(np.arange(24, dtype=np.int64).reshape(2, 3, 4))
    assert tensor.shape == [2, 3, 4] and tensor.strides == [96, 32, 8]
    np.testing.assert_array_equal(np.asarray(tensor), np.arange(24).reshape(2, 3, 4))
    assert "Tensor([2, 3, 4] I64" in repr(tensor)


_capsule_name = ctypes.pythonapi.PyCapsule_GetName
_capsule_name.restype, _capsule_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
_capsule_pointer = ctypes.pythonapi.PyCapsule_GetPointer
_capsule_pointer.restype = ctypes.c_void_p
_capsule_pointer.argtypes = [ctypes.py_object, ctypes.c_char_p]


class _DLPackVersion(ctypes.Structure):
    _fields_ = [("major", ctypes.c_uint32), ("minor", ctypes.c_uint32)]


class _DLManagedTensorVersionedHead(ctypes.Structure):
    """DLPack 1.0's DLManagedTensorVersioned up to its flags (dl_tensor follows)."""
    _fields_ = [("version", _DLPackVersion), ("manager_ctx", ctypes.c_void_p),
                ("deleter", ctypes.c_void_p), ("flags", ctypes.c_uint64)]


DLPACK_FLAG_BITMASK_READ_ONLY = 1


def dlpack_export(value, **kwargs):
    """(capsule name, DLPack version, flags) of value.__dlpack__(**kwargs)."""
    capsule = value.__dlpack__(**kwargs)
    name = _capsule_name(capsule)
    if name != b"dltensor_versioned":
        return name, None, None
    head = _DLManagedTensorVersionedHead.from_address(_capsule_pointer(capsule, name))
    return name, (head.version.major, head.version.minor), head.flags


def test_dlpack_versioned_capsule_says_read_only_for_a_received_value():
    publisher = horus.Topic(horus.Image, "frames")
    subscriber = horus.Topic(horus.Image, "frames")
    own = horus.Image.from_numpy(image_bytes())
    assert publisher.send(own)
    received = subscriber.recv(1.0)
    assert received is not None and not received.writable
    pool = own.pool

    assert dlpack_export(own, max_version=(1, 0)) == (b"dltensor_versioned", (1, 0), 0)
    assert dlpack_export(received, max_version=(1, 0)) == (
        b"dltensor_versioned", (1, 0), DLPACK_FLAG_BITMASK_READ_ONLY)
    assert dlpack_export(received, max_version=(1, 3))[0] == b"dltensor_versioned"
    # A consumer that does not say, or knows only 0.x, gets the unversioned capsule.
    assert dlpack_export(received) == (b"dltensor", None, None)
    assert dlpack_export(received, max_version=(0, 8)) == (b"dltensor", None, None)
    assert dlpack_export(own, stream=None, dl_device=(1, 0), copy=False)[0] == b"dltensor"
    with pytest.raises(BufferError, match="copy"):
        own.__dlpack__(copy=True)
    with pytest.raises(BufferError, match="device"):
        own.__dlpack__(max_version=(1, 0), dl_device=(2, 0))
    # Unconsumed capsules gave their references back.
    del publisher
    assert pool.references(own.block) == 2  # `own` and `received`
    del received, subscriber
    assert pool.references(own.block) == 1


def test_from_numpy_refuses_what_has_no_encoding():
    with pytest.raises(horus.HorusError, match="no encoding"):
        horus.Image.from_numpy(np.zeros((4, 4, 2), dtype=np.float64))
    with pytest.raises(horus.HorusError, match="float32"):
        horus.DepthImage.from_numpy(np.zeros((4, 4), dtype=np.uint8))


def test_a_received_value_is_read_only_and_the_tensor_topic_works_in_process():
    publisher = horus.Topic(horus.Tensor, "tensors")
    subscriber = horus.Topic(horus.Tensor, "tensors")
    sent = horus.Tensor.from_numpy(np.ones((3, 3), dtype=np.float32))
    assert publisher.send(sent)
    got = subscriber.recv(1.0)
    assert got is not None and not got.writable
    assert got.data_address == sent.data_address
    with pytest.raises(horus.HorusError, match="read-only"):
        got.copy_from(bytes(36))
    assert subscriber.try_recv() is None
    assert subscriber.recv(0.001) is None
    with pytest.raises(TypeError):
        publisher.send(horus.Image(2, 2, horus.ImageEncoding.Mono8))


def test_point_cloud_from_xyz_xyzi_xyzrgb_and_extract_xyz():
    xyz = np.array([[1.0, 2.0, 3.0], [-4.5, 0.25, 1e6]])  # float64: converted to float32
    cloud = horus.PointCloud.from_xyz(xyz)
    assert (cloud.point_count, cloud.fields_per_point, cloud.dtype) == (2, 3, horus.TensorDtype.F32)
    assert cloud.is_xyz() and not cloud.has_intensity() and not cloud.has_color()
    np.testing.assert_array_equal(np.asarray(cloud), xyz.astype(np.float32))
    extracted = cloud.extract_xyz()
    assert extracted.dtype == np.float32 and extracted.shape == (2, 3)
    assert extracted.ctypes.data != cloud.data_address  # a copy, not a view of the pool
    np.testing.assert_array_equal(extracted, xyz.astype(np.float32))

    from_tuples = horus.PointCloud.from_xyz([(1, 2, 3), (4, 5, 6), (7, 8, 9)])
    np.testing.assert_array_equal(from_tuples.extract_xyz(),
                                  np.arange(1, 10, dtype=np.float32).reshape(3, 3))

    xyzi = np.arange(20, dtype=np.float32).reshape(5, 4)
    with_intensity = horus.PointCloud.from_xyzi(xyzi)
    assert with_intensity.has_intensity() and with_intensity.fields_per_point == 4
    np.testing.assert_array_equal(np.asarray(with_intensity), xyzi)
    np.testing.assert_array_equal(with_intensity.extract_xyz(), xyzi[:, :3])

    xyzrgb = [(0.5, 1.5, 2.5, 255, 128, 0), (3.0, 4.0, 5.0, 0, 64, 255)]
    colored = horus.PointCloud.from_xyzrgb(xyzrgb)
    assert colored.has_color() and colored.point_count == 2
    assert colored.point_at(1) == np.array(xyzrgb[1], dtype=np.float32).tobytes()
    np.testing.assert_array_equal(colored.extract_xyz(), np.array(xyzrgb, np.float32)[:, :3])


def test_point_cloud_constructors_refuse_the_wrong_shape_and_extract_xyz_needs_float32():
    with pytest.raises(horus.HorusError, match=r"from_xyz: points have shape \(n, 3\)"):
        horus.PointCloud.from_xyz(np.zeros((4, 4), dtype=np.float32))
    with pytest.raises(horus.HorusError, match=r"from_xyzi: points have shape \(n, 4\)"):
        horus.PointCloud.from_xyzi([(1.0, 2.0, 3.0)])
    with pytest.raises(horus.HorusError, match=r"from_xyzrgb: points have shape \(n, 6\)"):
        horus.PointCloud.from_xyzrgb(np.zeros(6, dtype=np.float32))
    with pytest.raises(ValueError):
        horus.PointCloud.from_xyz([("a", "b", "c")])
    assert horus.PointCloud.from_numpy(np.zeros((3, 3), dtype=np.uint8)).extract_xyz() is None
    assert horus.PointCloud.from_numpy(np.zeros((3, 2), dtype=np.float32)).extract_xyz() is None


def test_the_pool_file_is_mode_0600_whatever_the_umask(namespace):
    previous = os.umask(0)
    try:
        image = horus.Image(2, 2, horus.ImageEncoding.Mono8)  # creates the namespace's default pool
        named = horus.TensorPool.open("modes", block_size=4096, block_count=2)
    finally:
        os.umask(previous)
    root = os.path.dirname(horus._core.namespace_directory(namespace))
    folder = os.path.join(root, "@pool", namespace)
    for name in ("default", "modes"):
        status = os.stat(os.path.join(folder, name))
        assert (oct(stat.S_IMODE(status.st_mode)), status.st_uid) == (oct(0o600), os.geteuid())
    assert oct(stat.S_IMODE(os.stat(folder).st_mode)) == oct(0o700)
    del image, named
