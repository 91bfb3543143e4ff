#pragma once
// The flight record of a mission, the same for both drivers: one sample of the vehicle as the
// mission saw it (VehicleView, with a simulator's ground truth) per record period, taken at the
// mission's ticks; and the mission's figures computed from it.

#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/eval/contest_score.h"
#include "mav/mission/driver.h"
#include "mav/mission/mission.h"

namespace mav::mission {

// One sample of the flight record.
struct FlightSample {
  double t_s = 0;
  Eigen::Vector3d p_true = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_true = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_true = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_est = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_est = Eigen::Quaterniond::Identity();
  Eigen::Vector3d omega_true = Eigen::Vector3d::Zero();
  bool armed = false;
};

// Keeps a sample of each view offered once per 1/rate_hz of the vehicle's clock, from the
// first view with an initialized estimator and a ground truth on.
class FlightRecorder {
 public:
  explicit FlightRecorder(double rate_hz);
  void Offer(const VehicleView& view);
  const std::vector<FlightSample>& samples() const { return samples_; }

 private:
  int64_t period_ns_;
  int64_t next_ns_ = 0;
  std::vector<FlightSample> samples_;
};

// The mission's ATE: RMS of |estimate - ground truth| over the samples while armed, without
// alignment; NaN when none was armed.
double EstimateRmsError(const std::vector<FlightSample>& record);

// The contest's hover figures (t3_1, mav/eval/contest_score.h) of a goal's hover, from the
// ground truth: RMS of |p - goal| and of |omega| over [hover_start_s + settle_s, reached_at_s).
// samples = 0 when the goal was not visited or the window is empty.
eval::WindowRms ScoreHover(const std::vector<FlightSample>& record, const GoalReport& goal,
                           double settle_s = 5.0);

}  // namespace mav::mission
