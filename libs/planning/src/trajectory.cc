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

// Above this ratio of the limits the trajectory is slowed where it exceeds them and refitted;
// below it (or after the last repair) it is slowed uniformly.
constexpr double kUniformScaleRatio = 1.01;

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

// How long the lateral acceleration takes to build up on the way into a corner, s: the
// curvature ramps over this time at the corner's speed (an Euler spiral), so the spline, which
// cannot follow a jump of the curvature, does not overshoot it.
constexpr double kRampTimeS = 0.5;

// The curve rounding a corner: in the corner's plane the curvature ramps linearly from 0 to
// kappa over `ramp` metres, stays kappa, and ramps back; sampled every `step` of arc length.
struct CornerCurve {
  std::vector<Eigen::Vector3d> points;
  double step = 0, length = 0, kappa = 0, ramp = 0;

  double Curvature(double sigma) const {
    const double from_end = std::min(sigma, length - sigma);
    return ramp > 0 && from_end < ramp ? kappa * std::max(0.0, from_end) / ramp : kappa;
  }
  Eigen::Vector3d At(double sigma) const {
    const double f = std::clamp(sigma / step, 0.0, static_cast<double>(points.size() - 1));
    const size_t i = std::min(static_cast<size_t>(f), points.size() - 2);
    return points[i] + (f - i) * (points[i + 1] - points[i]);
  }
};

struct Piece {
  bool curve = false;
  double s0 = 0, length = 0;
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();  // line
  const CornerCurve* corner_curve = nullptr;                                 // curve
  int corner = -1;  // the polyline vertex a curve rounds
};

struct Corner {
  enum Kind { kStop, kStraight, kArc };
  Kind kind = kStop;   // a stop (the ends, waypoints, corners no curve fits), straight on, a curve
  double tangent = 0;  // distance of the curve's ends from the vertex, along the segments
  double radius = 0;   // at its middle, 1 / kappa
  CornerCurve curve;
};

// The curve rounding vertex b between a and c with radius `radius` at its middle and a ramp of
// `ramp` metres at either end (capped so the ramps alone do not turn more than the corner).
Corner MakeCorner(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                  double radius, double ramp) {
  Corner k;
  k.kind = Corner::kArc;
  k.radius = radius;
  const Eigen::Vector3d u1 = (b - a).normalized(), u2 = (c - b).normalized();
  const double angle = std::acos(std::clamp(u1.dot(u2), -1.0, 1.0));
  // Towards the inside: perpendicular to u1 in the corner's plane, on the side of u2.
  const Eigen::Vector3d inward = (u2 - u1.dot(u2) * u1).normalized();
  CornerCurve& curve = k.curve;
  curve.kappa = 1.0 / radius;
  curve.ramp = std::min(ramp, angle * radius);
  const double middle = angle * radius - curve.ramp;  // the constant-curvature part
  curve.length = 2 * curve.ramp + middle;
  const int steps = std::max(8, static_cast<int>(std::ceil(curve.length / 0.02)));
  curve.step = curve.length / steps;
  // Heading along the curve in closed form, positions by the midpoint rule, in the corner's
  // frame (x along u1, y inwards), starting at the origin.
  const auto heading = [&](double sigma) {
    const double kappa = curve.kappa, r = curve.ramp;
    if (sigma <= r) return r > 0 ? 0.5 * kappa * sigma * sigma / r : 0.0;
    if (sigma <= r + middle) return 0.5 * kappa * r + kappa * (sigma - r);
    const double rest = curve.length - sigma;
    return angle - (r > 0 ? 0.5 * kappa * rest * rest / r : 0.0);
  };
  std::vector<Eigen::Vector2d> local(steps + 1, Eigen::Vector2d::Zero());
  for (int i = 0; i < steps; ++i) {
    const double phi = heading((i + 0.5) * curve.step);
    local[i + 1] = local[i] + curve.step * Eigen::Vector2d(std::cos(phi), std::sin(phi));
  }
  // The vertex: where the end's tangent line meets the x axis; the curve is symmetric, so its
  // start is as far before the vertex as its end is after.
  const Eigen::Vector2d end = local.back();
  k.tangent = end.x() - end.y() / std::tan(angle);
  const Eigen::Vector3d start = b - k.tangent * u1;
  curve.points.resize(steps + 1);
  for (int i = 0; i <= steps; ++i) {
    curve.points[i] = start + local[i].x() * u1 + local[i].y() * inward;
  }
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
    if (p.curve) return p.corner_curve->At(u);
    return p.length > 0 ? Eigen::Vector3d(p.a + (p.b - p.a) * (u / p.length)) : p.a;
  }
  double Radius(double s) const {
    const Piece& p = PieceAt(s);
    const double kappa = p.curve ? p.corner_curve->Curvature(s - p.s0) : 0.0;
    return kappa > 0 ? 1.0 / kappa : std::numeric_limits<double>::infinity();
  }
};

