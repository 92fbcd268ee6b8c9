"""Helpers of the sensor messages (horus/msg/sensor.hmsg), mirroring the C++ mixins.

f32 fields are computed on in float32 (numpy) so that results equal the C++ ones bit for bit.
"""
import math

# horus-gen copies each #[py_mixin] file into the package as _mixin_<file name>.py, so the geometry
# helpers sit beside this module (the standard library is always generated as one package).
from ._mixin_geometry import quaternion_from_euler


def _np():
    """numpy, imported on first use so that importing the message package stays fast."""
    import numpy
    return numpy




def _f32(value):
    """`value` rounded to float32, as the C++ helpers compute."""
    return _np().float32(value)




def _check_name(owner: str, what: str, text: str, capacity: int = 32) -> None:
    if len(text.encode()) > capacity:
        raise ValueError(f"{owner}: {what} '{text}' is longer than {capacity} bytes")


class LaserScanMixin:
    def _valid_mask(self):
        r = _np().asarray(self.ranges, dtype=_np().float32)
        return _np().isfinite(r) & (r >= _f32(self.range_min)) & (r <= _f32(self.range_max)), r

    def angle_at(self, index: int) -> float:
        """angle_min + index * angle_increment in radians (float32); NaN past the 360 readings."""
        if index < 0 or index >= len(self.ranges):
            return math.nan
        return float(_f32(self.angle_min) + _f32(index) * _f32(self.angle_increment))

    def is_range_valid(self, index: int) -> bool:
        """True when reading `index` exists, is finite and within [range_min, range_max]."""
        if index < 0 or index >= len(self.ranges):
            return False
        return bool(self._valid_mask()[0][index])

    def valid_count(self) -> int:
        """The number of valid readings."""
        return int(_np().count_nonzero(self._valid_mask()[0]))

    def min_range(self):
        """The closest valid reading in metres, or None when none is valid."""
        mask, r = self._valid_mask()
        return float(r[mask].min()) if mask.any() else None


class ImuMixin:
    @classmethod
    def new(cls):
        """No orientation: identity quaternion, orientation_covariance all -1."""
        return cls(orientation=[0.0, 0.0, 0.0, 1.0], orientation_covariance=[-1.0] * 9)

    def set_orientation_from_euler(self, roll: float, pitch: float, yaw: float) -> None:
        """Orientation from roll/pitch/yaw (rad); a "no estimate" covariance becomes all zeros."""
        self.orientation = list(quaternion_from_euler(roll, pitch, yaw))
        if float(self.orientation_covariance[0]) < 0.0:
            self.orientation_covariance = [0.0] * 9

    def has_orientation(self) -> bool:
        """True unless orientation_covariance[0] < 0."""
        return float(self.orientation_covariance[0]) >= 0.0

    def is_valid(self) -> bool:
        """True when orientation, angular velocity and linear acceleration are finite."""
        return all(math.isfinite(float(v)) for v in
                   [*self.orientation, *self.angular_velocity, *self.linear_acceleration])


class OdometryMixin:
    @classmethod
    def new(cls):
        """At the origin, not moving, no frames."""
        return cls()

    def set_frames(self, frame: str, child_frame: str) -> None:
        """Names the pose and twist frames; ValueError (nothing changed) past 32 bytes."""
        if len(frame.encode()) > 32 or len(child_frame.encode()) > 32:
            raise ValueError("Odometry::set_frames: frame names are at most 32 bytes, got "
                             f"'{frame}' and '{child_frame}'")
        self.frame_id = frame
        self.child_frame_id = child_frame

    def update(self, pose, twist) -> None:
        """Takes a new estimate, stamped with the later of the two inputs' stamps."""
        self.pose = pose
        self.twist = twist
        self.timestamp_ns = max(pose.timestamp_ns, twist.timestamp_ns)

    def is_valid(self) -> bool:
        """True when the pose and the twist are finite."""
        return self.pose.is_valid() and self.twist.is_valid()


