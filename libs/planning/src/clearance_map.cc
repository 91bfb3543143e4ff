#include "mav/planning/clearance_map.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace mav::planning {

bool Box::IsValid(const std::string& field, std::string* why) const {
  std::ostringstream msg;
  if (!min.allFinite()) {
    msg << field << ".min: not finite";
  } else if (!max.allFinite()) {
    msg << field << ".max: not finite";
  } else {
    for (int a = 0; a < 3; ++a) {
      if (!(min[a] < max[a])) {
        msg << field << ".max: must exceed " << field << ".min on every axis (axis "
            << "xyz"[a] << ": " << min[a] << " >= " << max[a] << ")";
        break;
      }
    }
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

double ClearanceMap::ValidFraction(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                   double required, double tolerance_m) const {
  const Box& box = bounds();
  const Eigen::Vector3d delta = b - a;
  const double length = delta.norm();
  const double tolerance = tolerance_m > 0 ? tolerance_m : kDefaultToleranceM;
  double s = 0, last_valid = 0;
  while (true) {
    const Eigen::Vector3d p = length > 0 ? Eigen::Vector3d(a + delta * (s / length)) : a;
    if (!box.Contains(p)) break;
    double c = ClearanceLowerBound(p);
    // Near the requirement the bound is too weak to step on: the exact value decides, and its
    // excess over the requirement is a safe step (the clearance is 1-Lipschitz). A step of a
    // quarter metre is plenty, so the exact search need not look farther.
    if (c < required + tolerance) {
      c = ClearanceUpTo(p, required + kMaxExactStepM);
      if (c < required) break;
    }
    last_valid = s;
    if (s >= length) return 1.0;
    s = std::min(length, s + std::max(c - required, tolerance));
  }
  return length > 0 ? last_valid / length : 0.0;
}

bool ClearanceMap::IsSegmentValid(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  double required, double tolerance_m) const {
  if (!bounds().Contains(a) || !bounds().Contains(b)) return false;
  return ValidFraction(a, b, required, tolerance_m) >= 1.0;
}

}  // namespace mav::planning