// The rounded path of `path` with the corners `corners` (one per vertex; the ends are stops).
// The pieces point into `corners`, which must outlive the result.
RoundedPath BuildRoundedPath(const std::vector<Eigen::Vector3d>& path,
                             const std::vector<Corner>& corners) {
  RoundedPath r;
  const size_t n = path.size();
  double s = 0;
  r.stop_s.push_back(0);
  for (size_t i = 0; i + 1 < n; ++i) {
    Piece line;
    line.a = corners[i].kind == Corner::kArc ? corners[i].curve.points.back() : path[i];
    line.b =
        corners[i + 1].kind == Corner::kArc ? corners[i + 1].curve.points.front() : path[i + 1];
    line.s0 = s;
    line.length = (line.b - line.a).norm();
    s += line.length;
    r.pieces.push_back(line);
    if (i + 2 == n) break;
    const Corner& k = corners[i + 1];
    if (k.kind == Corner::kArc) {
      Piece curve;
      curve.curve = true;
      curve.corner_curve = &k.curve;
      curve.s0 = s;
      curve.length = k.curve.length;
      curve.corner = static_cast<int>(i + 1);
      s += curve.length;
      r.pieces.push_back(curve);
    } else if (k.kind == Corner::kStop) {
      r.stop_s.push_back(s);
    }
  }
  r.length = s;
  r.stop_s.push_back(s);
  return r;
}

// ---- The speed plan -------------------------------------------------------------------------

// Where the repairs act: windows of arc length where the speed limit, the accelerations or the
// knot spacing are cut (factors <= 1, multiplied where windows overlap).
struct Window {
  double s0, s1;
  double speed = 1, knot = 1, accel = 1;
};

