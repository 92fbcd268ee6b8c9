"""Helpers of the navigation messages (horus/msg/navigation.hmsg), mirroring the C++ mixins.

Grid lookups convert the f32 resolution to float32 first, as C++ holds it, so that both
languages pick the same cell. CostMap inflation computes squared cell distances exactly
(integers) and the decay with the same libm calls as C++, so the costs are identical.
"""
import copy as _copy
import math



def _np():
    """numpy, imported on first use so that importing the message package stays fast."""
    import numpy
    return numpy


_TWO_PI = 2.0 * math.pi


def _resolution(grid) -> float:
    return float(_np().float32(grid.resolution))


class GoalMixin:
    @classmethod
    def new(cls, target_pose, position_tolerance: float, angle_tolerance: float):
        """A goal at `target_pose` with tolerances (m, rad); no timeout, priority 1."""
        return cls(target_pose=target_pose, tolerance_position=position_tolerance,
                   tolerance_angle=angle_tolerance, priority=1)

    def with_timeout(self, timeout_seconds: float):
        """A copy with a timeout in seconds (0: no limit)."""
        copy = _copy.deepcopy(self)
        copy.timeout_seconds = float(timeout_seconds)
        return copy

    def with_priority(self, priority: int):
        """A copy with `priority` (0 = highest)."""
        copy = _copy.deepcopy(self)
        copy.priority = priority
        return copy

    def is_position_reached(self, current) -> bool:
        """Within tolerance_position metres of the target."""
        return self.target_pose.distance_to(current) <= self.tolerance_position

    def is_orientation_reached(self, current) -> bool:
        """Heading within tolerance_angle of the target's, the short way round."""
        diff = math.remainder(self.target_pose.theta - current.theta, _TWO_PI)
        return abs(diff) <= self.tolerance_angle

    def is_reached(self, current) -> bool:
        """Position and orientation within tolerance."""
        return self.is_position_reached(current) and self.is_orientation_reached(current)


class GoalResultMixin:
    @classmethod
    def new(cls, goal_id: int, status):
        """The result of goal `goal_id` with `status` (a GoalStatus)."""
        return cls(goal_id=goal_id, status=int(status))

    def with_error(self, message: str):
        """A copy with `message`, cut to 64 bytes at a UTF-8 character boundary."""
        raw = message.encode()
        n = min(len(raw), 64)
        while 0 < n < len(raw) and (raw[n] & 0xC0) == 0x80:
            n -= 1
        copy = _copy.deepcopy(self)
        copy.error_message = raw[:n].decode()
        return copy


class WaypointMixin:
    @classmethod
    def new(cls, pose):
        """A waypoint at `pose`, zero velocity, no stop."""
        return cls(pose=pose)

    def with_velocity(self, velocity):
        """A copy with the desired velocity (a Twist)."""
        copy = _copy.deepcopy(self)
        copy.velocity = velocity
        return copy

    def with_stop(self):
        """A copy that requires a stop here (stop_required = 1, zero velocity)."""
        copy = _copy.deepcopy(self)
        copy.stop_required = 1
        copy.velocity = type(self.velocity)()
        return copy


class PathMixin:
    def add_waypoint(self, waypoint) -> bool:
        """Appends and extends total_length; False (unchanged) when full."""
        n = self.waypoint_count
        if n >= self.MAX_WAYPOINTS:
            return False
        self.waypoints[n] = waypoint
        if n > 0:
            self.total_length += self.waypoints[n - 1].pose.distance_to(waypoint.pose)
        self.waypoint_count = n + 1
        return True

    def closest_waypoint_index(self, current):
        """Index of the valid waypoint closest to `current` (first of equals), or None."""
        best, best_distance = None, 0.0
        for i in range(min(self.waypoint_count, self.MAX_WAYPOINTS)):
            d = current.distance_to(self.waypoints[i].pose)
            if best is None or d < best_distance:
                best, best_distance = i, d
        return best


class PathPlanMixin:
    def add_waypoint(self, x: float, y: float, theta: float) -> bool:
        """Appends (x m, y m, theta rad); False (unchanged) when full."""
        n = self.waypoint_count
        if n >= self.MAX_WAYPOINTS:
            return False
        self.waypoint_data[3 * n:3 * n + 3] = [x, y, theta]
        self.waypoint_count = n + 1
        return True

    def waypoint(self, index: int):
        """Waypoint `index` as (x, y, theta) floats, or None past the valid ones."""
        if index < 0 or index >= min(self.waypoint_count, self.MAX_WAYPOINTS):
            return None
        return tuple(float(_np().float32(v)) for v in self.waypoint_data[3 * index:3 * index + 3])

    def is_empty(self) -> bool:
        """True when the plan has no waypoint."""
        return self.waypoint_count == 0


