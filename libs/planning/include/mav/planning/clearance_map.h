#pragma once
// What the planners see of the world: the clearance of a point (its distance to the nearest
// obstacle) inside a planning volume. Like OMPL's StateValidityChecker (Sucan, Moll, Kavraki,
// "The Open Motion Planning Library", IEEE RAM 2012), the roadmap, the searches, the shortening
// and the trajectory check never see the map's representation: PlanningMap (planning_map.h)
// implements this interface on an OctoMap, tests implement it on analytic shapes.
//
// Frames and units: points are in the world frame (z up), metres.
//
// Validity: a point p is valid for a required clearance c when it lies in bounds() and
// Clearance(p) >= c; the planners use c = robot_radius() (plus a small planning margin, see
// roadmap.h). A segment is valid when every point on it is; IsSegmentValid() decides that with
// steps of at most `tolerance_m` where the clearance is within `tolerance_m` of c and with the
// safe step Clearance - c elsewhere (the clearance is 1-Lipschitz: it changes by at most the
// distance moved), so a valid segment never dips more than tolerance_m / 2 below c.

#include <cstdint>
#include <string>

#include <Eigen/Core>

namespace mav::planning {

// An axis-aligned box in the world frame, metres. Contains() includes the faces.
struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();

  bool Contains(const Eigen::Vector3d& p) const {
    return (p.array() >= min.array()).all() && (p.array() <= max.array()).all();
  }
  Eigen::Vector3d size() const { return max - min; }
  // false (with `why` naming "<field>.min"/"<field>.max") for non-finite corners or min >= max
  // on an axis.
  bool IsValid(const std::string& field, std::string* why) const;
};

class ClearanceMap {
 public:
  // Step of the segment checks where the clearance is close to the requirement, m. 1 cm, the
  // resolution the trajectories are checked at, so a valid segment dips at most 5 mm below.
  static constexpr double kDefaultToleranceM = 0.01;
  // The largest step a segment check takes from an exact clearance value, m.
  static constexpr double kMaxExactStepM = 0.25;

  virtual ~ClearanceMap() = default;

  // Euclidean distance (m) from p to the nearest obstacle, saturated at max_distance(): exact
  // below it. 0 inside an obstacle and outside the map's grid.
  virtual double Clearance(const Eigen::Vector3d& p) const = 0;
  // min(Clearance(p), limit), exact; cheaper than Clearance() when the limit is small (the
  // search for the nearest obstacle stops at the limit). The default calls Clearance().
  virtual double ClearanceUpTo(const Eigen::Vector3d& p, double limit) const {
    const double c = Clearance(p);
    return c < limit ? c : limit;
  }
  // A cheap lower bound of Clearance(p) (one look-up); the default is Clearance(p) itself.
  virtual double ClearanceLowerBound(const Eigen::Vector3d& p) const { return Clearance(p); }
  // Clearance(p) >= required, usually decided from the lower bound alone. The default calls
  // Clearance(); implementations may stop looking once an obstacle closer than `required` is
  // found.
  virtual bool HasClearance(const Eigen::Vector3d& p, double required) const {
    return Clearance(p) >= required;
  }
  // A fast approximation of Clearance (m) for path costs (PlanningMap: the distance map at the
  // nearest cell centre, within half a cell diagonal of the exact value).
  virtual double ApproximateClearance(const Eigen::Vector3d& p) const { return Clearance(p); }

  // The planning volume: states outside it are invalid.
  virtual const Box& bounds() const = 0;
  // Size of the map's cells, m (the finest detail the planners must respect).
  virtual double resolution() const = 0;
  // Radius of a sphere containing the vehicle, m: the clearance a state needs to be valid.
  virtual double robot_radius() const = 0;
  // Saturation of Clearance(), m (> robot_radius()).
  virtual double max_distance() const = 0;
  // Identifies the obstacles, the volume and the radius: a roadmap built on one map is accepted
  // on another only when the fingerprints agree.
  virtual uint64_t fingerprint() const = 0;

  // In bounds() and Clearance(p) >= required.
  bool IsValid(const Eigen::Vector3d& p, double required) const {
    return bounds().Contains(p) && HasClearance(p, required);
  }
  bool IsValid(const Eigen::Vector3d& p) const { return IsValid(p, robot_radius()); }

  // Whether every point of the segment [a, b] is valid for `required` (see the file comment for
  // the tolerance). Also false when a or b is outside bounds() (the volume is convex, so the
  // ends decide).
  bool IsSegmentValid(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double required,
                      double tolerance_m = kDefaultToleranceM) const;
  // The same, walking from a towards b, returning the fraction in [0, 1] of the segment known to
  // be valid before the first invalid point (1 when the whole segment is valid; 0 when a is
  // invalid). OMPL's checkMotion(s1, s2, lastValid) semantics.
  double ValidFraction(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double required,
                       double tolerance_m = kDefaultToleranceM) const;
};

}  // namespace mav::planning