double Factor(const std::vector<Window>& windows, double s, double Window::*factor) {
  double f = 1;
  for (const Window& w : windows) {
    if (s >= w.s0 && s <= w.s1) f *= w.*factor;
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
  std::vector<double> v_lim, curvature, from_stop, to_stop, accel_factor;
  for (size_t k = 0; k + 1 < r.stop_s.size(); ++k) {
    const double s0 = r.stop_s[k], s1 = r.stop_s[k + 1];
    const int steps = std::max(1, static_cast<int>(std::ceil((s1 - s0) / kStep)));
    for (int m = (k == 0 ? 0 : 1); m <= steps; ++m) {
      const double s = s0 + (s1 - s0) * m / steps;
      const double radius = r.Radius(s);
      const double accel = Factor(windows, s, &Window::accel);
      double lim = v_max * Factor(windows, s, &Window::speed);
      if (std::isfinite(radius)) lim = std::min(lim, std::sqrt(accel * a_lat * radius));
      if (m == 0 || m == steps) lim = 0;  // ends and stops
      p.s.push_back(s);
      v_lim.push_back(lim);
      curvature.push_back(std::isfinite(radius) ? 1.0 / radius : 0.0);
      from_stop.push_back(s - s0);
      to_stop.push_back(s1 - s);
      accel_factor.push_back(accel);
    }
  }
  const size_t n = p.s.size();
  // What is left of the tangential acceleration at speed v on curvature kappa, `d` from a stop.
  const auto tangential = [&](double v, double kappa, double d, double f) {
    const double lateral = v * v * kappa / (f * a_lat);
    const double ramp = std::cbrt(6 * jerk * jerk * std::max(d, 1e-4));
    return std::min(ramp, f * a_long) * std::sqrt(std::max(0.0, 1.0 - lateral * lateral));
  };
  p.v = v_lim;
  for (size_t m = 0; m + 1 < n; ++m) {
    const double ds = p.s[m + 1] - p.s[m];
    const double a = tangential(p.v[m], curvature[m], from_stop[m] + 0.5 * ds, accel_factor[m]);
    p.v[m + 1] = std::min(p.v[m + 1], std::sqrt(p.v[m] * p.v[m] + 2 * a * ds));
  }
  for (size_t m = n - 1; m > 0; --m) {
    const double ds = p.s[m] - p.s[m - 1];
    const double a = tangential(p.v[m], curvature[m], to_stop[m] + 0.5 * ds, accel_factor[m]);
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
      local.push_back(at + interval * Factor(windows, p.SAt(at), &Window::knot));
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
  std::vector<double> violation_times;  // closer than the required clearance
  // Samples over a limit: time, and the ratio of the speed and of the accelerations (>= 1 for the
  // one exceeded; square roots for the accelerations).
  struct Over {
    double t, speed, accel;
  };
  std::vector<Over> over_limits;
  Eigen::Vector3d worst = Eigen::Vector3d::Zero();
  std::vector<std::pair<double, Eigen::Vector3d>> samples;  // (clearance lower bound, position)
};

// Evaluates a trajectory at increasing times without searching for the segment each time.
class Walker {
 public:
  explicit Walker(const PolynomialTrajectory& t) : t_(t) {}
  // Position, velocity and (when `a` is given) acceleration at time `time` >= the last one.
  void At(double time, Eigen::Vector3d* p, Eigen::Vector3d* v, Eigen::Vector3d* a) {
    const auto& segments = t_.segments();
    while (i_ + 1 < segments.size() && time >= start_ + segments[i_].duration_s) {
      start_ += segments[i_].duration_s;
      ++i_;
    }
    const double tau = std::clamp(time - start_, 0.0, segments[i_].duration_s);
    const Eigen::Matrix<double, 3, 6>& c = segments[i_].coefficients;
    for (int axis = 0; axis < 3; ++axis) {
      (*p)[axis] = geometry::EvaluatePolynomial(c.row(axis).transpose(), tau, 0);
      (*v)[axis] = geometry::EvaluatePolynomial(c.row(axis).transpose(), tau, 1);
      if (a) (*a)[axis] = geometry::EvaluatePolynomial(c.row(axis).transpose(), tau, 2);
    }
  }

 private:
  const PolynomialTrajectory& t_;
  size_t i_ = 0;
  double start_ = 0;
};

// Clearance at spatial steps <= check_step (positions and speeds), limits every 5 ms.
CheckResult CheckTrajectory(const ClearanceMap& map, const PolynomialTrajectory& traj,
                            const SpeedLimits& limits, double required, double check_step) {
  constexpr double kLimitStep = 0.005;
  CheckResult r;
  const double duration = traj.duration_s();
  const double a_any = std::max(limits.max_acceleration_mps2, limits.max_lateral_acceleration_mps2);
  Walker walker(traj);
  Eigen::Vector3d p, v, a, previous = traj.Evaluate(0).position;
  double t = 0, next_limit_t = 0;
  bool last = false;
  while (true) {
    const bool limits_now = t >= next_limit_t || last;
    walker.At(t, &p, &v, limits_now ? &a : nullptr);
    const double speed = v.norm();
    r.max_speed = std::max(r.max_speed, speed);
    r.length += (p - previous).norm();
    previous = p;
    if (limits_now) {
      next_limit_t = t + kLimitStep;
      r.max_acceleration = std::max(r.max_acceleration, a.norm());
      const double speed_ratio = speed / limits.max_speed_mps;
      double accel_ratio;
      if (speed > 0.3) {
        const Eigen::Vector3d dir = v / speed;
        const double along = a.dot(dir);
        const double across = (a - along * dir).norm();
        accel_ratio = std::max(std::sqrt(std::abs(along) / limits.max_acceleration_mps2),
                               std::sqrt(across / limits.max_lateral_acceleration_mps2));
      } else {
        accel_ratio = std::sqrt(a.norm() / a_any);
      }
      const double ratio = std::max(speed_ratio, accel_ratio);
      r.limit_ratio = std::max(r.limit_ratio, ratio);
      if (ratio > 1.0) r.over_limits.push_back({t, speed_ratio, accel_ratio});
    }
    if (!map.IsValid(p, required)) {
      if (r.violation_times.empty()) r.worst = p;
      r.violation_times.push_back(t);
    }
    r.samples.emplace_back(map.ClearanceLowerBound(p), p);
    if (last) break;
    // Spatial steps below check_step: over 10 ms the speed changes by < 0.5 m/s.
    t += std::min(0.01, check_step / (speed + 0.5));
    if (t >= duration) {
      t = duration;
      last = true;
    }
  }
  return r;
}

// The exact minimum clearance over the check's samples: by increasing lower bound, until the
// bound passes the best exact value found.
double MinClearance(const ClearanceMap& map, CheckResult* check) {
  auto& samples = check->samples;
  std::sort(samples.begin(), samples.end(),
            [](const auto& x, const auto& y) { return x.first < y.first; });
  double best = std::numeric_limits<double>::infinity();
  for (const auto& [bound, p] : samples) {
    if (bound >= best) break;
    best = std::min(best, map.ClearanceUpTo(p, best));
  }
  return best;
}

// Whether every sample of the corner's curve (<= 2 cm apart) keeps `clearance`.
bool CurveValid(const ClearanceMap& map, const Corner& k, double clearance) {
  for (const Eigen::Vector3d& p : k.curve.points) {
    if (!map.IsValid(p, clearance)) return false;
  }
  return true;
}

// The widest curve for the corner b between a and c, radius at most `radius`, ramps of
// kRampTimeS at the speed the radius allows (`lateral` m/s^2, at most `v_max`). A taut path
// touches the obstacles at its corners, where a curve tangent to both segments would cut inside;
// so the vertex is first moved outwards along the bisector by the curve's cut (the distance
// from the vertex to the curve's middle), which puts that middle back on b. Radii shrink by
// 30 % until the curve and the straight pieces to a and c keep `clearance` (and the curve's ends
// fit in the shares `in_share`, `out_share` of the segments); with no curve at all the corner
// is a stop (kind kStop). *moved_b is the vertex the curve belongs to.
Corner FitCorner(const ClearanceMap& map, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                 const Eigen::Vector3d& c, double in_share, double out_share, double radius,
                 double lateral, double v_max, double clearance, Eigen::Vector3d* moved_b) {
  const Eigen::Vector3d u1 = (b - a).normalized(), u2 = (c - b).normalized();
  const Eigen::Vector3d outward = (u1 - u2).normalized();
  for (int shrink = 0; shrink < 24 && radius > 0.01; ++shrink, radius *= 0.7) {
    const double ramp = std::min(v_max, std::sqrt(lateral * radius)) * kRampTimeS;
    const Corner plain = MakeCorner(a, b, c, radius, ramp);
    const double cut = std::min(1.0, (plain.curve.At(0.5 * plain.curve.length) - b).norm());
    for (const double push : {cut, 0.0}) {
      const Eigen::Vector3d v = b + push * outward;
      Corner k = push > 0 ? MakeCorner(a, v, c, radius, ramp) : plain;
      if (k.tangent > (v - a).norm() * in_share || k.tangent > (c - v).norm() * out_share) continue;
      if (!CurveValid(map, k, clearance)) continue;
      if (push > 0 && (!map.IsSegmentValid(a, k.curve.points.front(), clearance) ||
                       !map.IsSegmentValid(k.curve.points.back(), c, clearance))) {
        continue;
      }
      *moved_b = v;
      return k;
    }
  }
  *moved_b = b;
  return Corner{};
}

// Corners a few metres apart that turn the same way (the shortening wraps an obstacle with
// several vertices) leave room only for small arcs. Where the segments before the first and after
// the last of up to four such vertices, extended, pass each other beyond both (closer than 2 cm +
// 15 % of the run's length: in 3-D they are skew), the run becomes one vertex there, if the two
// new segments keep `clearance`. Longer runs are tried first.
void MergeCloseCorners(const ClearanceMap& map, double run_m, double clearance,
                       std::vector<Eigen::Vector3d>* points, std::vector<bool>* pinned) {
  std::vector<Eigen::Vector3d>& p = *points;
  for (bool merged = true; merged;) {
    merged = false;
    for (size_t i = 1; i + 2 < p.size() && !merged; ++i) {
      for (size_t j = std::min(i + 3, p.size() - 2); j > i && !merged; --j) {
        bool movable = true;
        double run = 0;
        for (size_t k = i; k <= j; ++k) movable = movable && !(*pinned)[k];
        for (size_t k = i; k < j; ++k) run += (p[k + 1] - p[k]).norm();
        if (!movable || run > run_m) continue;
        // Closest points of p[i-1] + s (p[i] - p[i-1]) and p[j+1] + t (p[j] - p[j+1]).
        const Eigen::Vector3d d1 = p[i] - p[i - 1], d2 = p[j] - p[j + 1];
        const Eigen::Vector3d w = p[i - 1] - p[j + 1];
        const double aa = d1.dot(d1), bb = d1.dot(d2), cc = d2.dot(d2), dd = d1.dot(w),
                     ee = d2.dot(w);
        const double den = aa * cc - bb * bb;
        if (den < 1e-12 * aa * cc) continue;  // parallel
        const double s = (bb * ee - cc * dd) / den, t = (aa * ee - bb * dd) / den;
        if (s <= 1 || t <= 1) continue;
        const Eigen::Vector3d q1 = p[i - 1] + s * d1, q2 = p[j + 1] + t * d2;
        if ((q1 - q2).norm() > 0.02 + 0.15 * run || (q1 - p[i]).norm() > run + 0.5) continue;
        const Eigen::Vector3d q = 0.5 * (q1 + q2);
        if (!map.IsSegmentValid(p[i - 1], q, clearance) ||
            !map.IsSegmentValid(q, p[j + 1], clearance)) {
          continue;
        }
        p[i] = q;
        p.erase(p.begin() + i + 1, p.begin() + j + 1);
        pinned->erase(pinned->begin() + i + 1, pinned->begin() + j + 1);
        merged = true;
      }
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
  MergeCloseCorners(map, 6.0, corner_clearance, &points, &pinned);
  const SpeedLimits& limits = options.limits;
  const double radius_cap =
      limits.max_speed_mps * limits.max_speed_mps / limits.max_lateral_acceleration_mps2;

  TrajectoryResult result;
  std::vector<double> corner_scale(points.size(), 1.0);  // shrinks arcs that caused violations
  std::vector<Window> windows;
  for (int attempt = 0;; ++attempt) {
    MAV_RETURN_IF_ERROR(stop.Check("trajectory"));
    int64_t t0 = MonotonicNowNs();
    // 1. Corners, each from the previous (possibly moved) vertex to the next original one. A
    // segment between two corners is shared in proportion to the tangent lengths their widest
    // arcs would want (a gentle bend next to a sharp one leaves it most of the segment).
    const size_t n = points.size();
    std::vector<double> wanted(n, 0.0);
    for (size_t i = 1; i + 1 < n; ++i) {
      if (pinned[i]) continue;
      const double turn = std::acos(std::clamp(
          (points[i] - points[i - 1]).normalized().dot((points[i + 1] - points[i]).normalized()),
          -1.0, 1.0));
      const double radius = radius_cap * corner_scale[i];
      wanted[i] = radius * std::tan(0.5 * std::min(turn, 3.0)) +
                  0.5 * std::min(turn * radius, limits.max_speed_mps * kRampTimeS);
    }
    const auto share = [&](size_t mine, size_t other) {
      if (pinned[other]) return 0.95;
      const double total = wanted[mine] + wanted[other];
      return total > 0 ? std::min(0.95, wanted[mine] / total) : 0.5;
    };
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
      // The previous corner already took its tangent from segment i-1: what is left is ours.
      const double used = corners[i - 1].kind == Corner::kArc ? corners[i - 1].tangent : 0.0;
      const double in_length = (b - a).norm();
      const double in_share =
          std::min(share(i, i - 1), std::max(0.0, in_length - used) / std::max(in_length, 1e-9));
      corners[i] = FitCorner(map, a, b, c, in_share, share(i, i + 1), radius_cap * corner_scale[i],
                             0.92 * limits.max_lateral_acceleration_mps2, limits.max_speed_mps,
                             corner_clearance, &moved[i]);
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

    // 4. Check. Limits first repaired where they are exceeded (a local slow-down), the small
    // rest by a uniform time scale; clearance violations by closer knots, a lower speed and
    // smaller arcs around them.
    t0 = MonotonicNowNs();
    CheckResult check = CheckTrajectory(map, trajectory, limits, required, options.check_step_m);
    const bool clear = check.violation_times.empty();
    const bool last = attempt >= options.max_refits;
    double scale = 1;
    if (clear && (check.limit_ratio <= kUniformScaleRatio || last)) {
      if (check.limit_ratio > 1.0) {
        scale = check.limit_ratio * 1.0005;
        trajectory = TimeScaled(trajectory, scale);
        check = CheckTrajectory(map, trajectory, limits, required, options.check_step_m);
      }
      result.min_clearance_m = MinClearance(map, &check);
      result.check_ms += MsSince(t0);
      result.trajectory = std::move(trajectory);
      result.duration_s = result.trajectory.duration_s();
      result.length_m = check.length;
      result.max_speed_mps = check.max_speed;
      result.mean_speed_mps = result.duration_s > 0 ? check.length / result.duration_s : 0;
      result.max_acceleration_mps2 = check.max_acceleration;
      result.time_scale = scale;
      result.refits = attempt;
      return result;
    }
    result.check_ms += MsSince(t0);
    if (!clear && last) {
      std::ostringstream msg;
      msg << "trajectory: the spline still comes closer than " << required
          << " m to an obstacle near (" << check.worst.transpose() << ") after " << attempt
          << " repairs";
      return Status::FailedPrecondition(msg.str());
    }
    std::vector<double> where;
    for (double t : check.violation_times) {
      const double s = profile.SAt(t);
      if (where.empty() || s > where.back() + 1.0) where.push_back(s);
    }
    for (double s : where) {
      Window w{s - 2.0, s + 2.0};
      w.speed = 0.75;
      w.knot = 0.5;
      windows.push_back(w);
      for (const Piece& p : rounded.pieces) {
        if (p.curve && p.s0 <= s + 2.0 && p.s0 + p.length >= s - 2.0) corner_scale[p.corner] *= 0.5;
      }
    }
    // Over a limit: where the speed is exceeded the speed limit there drops by the ratio; where an
    // acceleration is (the spline overshoots the speed plan's acceleration steps), the
    // accelerations there drop by its square.
    for (size_t k = 0; k < check.over_limits.size();) {
      const double s0 = profile.SAt(check.over_limits[k].t);
      double speed = 1, accel = 1;
      size_t m = k;
      while (m < check.over_limits.size() && profile.SAt(check.over_limits[m].t) < s0 + 1.5) {
        speed = std::max(speed, check.over_limits[m].speed);
        accel = std::max(accel, check.over_limits[m].accel);
        ++m;
      }
      Window w{s0 - 1.5, profile.SAt(check.over_limits[m - 1].t) + 1.5};
      w.speed = 0.99 / speed;
      w.accel = 0.98 / (accel * accel);
      windows.push_back(w);
      k = m;
    }
  }
}

}  // namespace mav::planning
