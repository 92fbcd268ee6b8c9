"""Helpers of the vision messages (horus/msg/vision.hmsg), mirroring the C++ mixins."""
import math



def _np():
    """numpy, imported on first use so that importing the message package stays fast."""
    import numpy
    return numpy



class CameraInfoMixin:
    @classmethod
    def new(cls, width: int, height: int, fx: float, fy: float, cx: float, cy: float):
        """A distortion-free pinhole camera; identity rectification."""
        return cls(width=width, height=height,
                   camera_matrix=[fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
                   rectification_matrix=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                   projection_matrix=[fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0])

    def focal_lengths(self) -> tuple:
        """(fx, fy) in pixels."""
        return float(self.camera_matrix[0]), float(self.camera_matrix[4])

    def principal_point(self) -> tuple:
        """(cx, cy) in pixels."""
        return float(self.camera_matrix[2]), float(self.camera_matrix[5])


class RegionOfInterestMixin:
    @classmethod
    def new(cls, x: int, y: int, width: int, height: int):
        """The region at (x, y) of width x height pixels, not rectified."""
        return cls(x_offset=x, y_offset=y, width=width, height=height, do_rectify=False)

    def contains(self, x: int, y: int) -> bool:
        """True when pixel (x, y) lies inside (right and bottom edges excluded)."""
        return (self.x_offset <= x and x - self.x_offset < self.width
                and self.y_offset <= y and y - self.y_offset < self.height)

    def area(self) -> int:
        """Area in pixels."""
        return int(self.width) * int(self.height)


class StereoInfoMixin:
    def depth_from_disparity(self, disparity: float) -> float:
        """Depth in metres; +inf for a disparity <= 0."""
        d = _np().float32(disparity)
        if d <= 0.0:
            return math.inf
        return float(_np().float32(float(self.baseline) * float(self.left_camera.camera_matrix[0])
                                / float(d)))

    def disparity_from_depth(self, depth: float) -> float:
        """Disparity in pixels; NaN for a depth <= 0."""
        z = _np().float32(depth)
        if z <= 0.0:
            return math.nan
        return float(_np().float32(float(self.baseline) * float(self.left_camera.camera_matrix[0])
                                / float(z)))
