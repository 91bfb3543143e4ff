#include "mav/planning/path.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace mav::planning {
namespace {

bool NonNegativeFinite(double v) { return std::isfinite(v) && v >= 0; }

// Lower bound of SegmentCost (the proximity term is >= 0): lets the shortening skip checks.
double SegmentCostLowerBound(const CostWeights& w, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b) {
  return w.length * (b - a).norm() + w.altitude * std::abs(b.z() - a.z());
}

// Minimum clearance along [a, b]: samples every half cell, the exact value only where the cheap
// bound could beat the best so far, then 1 cm steps around the best sample.
double SegmentMinClearance(const ClearanceMap& map, const Eigen::Vector3d& a,
                           const Eigen::Vector3d& b, double best) {
  const double length = (b - a).norm();
  const double step = 0.5 * map.resolution();
  const int n = std::max(1, static_cast<int>(std::ceil(length / step)));
  int best_k = -1;
  for (int k = 0; k <= n; ++k) {
    const Eigen::Vector3d p = a + (b - a) * (static_cast<double>(k) / n);
    if (map.ClearanceLowerBound(p) >= best + step) continue;
    const double c = map.ClearanceUpTo(p, best);
    if (c < best) {
      best = c;
      best_k = k;
    }
  }
  if (best_k >= 0 && length > 0) {
    const double s0 = std::max(0.0, (best_k - 1.0) / n * length);
    const double s1 = std::min(length, (best_k + 1.0) / n * length);
    for (double s = s0; s <= s1; s += 0.01) {
      best = std::min(best, map.ClearanceUpTo(a + (b - a) * (s / length), best));
    }
  }
  return best;
}

}  // namespace

