#include "mav/planning/trajectory.h"

#include <Eigen/SparseCore>
#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "mav/common/time.h"

namespace mav::planning {
namespace {

using geometry::PolynomialSegment;
using geometry::PolynomialTrajectory;

// ---- The C4 quintic spline ------------------------------------------------------------------

// Jerk and snap at both ends of a quintic Hermite segment of duration T as linear functions of
// its end data x = (p0, v0, a0, p1, v1, a1): rows j0, s0, j1, s1.
Eigen::Matrix<double, 4, 6> EndDerivatives(double T) {
  Eigen::Matrix<double, 4, 6> m;
  for (int col = 0; col < 6; ++col) {
    Eigen::Matrix<double, 6, 1> x = Eigen::Matrix<double, 6, 1>::Unit(col);
    // Residuals of the end conditions once c0..c2 are fixed by the start.
    const double h = x[3] - x[0] - x[1] * T - 0.5 * x[2] * T * T;
    const double hv = x[4] - x[1] - x[2] * T;
    const double ha = x[5] - x[2];
    const double c3 = (10 * h - 4 * hv * T + 0.5 * ha * T * T) / (T * T * T);
    const double c4 = (-15 * h + 7 * hv * T - ha * T * T) / (T * T * T * T);
    const double c5 = (6 * h - 3 * hv * T + 0.5 * ha * T * T) / (T * T * T * T * T);
    m(0, col) = 6 * c3;
    m(1, col) = 24 * c4;
    m(2, col) = 6 * c3 + 24 * c4 * T + 60 * c5 * T * T;
    m(3, col) = 24 * c4 + 120 * c5 * T;
  }
  return m;
}

// Coefficients (ascending powers) of the quintic with the given end data.
Eigen::Matrix<double, 6, 1> HermiteQuintic(double T, double p0, double v0, double a0, double p1,
                                           double v1, double a1) {
  const double h = p1 - p0 - v0 * T - 0.5 * a0 * T * T;
  const double hv = v1 - v0 - a0 * T;
  const double ha = a1 - a0;
  Eigen::Matrix<double, 6, 1> c;
  c << p0, v0, 0.5 * a0, (10 * h - 4 * hv * T + 0.5 * ha * T * T) / (T * T * T),
      (-15 * h + 7 * hv * T - ha * T * T) / (T * T * T * T),
      (6 * h - 3 * hv * T + 0.5 * ha * T * T) / (T * T * T * T * T);
  return c;
}

// ---- The rounded path -----------------------------------------------------------------------

struct Piece {
  bool arc = false;
  double s0 = 0, length = 0;
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();  // line
  Eigen::Vector3d centre = Eigen::Vector3d::Zero(), e1 = Eigen::Vector3d::Zero(),
                  u1 = Eigen::Vector3d::Zero();  // arc: centre + R (cos phi e1 + sin phi u1)
  double radius = 0, angle = 0;
  int corner = -1;  // the polyline vertex an arc rounds
};

struct Corner {
  enum Kind { kStop, kStraight, kArc };
  Kind kind = kStop;   // a stop (the ends, waypoints, corners no arc fits), straight on, an arc
  double tangent = 0;  // distance of the arc's tangent points from the vertex
  double radius = 0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero(), e1 = Eigen::Vector3d::Zero(),
                  u1 = Eigen::Vector3d::Zero();
  double angle = 0;
};

Eigen::Vector3d ArcPoint(const Eigen::Vector3d& centre, const Eigen::Vector3d& e1,
                         const Eigen::Vector3d& u1, double radius, double phi) {
  return centre + radius * (std::cos(phi) * e1 + std::sin(phi) * u1);
}

// The arc rounding vertex b between a and c with tangent points `tangent` from b.
Corner MakeCorner(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                  double tangent) {
  Corner k;
  k.kind = Corner::kArc;
  const Eigen::Vector3d u1 = (b - a).normalized(), u2 = (c - b).normalized();
  const double angle = std::acos(std::clamp(u1.dot(u2), -1.0, 1.0));
  k.angle = angle;
  k.tangent = tangent;
  k.radius = tangent / std::tan(0.5 * angle);
  const Eigen::Vector3d t1 = b - tangent * u1;
  // Towards the centre: perpendicular to u1 in the corner's plane, on the side of u2.
  const Eigen::Vector3d inward = (u2 - u1.dot(u2) * u1).normalized();
  k.centre = t1 + k.radius * inward;
  k.e1 = -inward;
  k.u1 = u1;
  return k;
}

struct RoundedPath {
  std::vector<Piece> pieces;
  std::vector<double> stop_s;  // arc length of the ends and stops, increasing
  double length = 0;

