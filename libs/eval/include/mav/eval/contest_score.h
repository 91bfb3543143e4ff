#pragma once
// The EuRoC 2014 Challenge 3 scoring, as the contest's evaluation scripts compute it
// (docs/control.md, "Scoring"), on a ground-truth trace of a flown task:
//  * position error = |p_truth - p_goal| (3-D), angular-rate error = |w_truth| (3-D, the goal
//    is at rest); RMS over a window of scoring.window_s (10 s);
//  * kHover (t3_1): the window starts scoring.hover_delay_s (5 s) after the set point is
//    published; no settling is scored;
//  * kDisturbance (t3_2, t3_3): settling is counted from the onset of the first force: the
//    earliest t after it from which the vehicle stays within settle_radius_m (0.1 m) for
//    settle_hold_s (3 s); never leaving the ball counts as 0 s. Settling later than
//    settle_limit_s (10 s) after the onset scores nothing. The RMS window starts at settling;
//  * kWaypoints / kPlannedLegs (t4_x): every goal after the first is scored like a disturbance
//    from its publication; a goal that never settles counts as 101 % of each limit;
//  * bands of each figure against its limit (position 0.2 m, settling 10 s: 0 / 1.5 / 3.5 / 5.0
//    points; angular rate 0.2 rad/s: 0 / 1.0 / 2.0 / 3.0) for ratios > 100 %, (50, 100] %,
//    (10, 50] %, <= 10 %;
//  * any collision scores zero for the task.
// Besides the contest's figures: the estimator's position error over the same windows, and for
// the waypoint tasks each leg's flight time (leaving the previous goal's ball until entering the
// next), mean and peak speed.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/dataset/flight_task.h"

namespace mav::eval {

// One ground-truth sample of a flown task (any fixed rate; the contest's was 100 Hz).
struct FlightTraceSample {
  double t_s = 0;
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();     // truth
  Eigen::Vector3d v_world = Eigen::Vector3d::Zero();     // truth
  Eigen::Vector3d omega_body = Eigen::Vector3d::Zero();  // truth
  Eigen::Vector3d p_estimate = Eigen::Vector3d::Zero();  // the controller's estimate
};

// Points of one figure: value / limit in the bands above. `rate` selects the angular-rate
// points (0 / 1 / 2 / 3) instead of position/settling (0 / 1.5 / 3.5 / 5).
double BandPoints(double value, double limit, bool rate);

struct SettleResult {
  bool settled = false;
  double settling_time_s = 0;  // from `from_s`; valid when settled
};

// Earliest t >= from_s with |p(tau) - goal| <= radius for every sample in [t, t + hold]
// (the trace must reach t + hold), returned relative to from_s if it is <= limit_s.
SettleResult FindSettling(const std::vector<FlightTraceSample>& trace, double from_s,
                          const Eigen::Vector3d& goal, const dataset::FlightScoring& scoring);

struct WindowRms {
  double position_rms_m = 0;
  double angular_rate_rms_radps = 0;
  double estimator_rms_m = 0;  // |p_estimate - p_truth|
  int samples = 0;
};
// RMS over the samples with t in [t0, t1).
WindowRms RmsOverWindow(const std::vector<FlightTraceSample>& trace, double t0, double t1,
                        const Eigen::Vector3d& goal);

struct GoalScore {
  int goal = 0;                // index into FlightTask::goals
  double from_s = 0;           // publication, or the disturbance's onset
  bool settled = true;         // always true for kHover
  double settling_time_s = 0;  // 1.01 * limit when never settled
  double window_start_s = 0;
  WindowRms rms;  // 1.01 * the limits when never settled
  double position_points = 0, angular_rate_points = 0, settling_points = 0;
  // Waypoint legs (the goal before this one -> this one); zero otherwise.
  double flight_time_s = 0, mean_speed_mps = 0, peak_speed_mps = 0, path_length_m = 0;
};

struct TaskScore {
  std::string task;
  std::vector<GoalScore> goals;  // the scored goals
  int collisions = 0;
  double points = 0;      // the contest's total (0 with any collision)
  double max_points = 0;  // the full marks of the same figures
  // Means over the scored goals (the headline figures).
  double position_rms_m = 0, angular_rate_rms_radps = 0, settling_time_s = 0;
  double estimator_rms_m = 0;
  bool all_settled = true;
};

// Scores a trace of `task` (sorted by time). `collisions`: how many the simulation reported.
TaskScore ScoreFlightTask(const dataset::FlightTask& task,
                          const std::vector<FlightTraceSample>& trace, int collisions);

}  // namespace mav::eval
