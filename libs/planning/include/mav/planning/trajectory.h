#pragma once
// From a shortened path to a flyable reference: "a speed plan is calculated based on the path
// curvature. The resulting path and timing information are used to fit the quintic spline used
// for feedforward control" (Holzmann et al. 2015, Sec. 3), the polynomial approach of Richter,
// Bry, Roy, "Polynomial trajectory planning for aggressive quadrotor flight in dense indoor
// environments" (ISRR 2013): a geometric path first, then a smooth time-parameterised fit.
//
// 1. Corners: nearly collinear vertices are dropped (simplify_tolerance_m); runs of up to four
//    corners within 6 m turning the same way become one where the outer segments meet (when the
//    new segments are valid); every other corner (except the ends and the stops) gets the widest
//    curve tangent to both segments whose curvature ramps linearly from 0 to 1/R over 0.5 s at
//    the corner's speed (an Euler spiral), stays 1/R and ramps back, R <= v_max^2 / a_lat. The
//    vertex is first moved outwards by the curve's cut, so the curve's middle stays on the taut
//    path; a segment between two corners is shared in proportion to what their curves want;
//    curves keep corner_clearance_m. Where no curve fits, the corner becomes a stop.
// 2. Speed plan on the rounded path, sampled every 5 cm of arc length: v <= v_max on lines,
//    v <= sqrt(a_lat / kappa) on the curves, v = 0 at the ends and stops, and forward and
//    backward passes v_{k+1}^2 <= v_k^2 + 2 a_t ds with the tangential acceleration left by the
//    lateral one, a_t = a_long * sqrt(1 - (v^2 kappa / a_lat)^2) (a friction ellipse, so the
//    total acceleration never exceeds max(a_long, a_lat)), ramped up near the stops
//    (max_jerk_mps3); planned at 97 % of v_max and 92 % of the accelerations.
// 3. Spline: knots every knot_interval_s of the timed path (and at every stop), positions at the
//    knots from the speed plan, and the C4 quintic spline through them with v = a = 0 at both
//    ends (FitQuinticSpline).
// 4. Check of the final spline, not only of the polyline: speed and accelerations every 5 ms,
//    clearance at spatial steps <= check_step_m (1 cm). Where a limit is exceeded by more than
//    1 % the speed limit or the accelerations there are cut by the excess and the fit is redone;
//    a smaller excess is removed by the smallest uniform time scale (positions unchanged, v
//    scales by 1/k, a by 1/k^2). Where the spline comes closer than required_clearance_m, the
//    knots there are doubled, the speed limit there is cut and the curves near it shrink, and
//    the fit is redone; up to max_refits repairs in all. A trajectory that still violates the
//    clearance is never returned.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/geometry/polynomial_trajectory.h"
#include "mav/planning/clearance_map.h"

namespace mav::planning {

// Dynamic limits of the speed plan. Defaults for the AscTec Firefly (1.5 kg, six rotors of
// 8.54858e-6 N/(rad/s)^2 at up to 838 rad/s: 36 N of thrust, thrust-to-weight 2.4): a total
// acceleration of at most 6 m/s^2 needs m * |a + g| <= 1.5 * 11.5 = 17.2 N horizontally (a tilt
// of 31 deg) and at most 1.5 * 14.8 = 22.2 N climbing at 5 m/s^2, i.e. <= 62 % of the thrust:
// the rest is left to the controller (attitude changes, wind, rotor drag). docs/planning.md
// explains the choice.
struct SpeedLimits {
  // Speed along the path, m/s. 10 m/s: the paper flew 7.7 m/s peaks; at 10 m/s the Firefly's
  // rotor drag (~2 N) is still well inside its thrust margin. Validated (0, 20].
  double max_speed_mps = 10.0;
  // Acceleration along the path (speeding up and braking), m/s^2. Validated (0, 20].
  double max_acceleration_mps2 = 6.0;
  // Centripetal acceleration v^2 / R that sets the speed from the curvature, m/s^2 (31 deg of
  // tilt). Validated (0, 20].
  double max_lateral_acceleration_mps2 = 7.0;
  // How fast the acceleration may build up when leaving and approaching a stop, m/s^3: the speed
  // plan ramps the acceleration as a = (6 j^2 s)^(1/3) over the first metres (s from the stop),
  // the profile of a constant jerk j, so the spline (at rest with a = 0 at its ends) can follow
  // it. 15 m/s^3 means tilting by ~5 deg per 0.1 s. Validated (0, 200].
  double max_jerk_mps3 = 15.0;