  const Piece& PieceAt(double s) const {
    auto it = std::upper_bound(pieces.begin(), pieces.end(), s,
                               [](double v, const Piece& p) { return v < p.s0; });
    return it == pieces.begin() ? pieces.front() : *(it - 1);
  }
  Eigen::Vector3d Position(double s) const {
    const Piece& p = PieceAt(s);
    const double u = std::clamp(s - p.s0, 0.0, p.length);
    if (!p.arc) return p.length > 0 ? Eigen::Vector3d(p.a + (p.b - p.a) * (u / p.length)) : p.a;
    return ArcPoint(p.centre, p.e1, p.u1, p.radius, u / p.radius);
  }
  double Radius(double s) const {
    const Piece& p = PieceAt(s);
    return p.arc ? p.radius : std::numeric_limits<double>::infinity();
  }
};

// The rounded path of `path` with the corners `corners` (one per vertex; the ends are stops).
RoundedPath BuildRoundedPath(const std::vector<Eigen::Vector3d>& path,
                             const std::vector<Corner>& corners) {
  RoundedPath r;
  const size_t n = path.size();
  double s = 0;
  r.stop_s.push_back(0);
  for (size_t i = 0; i + 1 < n; ++i) {
    const Eigen::Vector3d u = (path[i + 1] - path[i]).normalized();
    Piece line;
    line.a = path[i] + corners[i].tangent * u;
    line.b = path[i + 1] - corners[i + 1].tangent * u;
    line.s0 = s;
    line.length = (line.b - line.a).norm();
    s += line.length;
    r.pieces.push_back(line);
    if (i + 2 == n) break;
    const Corner& k = corners[i + 1];
    if (k.kind == Corner::kArc) {
      Piece arc;
      arc.arc = true;
      arc.centre = k.centre;
      arc.e1 = k.e1;
      arc.u1 = k.u1;
      arc.radius = k.radius;
      arc.angle = k.angle;
      arc.s0 = s;
      arc.length = k.radius * k.angle;
      arc.corner = static_cast<int>(i + 1);
      s += arc.length;
      r.pieces.push_back(arc);
    } else if (k.kind == Corner::kStop) {
      r.stop_s.push_back(s);
    }
  }
  r.length = s;
  r.stop_s.push_back(s);
  return r;
}

// ---- The speed plan -------------------------------------------------------------------------

// Where the repairs act: windows of arc length where the speed limit is cut and the knots are
// closer together.
struct Window {
  double s0, s1, speed_factor, knot_factor;
};

double Factor(const std::vector<Window>& windows, double s, bool knot) {
  double f = 1;
  for (const Window& w : windows) {
    if (s >= w.s0 && s <= w.s1) f *= knot ? w.knot_factor : w.speed_factor;
  }
  return f;
}

struct SpeedProfile {
  std::vector<double> s, v, t;

