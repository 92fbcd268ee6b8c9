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

/// Where interpolate() takes the series: tan(angle / 2) below it, so the quaternions' angle is
/// below 0.1 (their rotations below 0.2 rad apart).
constexpr double kSeriesLimit = 0.05;

/// atan(z) for 0 <= z < kSeriesLimit: the terms left out are below 1e-18 of it. Coefficients,
/// not divisions, so that the chain is multiplications only.
double small_atan(double z) noexcept {
  constexpr double c3 = -1.0 / 3, c5 = 1.0 / 5, c7 = -1.0 / 7, c9 = 1.0 / 9, c11 = -1.0 / 11,
                   c13 = 1.0 / 13;
  const double z2 = z * z;
  return z * (1 + z2 * (c3 + z2 * (c5 + z2 * (c7 + z2 * (c9 + z2 * (c11 + z2 * c13))))));
}

/// sin(x) and cos(x) for |x| < 0.1: the terms left out are below 1e-22.
double small_sin(double x) noexcept {
  constexpr double c3 = -1.0 / 6, c5 = 1.0 / 120, c7 = -1.0 / 5040, c9 = 1.0 / 362880,
                   c11 = -1.0 / 39916800;
  const double x2 = x * x;
  return x * (1 + x2 * (c3 + x2 * (c5 + x2 * (c7 + x2 * (c9 + x2 * c11)))));
}
double small_cos(double x) noexcept {
  constexpr double c2 = -1.0 / 2, c4 = 1.0 / 24, c6 = -1.0 / 720, c8 = 1.0 / 40320,
                   c10 = -1.0 / 3628800, c12 = 1.0 / 479001600;
  const double x2 = x * x;
  return 1 + x2 * (c2 + x2 * (c4 + x2 * (c6 + x2 * (c8 + x2 * (c10 + x2 * c12)))));
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
  // Neighbouring entries of a history are close: below kSeriesLimit (rotations less than about
  // 0.2 rad, 11 degrees, apart; `angle` here is half that, the quaternions' own angle) the angle
  // and the sine and cosine of its part come from their Taylor series, exact to double precision
  // there, instead of atan2 and sincos (a lookup interpolates once per link).
  const double ratio = apart / together;  // tan(angle / 2); together >= sqrt(2) after the flip
  const bool close = ratio < kSeriesLimit;
  const double angle = 2 * (close ? small_atan(ratio) : std::atan2(apart, together));
  double weight_a = 1 - fraction;
  double weight_b = fraction;
  // Equal rotations (to round-off): sin(angle) vanishes and the linear blend is exact.
  if (angle > 1e-12) {
    // The chords are 2 sin(angle / 2) and 2 cos(angle / 2) (their squares sum to 4 for unit
    // quaternions), which give sin and cos of the angle without a call; only fraction * angle
    // needs one (sin and cos of one argument: one sincos). sin((1 - f) a) / sin(a) is then
    // cos(f a) - cos(a) sin(f a) / sin(a).
    const double chords = std::sqrt(apart * apart + together * together);
    const double half_sine = apart / chords;
    const double half_cosine = together / chords;
    const double sine = 2 * half_sine * half_cosine;
    const double cosine = half_cosine * half_cosine - half_sine * half_sine;
    const double part = fraction * angle;
    weight_b = (close ? small_sin(part) : std::sin(part)) / sine;
    weight_a = (close ? small_cos(part) : std::cos(part)) - cosine * weight_b;
  }
  // Slerp of unit quaternions is one (to round-off): no normalisation needed. The linear blend
  // of the equal-rotation case is one too, the two being the same to round-off.
  const Quaternion rotation{weight_a * qa.x + weight_b * qb.x, weight_a * qa.y + weight_b * qb.y,
                            weight_a * qa.z + weight_b * qb.z, weight_a * qa.w + weight_b * qb.w};
  return {translation, rotation};
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