  bool IsValid(std::string* why) const;
};

struct TrajectoryOptions {
  SpeedLimits limits;
  // Clearance every point of the spline keeps, m; 0 = the map's robot radius.
  double required_clearance_m = 0;
  // Clearance the corner curves keep, m; 0 = required_clearance_m + 0.05 (room for the spline's
  // deviation from the rounded path; the planner passes the radius plus half its margin).
  double corner_clearance_m = 0;
  // Vertices of the path closer than this to the chord of their neighbours are dropped first
  // (Douglas-Peucker; a chord must keep corner_clearance_m), m. 0.03 m: less than the room the
  // planners' clearance margin leaves. Validated [0, 1].
  double simplify_tolerance_m = 0.03;
  // Time between the spline's knots, s. 0.25 s: short enough for the spline to follow the corner
  // curves within millimetres, long enough to keep its jerk low.
  // Validated [0.02, 2].
  double knot_interval_s = 0.25;
  // Spatial step of the clearance check of the spline, m. Validated (0, 0.05].
  double check_step_m = 0.01;
  // Repairs (of clearance violations and of limits exceeded by more than 1 %) before giving up
  // on the clearance (a limit excess left then is removed by the time scale). Validated [0, 50].
  int max_refits = 12;
  geometry::YawPolicy yaw_policy = geometry::YawPolicy::kConstant;
  double start_yaw_rad = 0;

  bool IsValid(std::string* why) const;
};

struct TrajectoryResult {
  geometry::PolynomialTrajectory trajectory;
  double duration_s = 0;
  double length_m = 0;  // of the spline (sampled)
  double max_speed_mps = 0;
  double mean_speed_mps = 0;  // length / duration
  double max_acceleration_mps2 = 0;
  double min_clearance_m = 0;  // over the clearance-check samples
  double time_scale = 1;       // uniform slow-down applied for the limits (>= 1)
  int refits = 0;              // clearance repairs needed
  double speed_plan_ms = 0;    // corners + speed plan (all attempts)
  double spline_ms = 0;        // spline fits (all attempts)
  double check_ms = 0;         // limit and clearance checks (all attempts)
};

// The trajectory through `path` (>= 2 points, every segment valid for the required clearance),
// at rest at both ends and at path[i] for every i in `stops`. INVALID_ARGUMENT: fewer than two
// points, non-finite points, bad options; FAILED_PRECONDITION: still violating the clearance
// after max_refits repairs (the message says where); DEADLINE_EXCEEDED / CANCELLED from `stop`.
Result<TrajectoryResult> PlanTrajectory(const ClearanceMap& map,
                                        const std::vector<Eigen::Vector3d>& path,
                                        const std::vector<size_t>& stops,
                                        const TrajectoryOptions& options,
                                        const Termination& stop = {});

// The interpolating quintic spline through points[i] at times_s[i] (strictly increasing), C4 at
// the interior knots (position, velocity, acceleration, jerk and snap continuous), at rest
// (v = a = 0) at both ends: of all C3 curves through the points with those end conditions, the
// one of least integral of squared jerk (the natural spline of degree 5). Each segment is a
// quintic Hermite polynomial in local time; the knot velocities and accelerations solve the
// jerk and snap continuity equations (a banded system). INVALID_ARGUMENT for sizes that differ,
// fewer than two points, times not strictly increasing, non-finite input.
Result<geometry::PolynomialTrajectory> FitQuinticSpline(
    const std::vector<double>& times_s, const std::vector<Eigen::Vector3d>& points,
    geometry::YawPolicy yaw_policy = geometry::YawPolicy::kConstant, double start_yaw_rad = 0);

}  // namespace mav::planning