  double Duration() const { return t.back(); }
  // Arc length at time `time` (constant acceleration within each step).
  double SAt(double time) const {
    if (time <= 0) return 0;
    if (time >= t.back()) return s.back();
    const size_t m = std::upper_bound(t.begin(), t.end(), time) - t.begin() - 1;
    const double dt = t[m + 1] - t[m];
    if (dt <= 0) return s[m];
    const double accel = (v[m + 1] - v[m]) / dt;
    const double tau = time - t[m];
    return std::min(s[m + 1], s[m] + v[m] * tau + 0.5 * accel * tau * tau);
  }
  // Time at arc length `at` (linear within a step).
  double TAt(double at) const {
    if (at <= 0) return 0;
    if (at >= s.back()) return t.back();
    const size_t m = std::upper_bound(s.begin(), s.end(), at) - s.begin() - 1;
    const double f = (at - s[m]) / std::max(1e-12, s[m + 1] - s[m]);
    return t[m] + f * (t[m + 1] - t[m]);
  }
};

SpeedProfile PlanSpeed(const RoundedPath& r, const SpeedLimits& limits,
                       const std::vector<Window>& windows) {
  constexpr double kStep = 0.05;
  // Slightly inside the limits: the spline smooths the profile's acceleration steps and may
  // overshoot them a little; the check then rarely needs to slow the whole trajectory.
  const double v_max = 0.97 * limits.max_speed_mps;
  const double a_long = 0.92 * limits.max_acceleration_mps2;
  const double a_lat = 0.92 * limits.max_lateral_acceleration_mps2;
  const double jerk = limits.max_jerk_mps3;
  SpeedProfile p;
  std::vector<double> v_lim, curvature, from_stop, to_stop;
  for (size_t k = 0; k + 1 < r.stop_s.size(); ++k) {
    const double s0 = r.stop_s[k], s1 = r.stop_s[k + 1];
    const int steps = std::max(1, static_cast<int>(std::ceil((s1 - s0) / kStep)));
    for (int m = (k == 0 ? 0 : 1); m <= steps; ++m) {
      const double s = s0 + (s1 - s0) * m / steps;
      const double radius = r.Radius(s);
      double lim = v_max * Factor(windows, s, false);
      if (std::isfinite(radius)) lim = std::min(lim, std::sqrt(a_lat * radius));
      if (m == 0 || m == steps) lim = 0;  // ends and stops
      p.s.push_back(s);
      v_lim.push_back(lim);
      curvature.push_back(std::isfinite(radius) ? 1.0 / radius : 0.0);
      from_stop.push_back(s - s0);
      to_stop.push_back(s1 - s);
    }
  }
  const size_t n = p.s.size();
  // What is left of the tangential acceleration at speed v on curvature kappa, `d` from a stop.
  const auto tangential = [&](double v, double kappa, double d) {
    const double lateral = v * v * kappa / a_lat;
    const double ramp = std::cbrt(6 * jerk * jerk * std::max(d, 1e-4));
    return std::min(ramp, a_long) * std::sqrt(std::max(0.0, 1.0 - lateral * lateral));
  };
  p.v = v_lim;
  for (size_t m = 0; m + 1 < n; ++m) {
    const double ds = p.s[m + 1] - p.s[m];
    const double a = tangential(p.v[m], curvature[m], from_stop[m] + 0.5 * ds);
    p.v[m + 1] = std::min(p.v[m + 1], std::sqrt(p.v[m] * p.v[m] + 2 * a * ds));
  }
  for (size_t m = n - 1; m > 0; --m) {
    const double ds = p.s[m] - p.s[m - 1];
    const double a = tangential(p.v[m], curvature[m], to_stop[m] + 0.5 * ds);
    p.v[m - 1] = std::min(p.v[m - 1], std::sqrt(p.v[m] * p.v[m] + 2 * a * ds));
  }
  p.t.assign(n, 0);
  for (size_t m = 0; m + 1 < n; ++m) {
    const double ds = p.s[m + 1] - p.s[m];
    const double v_sum = p.v[m] + p.v[m + 1];
    p.t[m + 1] = p.t[m] + (v_sum > 0 ? 2 * ds / v_sum : 0);
  }
  return p;
}

// Knot times: every knot_interval (closer where a window asks), exactly at every stop.
std::vector<double> KnotTimes(const RoundedPath& r, const SpeedProfile& p, double interval,
                              const std::vector<Window>& windows) {
  std::vector<double> knots = {0};
  for (size_t k = 0; k + 1 < r.stop_s.size(); ++k) {
    const double t0 = p.TAt(r.stop_s[k]), t1 = p.TAt(r.stop_s[k + 1]);
    if (t1 - t0 < 1e-9) continue;
    std::vector<double> local = {t0};
    while (local.back() < t1) {
      const double at = local.back();
      local.push_back(at + interval * Factor(windows, p.SAt(at), true));
    }
    // Stretch so the last knot lands on the stop.
    const double scale = (t1 - t0) / (local.back() - t0);
    for (size_t i = 1; i < local.size(); ++i) knots.push_back(t0 + (local[i] - t0) * scale);
  }
  return knots;
}

PolynomialTrajectory TimeScaled(const PolynomialTrajectory& t, double k) {
  std::vector<PolynomialSegment> segments = t.segments();
  for (PolynomialSegment& s : segments) {
    s.duration_s *= k;
    double f = 1;
    for (int j = 0; j < 6; ++j, f /= k) s.coefficients.col(j) *= f;
  }
  return *PolynomialTrajectory::Create(std::move(segments), t.yaw_policy(), t.start_yaw_rad());
}

struct CheckResult {
  double max_speed = 0, max_acceleration = 0, length = 0;
  double limit_ratio = 0;  // max over samples of the limit ratios (speed, sqrt of accelerations)
  double min_clearance = std::numeric_limits<double>::infinity();
  std::vector<double> violation_times;
  Eigen::Vector3d worst = Eigen::Vector3d::Zero();
};

CheckResult CheckTrajectory(const ClearanceMap& map, const PolynomialTrajectory& traj,
                            const SpeedLimits& limits, double required, double check_step) {
  CheckResult r;
  const double duration = traj.duration_s();
  const double a_any = std::max(limits.max_acceleration_mps2, limits.max_lateral_acceleration_mps2);
  Eigen::Vector3d previous = traj.Evaluate(0).position;
  double t = 0;
  bool last = false;
  std::vector<std::pair<double, Eigen::Vector3d>> candidates;  // (lower bound, sample)
  while (true) {
    const Eigen::Vector3d p = traj.EvaluateDerivative(t, 0);
    const Eigen::Vector3d v = traj.EvaluateDerivative(t, 1);
    const Eigen::Vector3d a = traj.EvaluateDerivative(t, 2);
    const double speed = v.norm();
    r.max_speed = std::max(r.max_speed, speed);
    r.max_acceleration = std::max(r.max_acceleration, a.norm());
    r.length += (p - previous).norm();
    previous = p;
    double ratio = speed / limits.max_speed_mps;
    if (speed > 0.3) {
      const Eigen::Vector3d dir = v / speed;
      const double along = a.dot(dir);
      const double across = (a - along * dir).norm();
      ratio = std::max({ratio, std::sqrt(std::abs(along) / limits.max_acceleration_mps2),
                        std::sqrt(across / limits.max_lateral_acceleration_mps2)});
    } else {
      ratio = std::max(ratio, std::sqrt(a.norm() / a_any));
    }
    r.limit_ratio = std::max(r.limit_ratio, ratio);
    if (!map.IsValid(p, required)) {
      if (r.violation_times.empty()) r.worst = p;
      r.violation_times.push_back(t);
    }
    candidates.emplace_back(map.ClearanceLowerBound(p), p);
    if (last) break;
    // Spatial steps below check_step: over 10 ms the speed changes by < 0.5 m/s.
    t += std::min(0.01, check_step / (speed + 0.5));
    if (t >= duration) {
      t = duration;
      last = true;
    }
  }
  // The exact minimum over the samples: by increasing lower bound, until the bound passes the
  // best exact value found.
  std::sort(candidates.begin(), candidates.end(),
            [](const auto& x, const auto& y) { return x.first < y.first; });
  for (const auto& [bound, p] : candidates) {
    if (bound >= r.min_clearance) break;
    r.min_clearance = std::min(r.min_clearance, map.ClearanceUpTo(p, r.min_clearance));
  }
  return r;
}

// Whether every point of the arc keeps `clearance` (samples every 2 cm).
bool ArcValid(const ClearanceMap& map, const Corner& k, double clearance) {
  const int samples = std::max(2, static_cast<int>(std::ceil(k.radius * k.angle / 0.02)));
  for (int q = 0; q <= samples; ++q) {
    if (!map.IsValid(ArcPoint(k.centre, k.e1, k.u1, k.radius, k.angle * q / samples), clearance)) {
      return false;
    }
  }
  return true;
}

// The widest arc for the corner b between a and c, radius at most `radius`. A taut path
// touches the obstacles at its corners, where an arc tangent to both segments would cut inside;
// so the vertex is first moved outwards along the bisector by the arc's cut
// e = R (1 / cos(theta / 2) - 1), which puts the arc's middle back on b. Radii shrink by 30 %
// until the arc and the straight pieces to a and c keep `clearance` (and the tangent points fit
// on the segments); with no arc at all the corner is a stop (kind kStop). *moved_b is the vertex
// the arc belongs to.
Corner FitCorner(const ClearanceMap& map, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                 const Eigen::Vector3d& c, bool a_pinned, bool c_pinned, double radius,
                 double clearance, Eigen::Vector3d* moved_b) {
  const Eigen::Vector3d u1 = (b - a).normalized(), u2 = (c - b).normalized();
  const double angle = std::acos(std::clamp(u1.dot(u2), -1.0, 1.0));
  const Eigen::Vector3d outward = (u1 - u2).normalized();
  for (int shrink = 0; shrink < 24 && radius > 0.01; ++shrink, radius *= 0.7) {
    const double cut = std::min(1.0, radius * (1.0 / std::cos(0.5 * angle) - 1.0));
    for (const double push : {cut, 0.0}) {
      const Eigen::Vector3d v = b + push * outward;
      const double in = (v - a).norm(), out = (c - v).norm();
      const double turn =
          std::acos(std::clamp((v - a).normalized().dot((c - v).normalized()), -1.0, 1.0));
      const double tangent = radius * std::tan(0.5 * turn);
      if (tangent > in * (a_pinned ? 0.95 : 0.5) || tangent > out * (c_pinned ? 0.95 : 0.5)) {
        continue;
      }
      const Corner k = MakeCorner(a, v, c, tangent);
      if (!ArcValid(map, k, clearance)) continue;
      if (push > 0 && (!map.IsSegmentValid(a, v - tangent * (v - a).normalized(), clearance) ||
                       !map.IsSegmentValid(v + tangent * (c - v).normalized(), c, clearance))) {
        continue;
      }
      *moved_b = v;
      return k;
    }
  }
  *moved_b = b;
  return Corner{};
}

// Two corners joined by a short segment (the shortening wraps an obstacle's edge with two
// nearby vertices) leave room only for tiny arcs. Where the outer segments, extended, pass
// each other beyond both vertices (closer than 2 cm + 15 % of the short segment: in 3-D they are
// skew), the pair becomes one vertex there, if the two new segments keep `clearance`.
void MergeCloseCorners(const ClearanceMap& map, double short_m, double clearance,
                       std::vector<Eigen::Vector3d>* points, std::vector<bool>* pinned) {
  for (bool merged = true; merged;) {
    merged = false;
    for (size_t i = 1; i + 2 < points->size(); ++i) {
      std::vector<Eigen::Vector3d>& p = *points;
      if ((*pinned)[i] || (*pinned)[i + 1] || (p[i + 1] - p[i]).norm() > short_m) continue;
      // Closest points of a + s (v1 - a) and c + t (v2 - c).
      const Eigen::Vector3d d1 = p[i] - p[i - 1], d2 = p[i + 1] - p[i + 2];
      const Eigen::Vector3d w = p[i - 1] - p[i + 2];
      const double aa = d1.dot(d1), bb = d1.dot(d2), cc = d2.dot(d2), dd = d1.dot(w),
                   ee = d2.dot(w);
      const double den = aa * cc - bb * bb;
      if (den < 1e-12 * aa * cc) continue;  // parallel
      const double s = (bb * ee - cc * dd) / den, t = (aa * ee - bb * dd) / den;
      if (s <= 1 || t <= 1) continue;
      const Eigen::Vector3d q1 = p[i - 1] + s * d1, q2 = p[i + 2] + t * d2;
      if ((q1 - q2).norm() > 0.02 + 0.15 * (p[i + 1] - p[i]).norm() ||
          (q1 - p[i]).norm() > short_m) {
        continue;
      }
      const Eigen::Vector3d q = 0.5 * (q1 + q2);
      if (!map.IsSegmentValid(p[i - 1], q, clearance) ||
          !map.IsSegmentValid(q, p[i + 2], clearance)) {
        continue;
      }
      p[i] = q;
      p.erase(p.begin() + i + 1);
      pinned->erase(pinned->begin() + i + 1);
      merged = true;
    }
  }
}

// Douglas-Peucker on the polyline between pinned vertices: a run of vertices closer than
// `tolerance` to the chord is replaced by the chord when the chord keeps `clearance`. The
// shortening leaves clusters of nearly collinear vertices (its corner cuts) whose tiny segments
// would otherwise limit the arcs, and so the speed, at each of them.
void Simplify(const ClearanceMap& map, const std::vector<Eigen::Vector3d>& points, size_t i,
              size_t j, double tolerance, double clearance, std::vector<bool>* keep) {
  if (j <= i + 1) return;
  const Eigen::Vector3d chord = points[j] - points[i];
  const double chord2 = std::max(chord.squaredNorm(), 1e-18);
  size_t worst = i + 1;
  double worst_distance = -1;
  for (size_t k = i + 1; k < j; ++k) {
    const double f = std::clamp((points[k] - points[i]).dot(chord) / chord2, 0.0, 1.0);
    const double d = (points[i] + f * chord - points[k]).norm();
    if (d > worst_distance) {
      worst_distance = d;
      worst = k;
    }
  }
  if (worst_distance <= tolerance && map.IsSegmentValid(points[i], points[j], clearance)) {
    for (size_t k = i + 1; k < j; ++k) (*keep)[k] = false;
    return;
  }
  Simplify(map, points, i, worst, tolerance, clearance, keep);
  Simplify(map, points, worst, j, tolerance, clearance, keep);
}

}  // namespace

bool SpeedLimits::IsValid(std::string* why) const {
  std::ostringstream msg;
  const auto in = [](double v) { return v > 0 && v <= 20; };
  if (!in(max_speed_mps)) {
    msg << "max_speed_mps: must be in (0, 20] m/s, got " << max_speed_mps;
  } else if (!in(max_acceleration_mps2)) {
    msg << "max_acceleration_mps2: must be in (0, 20] m/s^2, got " << max_acceleration_mps2;
  } else if (!in(max_lateral_acceleration_mps2)) {
    msg << "max_lateral_acceleration_mps2: must be in (0, 20] m/s^2, got "
        << max_lateral_acceleration_mps2;
  } else if (!(max_jerk_mps3 > 0 && max_jerk_mps3 <= 200)) {
    msg << "max_jerk_mps3: must be in (0, 200] m/s^3, got " << max_jerk_mps3;
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

bool TrajectoryOptions::IsValid(std::string* why) const {
  if (!limits.IsValid(why)) {
    if (why) *why = "limits." + *why;
    return false;
  }
  std::ostringstream msg;
  if (!(required_clearance_m >= 0 && std::isfinite(required_clearance_m))) {
    msg << "required_clearance_m: must be finite and >= 0, got " << required_clearance_m;
  } else if (!(corner_clearance_m >= 0 && std::isfinite(corner_clearance_m))) {
    msg << "corner_clearance_m: must be finite and >= 0, got " << corner_clearance_m;
  } else if (!(knot_interval_s >= 0.02 && knot_interval_s <= 2)) {
    msg << "knot_interval_s: must be in [0.02, 2] s, got " << knot_interval_s;
  } else if (!(check_step_m > 0 && check_step_m <= 0.05)) {
    msg << "check_step_m: must be in (0, 0.05] m, got " << check_step_m;
  } else if (!(simplify_tolerance_m >= 0 && simplify_tolerance_m <= 1)) {
    msg << "simplify_tolerance_m: must be in [0, 1] m, got " << simplify_tolerance_m;
  } else if (max_refits < 0 || max_refits > 50) {
    msg << "max_refits: must be in [0, 50], got " << max_refits;
  } else if (!std::isfinite(start_yaw_rad)) {
    msg << "start_yaw_rad: must be finite";
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

Result<PolynomialTrajectory> FitQuinticSpline(const std::vector<double>& times_s,
                                              const std::vector<Eigen::Vector3d>& points,
                                              geometry::YawPolicy yaw_policy,
                                              double start_yaw_rad) {
  if (times_s.size() != points.size()) {
    return Status::InvalidArgument("times_s: " + std::to_string(times_s.size()) + " times for " +
                                   std::to_string(points.size()) + " points");
  }
  if (points.size() < 2) return Status::InvalidArgument("points: at least two needed");
  for (size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite() || !std::isfinite(times_s[i])) {
      return Status::InvalidArgument("points[" + std::to_string(i) + "]: not finite");
    }
    if (i > 0 && !(times_s[i] > times_s[i - 1])) {
      return Status::InvalidArgument("times_s[" + std::to_string(i) +
                                     "]: times must increase strictly");
    }
  }
  const int segments = static_cast<int>(points.size()) - 1;
  const int interior = segments - 1;
  // Unknown velocity and acceleration (per axis) at every interior knot; zero at the ends.
  Eigen::MatrixXd va = Eigen::MatrixXd::Zero(2 * (interior + 2), 3);  // rows 2k, 2k+1: knot k
  if (interior > 0) {
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(2 * interior, 3);
    for (int k = 1; k <= interior; ++k) {
      const double t_left = times_s[k] - times_s[k - 1], t_right = times_s[k + 1] - times_s[k];
      const Eigen::Matrix<double, 4, 6> left = EndDerivatives(t_left);
      const Eigen::Matrix<double, 4, 6> right = EndDerivatives(t_right);
      // Row scaling: jerk rows by t^3, snap rows by t^4 keep the entries of order one.
      const double t_mean = 0.5 * (t_left + t_right);
      for (int e = 0; e < 2; ++e) {  // 0: jerk, 1: snap
        const int row = 2 * (k - 1) + e;
        const double scale = std::pow(t_mean, 3 + e);
        // left's end row (j1 or s1) minus right's start row (j0 or s0).
        const Eigen::Matrix<double, 1, 6> l = left.row(2 + e) * scale;
        const Eigen::Matrix<double, 1, 6> r = right.row(e) * scale;
        // Unknowns of knots k-1, k, k+1 (columns v, a of each).
        const double coeff[3][2] = {{l[1], l[2]}, {l[4] - r[1], l[5] - r[2]}, {-r[4], -r[5]}};
        for (int d = -1; d <= 1; ++d) {
          const int knot = k + d;
          if (knot < 1 || knot > interior) continue;  // the ends are at rest: known zeros
          for (int q = 0; q < 2; ++q) {
            triplets.emplace_back(row, 2 * (knot - 1) + q, coeff[d + 1][q]);
          }
        }
        rhs.row(row) =
            -(l[0] * points[k - 1] + (l[3] - r[0]) * points[k] - r[3] * points[k + 1]).transpose();
      }
    }
    Eigen::SparseMatrix<double> a(2 * interior, 2 * interior);
    a.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SparseLU<Eigen::SparseMatrix<double>> solver;
    solver.compute(a);
    if (solver.info() != Eigen::Success) {
      return Status::InvalidArgument("times_s: the spline's system is singular");
    }
    const Eigen::MatrixXd x = solver.solve(rhs);
    va.block(2, 0, 2 * interior, 3) = x;
  }
  std::vector<PolynomialSegment> out(segments);
  for (int i = 0; i < segments; ++i) {
    const double T = times_s[i + 1] - times_s[i];
    out[i].duration_s = T;
    for (int axis = 0; axis < 3; ++axis) {
      out[i].coefficients.row(axis) =
          HermiteQuintic(T, points[i][axis], va(2 * i, axis), va(2 * i + 1, axis),
                         points[i + 1][axis], va(2 * i + 2, axis), va(2 * i + 3, axis))
              .transpose();
    }
  }
  return PolynomialTrajectory::Create(std::move(out), yaw_policy, start_yaw_rad);
}

Result<TrajectoryResult> PlanTrajectory(const ClearanceMap& map,
                                        const std::vector<Eigen::Vector3d>& path,
                                        const std::vector<size_t>& stops,
                                        const TrajectoryOptions& options, const Termination& stop) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  if (path.size() < 2) return Status::InvalidArgument("path: at least two points needed");
  for (size_t i = 0; i < path.size(); ++i) {
    if (!path[i].allFinite()) {
      return Status::InvalidArgument("path[" + std::to_string(i) + "]: not finite");
    }
  }
  // Repeated points carry no geometry: drop them (keeping the stops).
  std::vector<Eigen::Vector3d> points = {path.front()};
  std::vector<bool> pinned = {true};
  for (size_t i = 1; i < path.size(); ++i) {
    const bool is_stop =
        i + 1 == path.size() || std::find(stops.begin(), stops.end(), i) != stops.end();
    if ((path[i] - points.back()).norm() < 1e-6) {
      pinned.back() = pinned.back() || is_stop;
      continue;
    }
    points.push_back(path[i]);
    pinned.push_back(is_stop);
  }
  pinned.back() = true;
  if (points.size() < 2) return Status::InvalidArgument("path: start and goal coincide");

  const double required =
      options.required_clearance_m > 0 ? options.required_clearance_m : map.robot_radius();
  const double corner_clearance =
      options.corner_clearance_m > 0 ? options.corner_clearance_m : required + 0.05;
  {
    std::vector<bool> keep(points.size(), true);
    size_t from = 0;
    for (size_t i = 1; i < points.size(); ++i) {
      if (!pinned[i]) continue;
      Simplify(map, points, from, i, options.simplify_tolerance_m, corner_clearance, &keep);
      from = i;
    }
    std::vector<Eigen::Vector3d> kept_points;
    std::vector<bool> kept_pinned;
    for (size_t i = 0; i < points.size(); ++i) {
      if (!keep[i]) continue;
      kept_points.push_back(points[i]);
      kept_pinned.push_back(pinned[i]);
    }
    points = std::move(kept_points);
    pinned = std::move(kept_pinned);
  }
  MergeCloseCorners(map, 2.5, corner_clearance, &points, &pinned);
  const SpeedLimits& limits = options.limits;
  const double radius_cap =
      limits.max_speed_mps * limits.max_speed_mps / limits.max_lateral_acceleration_mps2;

  TrajectoryResult result;
  std::vector<double> corner_scale(points.size(), 1.0);  // shrinks arcs that caused violations
  std::vector<Window> windows;
  for (int attempt = 0;; ++attempt) {
    MAV_RETURN_IF_ERROR(stop.Check("trajectory"));
    int64_t t0 = MonotonicNowNs();
    // 1. Corners, each from the previous (possibly moved) vertex to the next original one.
    const size_t n = points.size();
    std::vector<Corner> corners(n);
    std::vector<Eigen::Vector3d> moved = points;
    for (size_t i = 1; i + 1 < n; ++i) {
      if (pinned[i]) continue;
      const Eigen::Vector3d &a = moved[i - 1], &b = points[i], &c = points[i + 1];
      const double angle =
          std::acos(std::clamp((b - a).normalized().dot((c - b).normalized()), -1.0, 1.0));
      if (angle < 1e-4) {
        corners[i].kind = Corner::kStraight;
        continue;
      }
      if (angle > M_PI - 1e-3) continue;  // a reversal: stop there
      const double radius = radius_cap * corner_scale[i];
      corners[i] = FitCorner(map, a, b, c, pinned[i - 1], pinned[i + 1], radius, corner_clearance,
                             &moved[i]);
    }
    const RoundedPath rounded = BuildRoundedPath(moved, corners);
    const SpeedProfile profile = PlanSpeed(rounded, limits, windows);
    result.speed_plan_ms += MsSince(t0);

    // 3. Spline.
    t0 = MonotonicNowNs();
    const std::vector<double> knots = KnotTimes(rounded, profile, options.knot_interval_s, windows);
    std::vector<Eigen::Vector3d> knot_points;
    knot_points.reserve(knots.size());
    for (double t : knots) knot_points.push_back(rounded.Position(profile.SAt(t)));
    MAV_ASSIGN_OR_RETURN(
        PolynomialTrajectory trajectory,
        FitQuinticSpline(knots, knot_points, options.yaw_policy, options.start_yaw_rad));
    result.spline_ms += MsSince(t0);

    // 4. Check.
    t0 = MonotonicNowNs();
    CheckResult check = CheckTrajectory(map, trajectory, limits, required, options.check_step_m);
    double scale = 1;
    if (check.limit_ratio > 1.0) {
      scale = check.limit_ratio * 1.0005;
      trajectory = TimeScaled(trajectory, scale);
      check = CheckTrajectory(map, trajectory, limits, required, options.check_step_m);
    }
    result.check_ms += MsSince(t0);
    if (check.violation_times.empty()) {
      result.trajectory = std::move(trajectory);
      result.duration_s = result.trajectory.duration_s();
      result.length_m = check.length;
      result.max_speed_mps = check.max_speed;
      result.mean_speed_mps = result.duration_s > 0 ? check.length / result.duration_s : 0;
      result.max_acceleration_mps2 = check.max_acceleration;
      result.min_clearance_m = check.min_clearance;
      result.time_scale = scale;
      result.refits = attempt;
      return result;
    }
    if (attempt >= options.max_refits) {
      std::ostringstream msg;
      msg << "trajectory: the spline still comes closer than " << required
          << " m to an obstacle near (" << check.worst.transpose() << ") after " << attempt
          << " repairs";
      return Status::FailedPrecondition(msg.str());
    }
    // Repair: around every violation, closer knots, a lower speed and smaller arcs.
    std::vector<double> where;
    for (double t : check.violation_times) {
      const double s = profile.SAt(t / scale);
      if (where.empty() || s > where.back() + 1.0) where.push_back(s);
    }
    for (double s : where) {
      windows.push_back({s - 2.0, s + 2.0, 0.75, 0.5});
      for (const Piece& p : rounded.pieces) {
        if (p.arc && p.s0 <= s + 2.0 && p.s0 + p.length >= s - 2.0) corner_scale[p.corner] *= 0.5;
      }
    }
  }
}

}  // namespace mav::planning