bool CostWeights::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!NonNegativeFinite(length)) {
    msg << "length: must be finite and >= 0, got " << length;
  } else if (!NonNegativeFinite(clearance)) {
    msg << "clearance: must be finite and >= 0, got " << clearance;
  } else if (!NonNegativeFinite(altitude)) {
    msg << "altitude: must be finite and >= 0, got " << altitude;
  } else if (length == 0 && clearance == 0 && altitude == 0) {
    msg << "length: the weights cannot all be 0";
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

bool ShortenOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!(max_cost_increase >= 0 && max_cost_increase <= 10)) {
    msg << "max_cost_increase: must be in [0, 10], got " << max_cost_increase;
  } else if (!NonNegativeFinite(required_clearance_m)) {
    msg << "required_clearance_m: must be finite and >= 0, got " << required_clearance_m;
  } else if (!NonNegativeFinite(tolerance_m) || tolerance_m > 1) {
    msg << "tolerance_m: must be in [0, 1] m, got " << tolerance_m;
  } else if (corner_passes < 0 || corner_passes > 100) {
    msg << "corner_passes: must be in [0, 100], got " << corner_passes;
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

double ProximityPenalty(double clearance_m, double max_distance_m) {
  if (clearance_m >= max_distance_m) return 0.0;
  return 1.0 / std::max(clearance_m, 1e-3) - 1.0 / max_distance_m;
}

double SegmentProximity(const ClearanceMap& map, const Eigen::Vector3d& a,
                        const Eigen::Vector3d& b) {
  const double length = (b - a).norm();
  if (length == 0) return 0;
  const double max_distance = map.max_distance();
  const int n = std::max(1, static_cast<int>(std::ceil(length / (0.5 * map.resolution()))));
  double sum = 0;
  for (int k = 0; k <= n; ++k) {
    const double rho = ProximityPenalty(
        map.ApproximateClearance(a + (b - a) * (static_cast<double>(k) / n)), max_distance);
    sum += (k == 0 || k == n) ? 0.5 * rho : rho;
  }
  return sum * length / n;
}

double SegmentCost(const ClearanceMap& map, const CostWeights& w, const Eigen::Vector3d& a,
                   const Eigen::Vector3d& b) {
  return SegmentCostLowerBound(w, a, b) +
         (w.clearance > 0 ? w.clearance * SegmentProximity(map, a, b) : 0.0);
}

double PathLength(const std::vector<Eigen::Vector3d>& path) {
  double length = 0;
  for (size_t i = 1; i < path.size(); ++i) length += (path[i] - path[i - 1]).norm();
  return length;
}

PathCost EvaluatePathCost(const ClearanceMap& map, const CostWeights& w,
                          const std::vector<Eigen::Vector3d>& path) {
  PathCost cost;
  cost.min_clearance_m = path.empty() ? 0 : map.Clearance(path.front());
  for (size_t i = 1; i < path.size(); ++i) {
    const Eigen::Vector3d& a = path[i - 1];
    const Eigen::Vector3d& b = path[i];
    cost.length_m += (b - a).norm();
    cost.altitude_change_m += std::abs(b.z() - a.z());
    cost.clearance_cost += SegmentProximity(map, a, b);
    cost.total += SegmentCost(map, w, a, b);
    cost.min_clearance_m = SegmentMinClearance(map, a, b, cost.min_clearance_m);
  }
  return cost;
}

std::vector<Eigen::Vector3d> ShortenPath(const ClearanceMap& map, const CostWeights& w,
                                         const std::vector<Eigen::Vector3d>& raw,
                                         const ShortenOptions& options, const Termination& stop) {
  if (raw.size() <= 2) return raw;
  const double required =
      options.required_clearance_m > 0 ? options.required_clearance_m : map.robot_radius();
  const double tolerance =
      options.tolerance_m > 0 ? options.tolerance_m : ClearanceMap::kDefaultToleranceM;
  const auto cost = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return SegmentCost(map, w, a, b);
  };

  // The current path and its segment costs; `total` is always their sum.
  std::vector<Eigen::Vector3d> path = raw;
  std::vector<double> seg(path.size() - 1);
  double total = 0;
  for (size_t i = 0; i + 1 < path.size(); ++i) total += seg[i] = cost(path[i], path[i + 1]);
  const double bound = (1.0 + options.max_cost_increase) * total;

  // 1. Vertex shortcuts: from each kept vertex to the farthest valid one within the bound.
  const auto vertex_shortcuts = [&] {
    std::vector<double> prefix(path.size(), 0.0);  // cost from path[0] to path[k]
    for (size_t k = 1; k < path.size(); ++k) prefix[k] = prefix[k - 1] + seg[k - 1];
    std::vector<Eigen::Vector3d> out = {path.front()};
    std::vector<double> out_seg;
    size_t i = 0;
    while (i + 1 < path.size()) {
      size_t next = i + 1;
      double next_cost = seg[i];
      for (size_t j = path.size() - 1; j >= i + 2 && !stop.ShouldStop(); --j) {
        const double replaced = prefix[j] - prefix[i];
        if (total - replaced + SegmentCostLowerBound(w, path[i], path[j]) > bound) continue;
        if (!map.IsSegmentValid(path[i], path[j], required, tolerance)) continue;
        const double c = cost(path[i], path[j]);
        if (total - replaced + c > bound) continue;
        total += c - replaced;
        next = j;
        next_cost = c;
        break;
      }
      out.push_back(path[next]);
      out_seg.push_back(next_cost);
      i = next;
    }
    path = std::move(out);
    seg = std::move(out_seg);
  };
  vertex_shortcuts();

  // 2. Corner cutting, until a pass saves less than a centimetre.
  for (int pass = 0; pass < options.corner_passes && path.size() > 2; ++pass) {
    if (stop.ShouldStop()) break;
    const double length_before = PathLength(path);
    std::vector<Eigen::Vector3d> out = {path.front()};
    std::vector<double> out_seg;
    double ab_cost = seg[0];  // cost of the segment from out.back() to path[i]
    for (size_t i = 1; i + 1 < path.size(); ++i) {
      const Eigen::Vector3d a = out.back(), b = path[i], c = path[i + 1];
      const double bc_cost = seg[i];
      const double base = total - ab_cost - bc_cost;
      // The whole corner first (t = 1: a straight to c).
      if (map.IsSegmentValid(a, c, required, tolerance)) {
        const double ac = cost(a, c);
        if (base + ac <= bound) {
          total = base + ac;
          ab_cost = ac;
          continue;
        }
      }
      // Bisection on the cut fraction t: p = b + t (a - b), q = b + t (c - b).
      double lo = 0, hi = 1, lo_ap = 0, lo_pq = 0, lo_qc = 0;
      for (int it = 0; it < 6; ++it) {
        const double t = 0.5 * (lo + hi);
        const Eigen::Vector3d p = b + t * (a - b), q = b + t * (c - b);
        bool ok = map.IsSegmentValid(p, q, required, tolerance);
        double ap = 0, pq = 0, qc = 0;
        if (ok) {
          ap = cost(a, p);
          pq = cost(p, q);
          qc = cost(q, c);
          ok = base + ap + pq + qc <= bound;
        }
        if (ok) {
          lo = t;
          lo_ap = ap;
          lo_pq = pq;
          lo_qc = qc;
        } else {
          hi = t;
        }
      }
      // A cut shorter than a millimetre is not worth two more vertices.
      if (lo > 0 && lo * std::min((a - b).norm(), (c - b).norm()) > 1e-3) {
        out.push_back(b + lo * (a - b));
        out_seg.push_back(lo_ap);
        out.push_back(b + lo * (c - b));
        out_seg.push_back(lo_pq);
        total = base + lo_ap + lo_pq + lo_qc;
        ab_cost = lo_qc;
      } else {
        out.push_back(b);
        out_seg.push_back(ab_cost);
        ab_cost = bc_cost;
      }
    }
    out.push_back(path.back());
    out_seg.push_back(ab_cost);
    path = std::move(out);
    seg = std::move(out_seg);
    if (length_before - PathLength(path) < 0.01) break;
  }
  // The cuts leave nearly collinear vertices behind: drop each whose neighbours see each other
  // (a local check: the global shortcuts would start many checks at vertices that touch the
  // obstacles, the expensive case).
  for (size_t i = 1; i + 1 < path.size() && options.corner_passes > 0;) {
    const Eigen::Vector3d u = (path[i] - path[i - 1]).normalized();
    const Eigen::Vector3d v = (path[i + 1] - path[i]).normalized();
    if (u.dot(v) > std::cos(0.01)) {
      const double c = cost(path[i - 1], path[i + 1]);
      if (total - seg[i - 1] - seg[i] + c <= bound &&
          map.IsSegmentValid(path[i - 1], path[i + 1], required, tolerance)) {
        total += c - seg[i - 1] - seg[i];
        seg[i - 1] = c;
        seg.erase(seg.begin() + i);
        path.erase(path.begin() + i);
        continue;
      }
    }
    ++i;
  }
  return path;
}

}  // namespace mav::planning