class OccupancyGridMixin:
    @classmethod
    def new(cls, width: int, height: int, resolution: float, origin):
        """A width x height grid of `resolution` m cells, every cell UNKNOWN."""
        return cls(width=width, height=height, resolution=resolution, origin=origin,
                   data=[cls.UNKNOWN] * (width * height))

    def world_to_grid(self, x: float, y: float):
        """The cell (gx, gy) containing world point (x, y), or None (off the map, non-finite
        point, resolution not positive)."""
        res = _resolution(self)
        if not res > 0.0:
            return None
        fx = (x - self.origin.x) / res + 1e-6
        fy = (y - self.origin.y) / res + 1e-6
        if not (math.isfinite(fx) and math.isfinite(fy)):
            return None
        gx, gy = math.floor(fx), math.floor(fy)
        if 0 <= gx < self.width and 0 <= gy < self.height:
            return gx, gy
        return None

    def grid_to_world(self, gx: int, gy: int):
        """The world point at the centre of cell (gx, gy), or None off the grid."""
        if not (0 <= gx < self.width and 0 <= gy < self.height):
            return None
        res = _resolution(self)
        return self.origin.x + (gx + 0.5) * res, self.origin.y + (gy + 0.5) * res

    def occupancy(self, gx: int, gy: int):
        """The value of cell (gx, gy), or None off the grid."""
        if not (0 <= gx < self.width and 0 <= gy < self.height):
            return None
        index = gy * self.width + gx
        return int(self.data[index]) if index < len(self.data) else None

    def set_occupancy(self, gx: int, gy: int, value: int) -> bool:
        """Sets cell (gx, gy) to `value` clamped to [-1, 100]; False off the grid."""
        if not (0 <= gx < self.width and 0 <= gy < self.height):
            return False
        index = gy * self.width + gx
        if index >= len(self.data):
            return False
        self.data[index] = max(self.UNKNOWN, min(self.OCCUPIED, int(value)))
        return True

    def is_free(self, x: float, y: float) -> bool:
        """A known cell below 50 % occupancy."""
        cell = self.world_to_grid(x, y)
        value = None if cell is None else self.occupancy(*cell)
        return value is not None and 0 <= value < 50

    def is_occupied(self, x: float, y: float) -> bool:
        """A cell of at least 50 % occupancy."""
        cell = self.world_to_grid(x, y)
        value = None if cell is None else self.occupancy(*cell)
        return value is not None and value >= 50


class CostMapMixin:
    @classmethod
    def from_occupancy_grid(cls, grid, inflation_radius: float):
        """The cost map of `grid` with obstacles inflated by `inflation_radius` metres."""
        costmap = cls(occupancy_grid=grid, inflation_radius=inflation_radius)
        costmap.compute_costs()
        return costmap

    def compute_costs(self) -> None:
        """Recomputes costs from occupancy_grid (rules in the C++ mixin, cost_map.hpp)."""
        grid = self.occupancy_grid
        width, height = int(grid.width), int(grid.height)
        lethal = int(self.lethal_cost)
        size = width * height
        occ = _np().full(size, -1, dtype=_np().int64)
        data = _np().asarray(list(grid.data)[:size], dtype=_np().int64)
        occ[:len(data)] = data
        costs = _np().where(occ < 0, 255, _np().where(occ >= 65, lethal, occ * 2)).astype(_np().int64)
        res = _resolution(grid)
        radius = float(_np().float32(self.inflation_radius))
        if res > 0.0 and radius > 0.0 and math.isfinite(radius) and size > 0:
            reach = int(min(math.ceil(radius / res), max(width, height)))
            obstacle = (costs >= lethal).reshape(height, width)
            nearest = _np().full((height, width), -1, dtype=_np().int64)
            for dy in range(-reach, reach + 1):
                for dx in range(-reach, reach + 1):
                    # cells (y, x) whose neighbour (y - dy, x - dx) is an obstacle
                    src = obstacle[max(0, -dy):height - max(0, dy), max(0, -dx):width - max(0, dx)]
                    if src.size == 0 or not src.any():
                        continue
                    dst = nearest[max(0, dy):height - max(0, -dy), max(0, dx):width - max(0, -dx)]
                    d2 = dx * dx + dy * dy
                    update = src & ((dst < 0) | (d2 < dst))
                    dst[update] = d2
            nearest = nearest.reshape(size)
            top = float(lethal) - 1.0
            scaling = float(_np().float32(self.cost_scaling_factor))
            decay = {}
            for d2 in _np().unique(nearest[nearest >= 0]).tolist():
                distance = math.sqrt(float(d2)) * res
                if distance > radius:
                    continue
                inflated = min(top * math.pow(1.0 - distance / radius, scaling), top)
                decay[d2] = int(inflated) if inflated > 0.0 else 0
            for i in _np().nonzero((nearest >= 0) & (costs < lethal))[0].tolist():
                value = decay.get(int(nearest[i]))
                if value is not None and value > costs[i]:
                    costs[i] = value
        self.costs = costs.astype(_np().uint8)

    def cost(self, x: float, y: float):
        """The cost at world point (x, y): lethal_cost off the map; None when not computed."""
        cell = self.occupancy_grid.world_to_grid(x, y)
        if cell is None:
            return int(self.lethal_cost)
        index = cell[1] * self.occupancy_grid.width + cell[0]
        return int(self.costs[index]) if index < len(self.costs) else None