class RangeMixin:
    @classmethod
    def new(cls, sensor_type: int, range: float):  # noqa: A002 (the field's name)
        """A reading with typical limits: 0.1 rad field of view, 0.02-4.0 m."""
        return cls(sensor_type=sensor_type, field_of_view=0.1, min_range=0.02, max_range=4.0,
                   range=range)

    def is_valid(self) -> bool:
        """True when the reading is finite and within [min_range, max_range]."""
        r = _f32(self.range)
        return bool(_np().isfinite(r) and _f32(self.min_range) <= r <= _f32(self.max_range))


class BatteryStateMixin:
    @classmethod
    def new(cls, voltage: float, percentage: float):
        """A reading with charge, capacity and temperature unknown (NaN)."""
        return cls(voltage=voltage, percentage=percentage, charge=math.nan, capacity=math.nan,
                   temperature=math.nan)

    def is_low(self, threshold_percent: float) -> bool:
        """True when the charge is below `threshold_percent`."""
        return bool(_f32(self.percentage) < _f32(threshold_percent))

    def is_critical(self) -> bool:
        """True below 10 % charge."""
        return bool(_f32(self.percentage) < _f32(10.0))

    def time_remaining(self):
        """Seconds until empty at the present discharge current, or None when not
        discharging or when the charge is unknown."""
        current, charge = _f32(self.current), _f32(self.charge)
        if not (current < _f32(-1e-9)) or not _np().isfinite(charge):
            return None
        return float(charge / -current * _f32(3600.0))


class NavSatFixMixin:
    @classmethod
    def from_coordinates(cls, latitude: float, longitude: float, altitude: float):
        """A fix (STATUS_FIX) at the given WGS84 coordinates."""
        return cls(latitude=latitude, longitude=longitude, altitude=altitude,
                   status=cls.STATUS_FIX)

    def has_fix(self) -> bool:
        """True for any fix status."""
        return self.status >= self.STATUS_FIX

    def is_valid(self) -> bool:
        """Finite coordinates, latitude in [-90, 90], longitude in [-180, 180]."""
        return (all(math.isfinite(v) for v in (self.latitude, self.longitude, self.altitude))
                and -90.0 <= self.latitude <= 90.0 and -180.0 <= self.longitude <= 180.0)

    def horizontal_accuracy(self) -> float:
        """HDOP times a 5 m user range error, in metres."""
        return float(_f32(self.hdop) * _f32(5.0))

    def distance_to(self, other) -> float:
        """Great-circle distance in metres (haversine, mean Earth radius 6371 km)."""
        to_rad = math.pi / 180.0
        lat1, lat2 = self.latitude * to_rad, other.latitude * to_rad
        dlat = (other.latitude - self.latitude) * to_rad
        dlon = (other.longitude - self.longitude) * to_rad
        a = (math.sin(dlat / 2.0) * math.sin(dlat / 2.0)
             + math.cos(lat1) * math.cos(lat2) * math.sin(dlon / 2.0) * math.sin(dlon / 2.0))
        return 2.0 * 6371000.0 * math.atan2(math.sqrt(a), math.sqrt(1.0 - a))


class JointStateMixin:
    def add_joint(self, name: str, position: float, velocity: float, effort: float) -> bool:
        """Appends a joint; False when full; ValueError when `name` is over 32 bytes."""
        if self.joint_count >= self.MAX_JOINTS:
            return False
        _check_name("JointState::add_joint", "joint name", name)
        i = self.joint_count
        self.names[i] = name
        self.positions[i] = position
        self.velocities[i] = velocity
        self.efforts[i] = effort
        self.joint_count = i + 1
        return True

    def index_of(self, name: str):
        """The index of joint `name` among the valid joints, or None."""
        for i in range(min(self.joint_count, self.MAX_JOINTS)):
            if self.names[i] == name:
                return i
        return None

    def position_of(self, name: str):
        """The position of joint `name`, or None."""
        i = self.index_of(name)
        return None if i is None else float(self.positions[i])
