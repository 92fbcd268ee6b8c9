// Transform arithmetic: what lookups compose, and the helpers users transform their data with.
#include <cmath>

#include "horus/frames.hpp"

namespace horus {

Quaternion multiply(const Quaternion& a, const Quaternion& b) noexcept {
  return {
      a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y, a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
      a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w, a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z};
}

Vector3 rotate(const Quaternion& q, const Vector3& v) noexcept {
  // v + 2w(u x v) + 2u x (u x v), with u the vector part: fewer products than q v q*.
  const Vector3 u{q.x, q.y, q.z};
  const Vector3 t{2 * (u.y * v.z - u.z * v.y), 2 * (u.z * v.x - u.x * v.z),
                  2 * (u.x * v.y - u.y * v.x)};
  return {v.x + q.w * t.x + (u.y * t.z - u.z * t.y), v.y + q.w * t.y + (u.z * t.x - u.x * t.z),
          v.z + q.w * t.z + (u.x * t.y - u.y * t.x)};
}

Transform compose(const Transform& a, const Transform& b) noexcept {
  const Vector3 moved = rotate(a.rotation, b.translation);
  return {{a.translation.x + moved.x, a.translation.y + moved.y, a.translation.z + moved.z},
          multiply(a.rotation, b.rotation)};
}

Transform inverse(const Transform& t) noexcept {
  const Quaternion conjugate{-t.rotation.x, -t.rotation.y, -t.rotation.z, t.rotation.w};
  const Vector3 back = rotate(conjugate, t.translation);
  return {{-back.x, -back.y, -back.z}, conjugate};
}

namespace {

Quaternion normalized(const Quaternion& q) noexcept {
  const double norm = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  return {q.x / norm, q.y / norm, q.z / norm, q.w / norm};
}

}  // namespace

Transform interpolate(const Transform& a, const Transform& b, double fraction) noexcept {
  const Vector3 ta = a.translation;
  const Vector3 tb = b.translation;
  const Vector3 translation{ta.x + (tb.x - ta.x) * fraction, ta.y + (tb.y - ta.y) * fraction,
                            ta.z + (tb.z - ta.z) * fraction};
  const Quaternion qa = a.rotation;
  Quaternion qb = b.rotation;
  // q and -q are the same rotation: take the short way round.
  if (qa.x * qb.x + qa.y * qb.y + qa.z * qb.z + qa.w * qb.w < 0) {
    qb = {-qb.x, -qb.y, -qb.z, -qb.w};
  }
  // The angle between them from the chord lengths, not acos of the dot product, which loses
  // half the digits for the small steps between neighbouring entries.
  const double apart = std::sqrt((qb.x - qa.x) * (qb.x - qa.x) + (qb.y - qa.y) * (qb.y - qa.y) +
                                 (qb.z - qa.z) * (qb.z - qa.z) + (qb.w - qa.w) * (qb.w - qa.w));
  const double together = std::sqrt((qb.x + qa.x) * (qb.x + qa.x) + (qb.y + qa.y) * (qb.y + qa.y) +
                                    (qb.z + qa.z) * (qb.z + qa.z) + (qb.w + qa.w) * (qb.w + qa.w));
  const double angle = 2 * std::atan2(apart, together);
  double weight_a = 1 - fraction;
  double weight_b = fraction;
  // Equal rotations (to round-off): sin(angle) vanishes and the linear blend is exact.
  if (angle > 1e-12) {
    const double sine = std::sin(angle);
    weight_a = std::sin((1 - fraction) * angle) / sine;
    weight_b = std::sin(fraction * angle) / sine;
  }
  const Quaternion rotation{weight_a * qa.x + weight_b * qb.x, weight_a * qa.y + weight_b * qb.y,
                            weight_a * qa.z + weight_b * qb.z, weight_a * qa.w + weight_b * qb.w};
  return {translation, normalized(rotation)};
}

Vector3 transform_point(const Transform& t, const Vector3& point) noexcept {
  const Vector3 turned = rotate(t.rotation, point);
  return {turned.x + t.translation.x, turned.y + t.translation.y, turned.z + t.translation.z};
}

Vector3 transform_vector(const Transform& t, const Vector3& vector) noexcept {
  return rotate(t.rotation, vector);
}

Pose transform_pose(const Transform& t, const Pose& pose) noexcept { return compose(t, pose); }

Quaternion axis_angle(const Vector3& axis, double radians) noexcept {
  const double half = radians / 2;
  const double s = std::sin(half);
  return {axis.x * s, axis.y * s, axis.z * s, std::cos(half)};
}

}  // namespace horus
