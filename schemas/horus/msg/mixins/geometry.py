"""Helpers of the geometry messages (horus/msg/geometry.hmsg), mirroring the C++ mixins.

Each class is the base of the generated message of the same name without the `Mixin` suffix.
C++ spells the Rust `new(...)` constructors `make(...)` (`new` is a C++ keyword); Python keeps
`new(...)`. Factories leave timestamps at 0: the caller stamps a message when it sends it.
"""
import math

_TWO_PI = 2.0 * math.pi


def _finite(values) -> bool:
    return all(math.isfinite(float(v)) for v in values)


def quaternion_from_euler(roll: float, pitch: float, yaw: float) -> tuple:
    """(x, y, z, w) of R = Rz(yaw) * Ry(pitch) * Rx(roll), as Quaternion::from_euler in C++."""
    cr, sr = math.cos(roll / 2.0), math.sin(roll / 2.0)
    cp, sp = math.cos(pitch / 2.0), math.sin(pitch / 2.0)
    cy, sy = math.cos(yaw / 2.0), math.sin(yaw / 2.0)
    return (sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def normalize_angle(theta: float) -> float:
    """theta wrapped into [-pi, pi] by IEEE remainder (what std::remainder does in C++)."""
    return math.remainder(theta, _TWO_PI) if math.isfinite(theta) else theta


class CmdVelMixin:
    @classmethod
    def new(cls, linear: float, angular: float):
        """`linear` m/s forward, `angular` rad/s, unstamped."""
        return cls(linear=linear, angular=angular)

    @classmethod
    def zero(cls):
        """The stop command."""
        return cls()

    @classmethod
    def with_timestamp(cls, linear: float, angular: float, stamp_nanos: int):
        """A command stamped with `stamp_nanos` (nanoseconds since epoch)."""
        return cls(stamp_nanos=stamp_nanos, linear=linear, angular=angular)


class TwistMixin:
    @classmethod
    def new(cls, linear, angular):
        """`linear` [x, y, z] m/s and `angular` [roll, pitch, yaw] rad/s, unstamped."""
        return cls(linear=[float(v) for v in linear], angular=[float(v) for v in angular])

    @classmethod
    def new_2d(cls, linear_x: float, angular_z: float):
        """The planar twist: `linear_x` m/s forward, `angular_z` rad/s about +Z."""
        return cls.new([linear_x, 0.0, 0.0], [0.0, 0.0, angular_z])

    @classmethod
    def stop(cls):
        """All velocities zero."""
        return cls()

    def is_valid(self) -> bool:
        """True when every velocity component is finite."""
        return _finite(self.linear) and _finite(self.angular)


class Pose2DMixin:
    @classmethod
    def new(cls, x: float, y: float, theta: float):
        """The pose (`x` m, `y` m, `theta` rad), unstamped."""
        return cls(x=x, y=y, theta=theta)

    @classmethod
    def origin(cls):
        """The pose at the origin, heading along +X."""
        return cls()

    def distance_to(self, other) -> float:
        """Euclidean distance in metres between the positions."""
        return math.hypot(self.x - other.x, self.y - other.y)

    def normalize_angle(self) -> None:
        """Wraps theta into [-pi, pi]; a non-finite theta is left as it is."""
        self.theta = normalize_angle(float(self.theta))

    def is_valid(self) -> bool:
        """True when x, y and theta are finite."""
        return _finite((self.x, self.y, self.theta))


class TransformStampedMixin:
    @classmethod
    def new(cls, translation, rotation):
        """`translation` [x, y, z] m and `rotation` quaternion [x, y, z, w], unstamped."""
        return cls(translation=[float(v) for v in translation],
                   rotation=[float(v) for v in rotation])

    @classmethod
    def identity(cls):
        """No translation, identity rotation."""
        return cls.new([0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])

    @classmethod
    def from_pose_2d(cls, pose):
        """The planar transform of a Pose2D (z = 0, yaw only), keeping its timestamp."""
        half = pose.theta / 2.0
        return cls(translation=[pose.x, pose.y, 0.0],
                   rotation=[0.0, 0.0, math.sin(half), math.cos(half)],
                   timestamp_ns=pose.timestamp_ns)

    def normalize_rotation(self) -> None:
        """Scales the rotation to unit length; a zero or non-finite one is left unchanged."""
        norm = math.sqrt(sum(float(v) * float(v) for v in self.rotation))
        if norm > 0.0 and math.isfinite(norm):
            self.rotation = [float(v) / norm for v in self.rotation]

    def is_valid(self) -> bool:
        """Every value finite and the rotation of unit norm (within 0.01)."""
        if not (_finite(self.translation) and _finite(self.rotation)):
            return False
        return abs(math.sqrt(sum(float(v) * float(v) for v in self.rotation)) - 1.0) < 0.01


class Point3Mixin:
    @classmethod
    def new(cls, x: float, y: float, z: float):
        """The point (x, y, z) in metres."""
        return cls(x=x, y=y, z=z)

    @classmethod
    def origin(cls):
        """The origin."""
        return cls()

    def distance_to(self, other) -> float:
        """Euclidean distance in metres."""
        dx, dy, dz = self.x - other.x, self.y - other.y, self.z - other.z
        return math.sqrt(dx * dx + dy * dy + dz * dz)


class Vector3Mixin:
    @classmethod
    def new(cls, x: float, y: float, z: float):
        """The vector (x, y, z)."""
        return cls(x=x, y=y, z=z)

    @classmethod
    def zero(cls):
        """The zero vector."""
        return cls()

    def magnitude(self) -> float:
        """Euclidean length."""
        return math.sqrt(self.x * self.x + self.y * self.y + self.z * self.z)

    def normalize(self) -> None:
        """Scales to unit length; the zero vector is left unchanged."""
        m = self.magnitude()
        if m > 0.0:
            self.x, self.y, self.z = self.x / m, self.y / m, self.z / m

    def normalized(self):
        """A unit-length copy; the zero vector for the zero vector."""
        copy = type(self)(x=self.x, y=self.y, z=self.z)
        copy.normalize()
        return copy

    def dot(self, other) -> float:
        """Dot product."""
        return self.x * other.x + self.y * other.y + self.z * other.z

    def cross(self, other):
        """Cross product (right-handed): self x other."""
        return type(self)(x=self.y * other.z - self.z * other.y,
                          y=self.z * other.x - self.x * other.z,
                          z=self.x * other.y - self.y * other.x)


class QuaternionMixin:
    @classmethod
    def new(cls, x: float, y: float, z: float, w: float):
        """The quaternion (x, y, z, w), taken as given."""
        return cls(x=x, y=y, z=z, w=w)

    @classmethod
    def identity(cls):
        """No rotation."""
        return cls(x=0.0, y=0.0, z=0.0, w=1.0)

    @classmethod
    def from_euler(cls, roll: float, pitch: float, yaw: float):
        """Roll about X, then pitch about Y, then yaw about Z (radians)."""
        x, y, z, w = quaternion_from_euler(roll, pitch, yaw)
        return cls(x=x, y=y, z=z, w=w)

    def normalize(self) -> None:
        """Scales to unit norm; a zero or non-finite quaternion is left unchanged."""
        norm = math.sqrt(self.x * self.x + self.y * self.y + self.z * self.z + self.w * self.w)
        if norm > 0.0 and math.isfinite(norm):
            self.x, self.y, self.z, self.w = (self.x / norm, self.y / norm, self.z / norm,
                                              self.w / norm)

    def is_valid(self) -> bool:
        """True when all four components are finite."""
        return _finite((self.x, self.y, self.z, self.w))


class Pose3DMixin:
    @classmethod
    def new(cls, position, orientation):
        """The pose at `position` (Point3) with `orientation` (Quaternion), unstamped."""
        return cls(position=position, orientation=orientation)

    @classmethod
    def identity(cls):
        """At the origin, no rotation."""
        return cls()

    @classmethod
    def from_pose_2d(cls, pose):
        """The 3D pose of a Pose2D (z = 0, yaw only), keeping its timestamp."""
        half = pose.theta / 2.0
        result = cls(timestamp_ns=pose.timestamp_ns)
        result.position.x, result.position.y, result.position.z = pose.x, pose.y, 0.0
        o = result.orientation
        o.x, o.y, o.z, o.w = 0.0, 0.0, math.sin(half), math.cos(half)
        return result

    def distance_to(self, other) -> float:
        """Euclidean distance in metres between the positions."""
        return self.position.distance_to(other.position)

    def is_valid(self) -> bool:
        """True when the position and orientation are finite."""
        p = self.position
        return _finite((p.x, p.y, p.z)) and self.orientation.is_valid()
