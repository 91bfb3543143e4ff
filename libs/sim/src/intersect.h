#pragma once
// Ray-primitive intersections in a primitive's local frame, shared by the exact double-precision
// queries of World and the float fast path of the renderer. Rays: o + t d, t > t_min; the
// direction need not be unit length (t is then in units of |d|). No hit: +infinity.

#include <algorithm>
#include <cmath>
#include <limits>

namespace mav::sim::internal {

template <typename S>
inline S Inf() {
  return std::numeric_limits<S>::infinity();
}

// Axis-aligned box [-h, h] (slab method, Kay & Kajiya 1986).
template <typename S>
inline S RayBoxLocal(S ox, S oy, S oz, S dx, S dy, S dz, S hx, S hy, S hz, S t_min) {
  const S ix = S(1) / dx, iy = S(1) / dy, iz = S(1) / dz;
  const S tx1 = (-hx - ox) * ix, tx2 = (hx - ox) * ix;
  const S ty1 = (-hy - oy) * iy, ty2 = (hy - oy) * iy;
  const S tz1 = (-hz - oz) * iz, tz2 = (hz - oz) * iz;
  const S tn = std::max(std::max(std::min(tx1, tx2), std::min(ty1, ty2)), std::min(tz1, tz2));
  const S tf = std::min(std::min(std::max(tx1, tx2), std::max(ty1, ty2)), std::max(tz1, tz2));
  if (!(tn <= tf) || !(tf > t_min)) return Inf<S>();
  return tn > t_min ? tn : tf;
}

// Capped cylinder of radius r around the local z axis, |z| <= h.
template <typename S>
inline S RayCylinderLocal(S ox, S oy, S oz, S dx, S dy, S dz, S r, S h, S t_min) {
  S best = Inf<S>();
  const S a = dx * dx + dy * dy;
  if (a > S(1e-12)) {
    const S b = ox * dx + oy * dy;
    const S cross = ox * dy - oy * dx;
    // b^2 - a (|o|^2 - r^2) written without cancellation (Lagrange's identity).
    const S disc = r * r * a - cross * cross;
    if (disc >= S(0)) {
      const S sq = std::sqrt(disc);
      S t = (-b - sq) / a;
      if (!(t > t_min)) t = (-b + sq) / a;
      if (t > t_min && std::abs(oz + t * dz) <= h) best = t;
    }
  }
  if (dz != S(0)) {
    for (int s = -1; s <= 1; s += 2) {
      const S t = (static_cast<S>(s) * h - oz) / dz;
      if (t > t_min && t < best) {
        const S x = ox + t * dx, y = oy + t * dy;
        if (x * x + y * y <= r * r) best = t;
      }
    }
  }
  return best;
}

// Rectangle |x| <= hx, |y| <= hy in the plane z = 0.
template <typename S>
inline S RayRectangleLocal(S ox, S oy, S oz, S dx, S dy, S dz, S hx, S hy, S t_min) {
  if (dz == S(0)) return Inf<S>();
  const S t = -oz / dz;
  if (!(t > t_min)) return Inf<S>();
  if (std::abs(ox + t * dx) > hx || std::abs(oy + t * dy) > hy) return Inf<S>();
  return t;
}

}  // namespace mav::sim::internal
