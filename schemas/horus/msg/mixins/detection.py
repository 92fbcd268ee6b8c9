"""Helpers of the detection messages (horus/msg/detection.hmsg), mirroring the C++ mixins.
Computed in float32, like the f32 fields in C++."""


def _np():
    """numpy, imported on first use so that importing the message package stays fast."""
    import numpy
    return numpy




def _f32(value):
    """`value` rounded to float32, as the C++ helpers compute."""
    return _np().float32(value)


class BoundingBox2DMixin:
    def area(self) -> float:
        """Area in square pixels (0 for a degenerate box)."""
        w, h = _f32(self.width), _f32(self.height)
        return float(w * h) if w > 0 and h > 0 else 0.0

    def iou(self, other) -> float:
        """Intersection over union, 0-1; 0 when the union is empty."""
        x, y, w, h = _f32(self.x), _f32(self.y), _f32(self.width), _f32(self.height)
        ox, oy = _f32(other.x), _f32(other.y)
        ow, oh = _f32(other.width), _f32(other.height)
        left, top = max(x, ox), max(y, oy)
        right, bottom = min(x + w, ox + ow), min(y + h, oy + oh)
        inter = (right - left) * (bottom - top) if right > left and bottom > top else _f32(0)
        union = _f32(self.area()) + _f32(other.area()) - inter
        return float(inter / union) if union > 0 else 0.0
