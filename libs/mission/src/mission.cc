#include "mav/mission/mission.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "mav/common/time.h"
#include "mav/control/reference.h"

namespace mav::mission {

const char* MissionPhaseName(MissionPhase phase) {
  switch (phase) {
    case MissionPhase::kWaiting:
      return "waiting";
    case MissionPhase::kTakingOff:
      return "taking_off";
    case MissionPhase::kPlanning:
      return "planning";
    case MissionPhase::kFlying:
      return "flying";
    case MissionPhase::kHovering:
      return "hovering";
    case MissionPhase::kLanding:
      return "landing";
    case MissionPhase::kHolding:
      return "holding";
    case MissionPhase::kFaultLanding:
      return "fault_landing";
    case MissionPhase::kDone:
      return "done";
  }
  return "?";
}

const char* MissionOutcomeName(MissionOutcome outcome) {
  switch (outcome) {
    case MissionOutcome::kCompleted:
      return "completed";
    case MissionOutcome::kLandedOnFault:
      return "landed_on_fault";
    case MissionOutcome::kAborted:
      return "aborted";
    case MissionOutcome::kCollision:
      return "collision";
  }
  return "?";
}

bool MissionOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  auto positive = [&](double v, const char* name) {
    if (msg.str().empty() && !(v > 0 && std::isfinite(v))) {
      msg << name << ": must be positive and finite, got " << v;
    }
  };
  positive(tick_s, "tick_s");
  positive(hold_after_s, "hold_after_s");
  positive(land_after_s, "land_after_s");
  positive(resume_below_s, "resume_below_s");
  positive(takeoff_tolerance_m, "takeoff_tolerance_m");
  positive(goal_tolerance_m, "goal_tolerance_m");
  positive(landing_overshoot_m, "landing_overshoot_m");
  positive(landed_speed_mps, "landed_speed_mps");
  positive(landed_hold_s, "landed_hold_s");
  positive(landed_after_s, "landed_after_s");
  positive(timeout_s, "timeout_s");
  positive(arm_timeout_s, "arm_timeout_s");
  if (msg.str().empty() && !(land_after_s > hold_after_s)) {
    msg << "land_after_s: must exceed hold_after_s (" << hold_after_s << "), got " << land_after_s;
  }
  if (msg.str().empty() && !(resume_below_s < hold_after_s)) {
    msg << "resume_below_s: must be below hold_after_s (" << hold_after_s << "), got "
        << resume_below_s;
  }
  std::string limits_why;
  if (msg.str().empty() && !takeoff_limits.IsValid(&limits_why)) {
    msg << "takeoff_limits." << limits_why;
  }
  if (msg.str().empty() && !landing_limits.IsValid(&limits_why)) {
    msg << "landing_limits." << limits_why;
  }
  if (msg.str().empty() && !approach_limits.IsValid(&limits_why)) {
    msg << "approach_limits." << limits_why;
  }
  positive(approach_height_m, "approach_height_m");
  if (msg.str().empty() && !(std::isfinite(ground_z_m) && legs_height_m >= 0)) {
    msg << "ground_z_m / legs_height_m: must be finite, legs >= 0";
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

namespace {

std::string FormatPoint(const Eigen::Vector3d& p) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), "(%.2f, %.2f, %.2f)", p.x(), p.y(), p.z());
  return buf;
}

double WrapAngle(double a) { return std::atan2(std::sin(a), std::cos(a)); }

class Runner {
 public:
  Runner(const dataset::MissionSpec& mission, const MissionOptions& options, MissionDriver& driver)
      : m_(mission), o_(options), d_(driver) {
    for (const dataset::MissionGoal& g : m_.goals) {
      GoalReport goal;
      goal.goal = g.position;
      goal.line = g.line;
      r_.goals.push_back(goal);
    }
  }

  MissionReport Run(const MissionProgressCallback& progress) {
    // Every goal and the take-off point must be places the vehicle may be, before it flies.
    for (size_t i = 0; i <= m_.goals.size(); ++i) {
      const bool takeoff = i == m_.goals.size();
      const Status s = d_.CheckPoint(takeoff ? m_.start + Eigen::Vector3d(0, 0, m_.altitude_m)
                                             : m_.goals[i].position);
      if (s.ok()) continue;
      r_.error = (takeoff ? std::string("the take-off point (start + altitude)")
                          : GoalName(static_cast<int>(i))) +
                 ": " + s.message() + " (no take-off)";
      r_.outcome = MissionOutcome::kAborted;
      Event("refused: " + r_.error);
      return std::move(r_);
    }
    bool first = true;
    while (phase_ != MissionPhase::kDone) {
      Result<VehicleView> view = d_.Advance(first ? 0.0 : o_.tick_s);
      if (!view.ok()) {
        Finish(MissionOutcome::kAborted, "vehicle: " + view.status().ToString());
        break;
      }
      v_ = *std::move(view);
      if (first) t0_ns_ = v_.t_ns;
      first = false;
      t_ = NsToSeconds(v_.t_ns - t0_ns_);
      Tick();
      if (progress) {
        MissionProgress p;
        p.t_s = t_;
        p.phase = phase_;
        p.goal = goal_;
        p.goals = static_cast<int>(m_.goals.size());
        p.vehicle = &v_;
        progress(p);
      }
    }
    r_.sim_time_s = t_;
    return std::move(r_);
  }

 private:
  void Event(const std::string& what) { r_.events.push_back({t_, what}); }

  void Finish(MissionOutcome outcome, const std::string& error) {
    r_.outcome = outcome;
    // A collision outranks whatever happened before it.
    if (r_.error.empty() || outcome == MissionOutcome::kCollision) r_.error = error;
    r_.last_phase = phase_;
    Event(std::string("end: ") + MissionOutcomeName(outcome) + (error.empty() ? "" : ": " + error));
    phase_ = MissionPhase::kDone;
  }

  std::string GoalName(int i) const {
    std::ostringstream s;
    s << "goals[" << i << "]";
    if (m_.goals[i].line > 0) s << " (" << m_.source << ":" << m_.goals[i].line << ")";
    s << " " << FormatPoint(m_.goals[i].position);
    return s.str();
  }

  // The yaw a leg to goal i flies with: the goal's own, else (face_goals) the direction from the
  // leg's start to the goal, else the yaw held so far.
  double GoalYaw(int i) const {
    if (m_.goals[i].yaw_rad) return *m_.goals[i].yaw_rad;
    const Eigen::Vector2d d = (m_.goals[i].position - leg_start_).head<2>();
    if (o_.face_goals && d.norm() > 0.3) return std::atan2(d.y(), d.x());
    return yaw_;
  }

  Eigen::Vector3d Ground(const Eigen::Vector3d& p) const {
    return {p.x(), p.y(), o_.ground_z_m + o_.legs_height_m - o_.landing_overshoot_m};
  }

  // Starts the descent from the estimate to landing_target_. The touchdown cannot come before
  // the reference (a GoTo from rest, as the autopilot flies it) passes 0.2 m above the resting
  // height: landed_after_ is that moment (at least landed_after_s).
  void StartDescent() {
    landing_stage_ = LandingStage::kFinal;
    descent_started_ = t_;
    landed_after_ = o_.landed_after_s;
    geometry::TrajectoryPoint from;
    from.position = v_.p_est;
    from.yaw_rad = yaw_;
    const double rest_z = o_.ground_z_m + o_.legs_height_m + 0.2;
    if (Result<geometry::PolynomialTrajectory> ref =
            control::MakeGoToTrajectory(from, landing_target_, yaw_, o_.landing_limits);
        ref.ok()) {
      for (double t = 0; t <= ref->duration_s(); t += 0.05) {
        if (ref->Evaluate(t).position.z() <= rest_z) {
          landed_after_ = std::max(landed_after_, t);
          break;
        }
      }
    }
    const Status s = d_.GoTo(landing_target_, yaw_, o_.landing_limits);
    if (!s.ok()) Event("landing: " + s.ToString());
  }

  // Over the landing column: down to approach_height_m above the resting height at
  // approach_limits (skipped when already that low), then the final descent.
  void Approach() {
    const double approach_z = o_.ground_z_m + o_.legs_height_m + o_.approach_height_m;
    if (v_.p_est.z() <= approach_z + 0.1) return StartDescent();
    landing_stage_ = LandingStage::kApproach;
    const Status s =
        d_.GoTo({landing_target_.x(), landing_target_.y(), approach_z}, yaw_, o_.approach_limits);
    if (!s.ok()) Event("landing: " + s.ToString());
  }

  // Lands at the free column nearest to `p` (moving there first at p's altitude); ends with
  // `outcome`.
  void StartLanding(const Eigen::Vector3d& p, MissionOutcome outcome, MissionPhase phase) {
    landing_outcome_ = outcome;
    landed_since_ = -1;
    phase_ = phase;
    if (!v_.armed) {
      Finish(outcome, "");
      return;
    }
    Eigen::Vector3d spot = p;
    if (Result<Eigen::Vector3d> found = d_.LandingSpot(p); found.ok()) {
      spot = *found;
    } else {
      Event("landing spot: " + found.status().message() + "; descending where it is");
    }
    landing_target_ = Ground(spot);
    if ((spot - p).head<2>().norm() < 0.02) return Approach();
    landing_stage_ = LandingStage::kMove;
    Event("moving to the free landing column at " + FormatPoint(spot));
    if (Status s = d_.GoTo(spot, yaw_, o_.takeoff_limits); !s.ok())
      Event("landing: " + s.ToString());
  }

  void Abort(const std::string& error) {
    r_.error = error;
    Event("abort: " + error);
    if (v_.armed) {
      StartLanding(v_.p_est, MissionOutcome::kAborted, MissionPhase::kLanding);
    } else {
      Finish(MissionOutcome::kAborted, error);
    }
  }

  bool Airborne() const {
    return v_.armed && phase_ != MissionPhase::kWaiting && phase_ != MissionPhase::kDone;
  }

  void Tick() {
    if (v_.collisions > 0) {
      Finish(MissionOutcome::kCollision,
             "the vehicle touched an obstacle at t = " + std::to_string(t_) + " s");
      return;
    }
    if (t_ > o_.timeout_s) {
      Finish(MissionOutcome::kAborted,
             "the mission took longer than timeout_s = " + std::to_string(o_.timeout_s) + " s");
      return;
    }
    if (Airborne() && CheckHealth()) return;
    switch (phase_) {
      case MissionPhase::kWaiting:
        return Wait();
      case MissionPhase::kTakingOff:
        return TakeOff();
      case MissionPhase::kPlanning:
        return PlanLeg();
      case MissionPhase::kFlying:
        if (v_.map_version != map_version_) {
          map_version_ = v_.map_version;
          if (ReplanIfBlocked()) return;
        }
        if (!v_.moving) {
          phase_ = MissionPhase::kHovering;
          hover_until_ = t_ + m_.goals[goal_].hover_s;
          r_.goals[goal_].hover_start_s = t_;
        }
        return;
      case MissionPhase::kHovering:
        return Hover();
      case MissionPhase::kLanding:
      case MissionPhase::kFaultLanding:
        return Land();
      case MissionPhase::kHolding:  // CheckHealth decides
      case MissionPhase::kDone:
        return;
    }
  }

  // Returns true when the health logic took this tick.
  bool CheckHealth() {
    const double age = v_.pose_age_s;
    // A restarted localization is re-seeded from the estimate (holding or landing on fault).
    if (!v_.localization_needs_seed) {
      seeded_ = false;
    } else if (!seeded_ && age > o_.hold_after_s) {
      const Status s = d_.SeedLocalization(geometry::SE3(v_.q_est, v_.p_est));
      Event(s.ok() ? "localization re-seeded from the estimate " + FormatPoint(v_.p_est)
                   : "seeding the localization: " + s.ToString());
      seeded_ = s.ok();
    }
    if (phase_ == MissionPhase::kFaultLanding) return false;
    if (age > o_.land_after_s) {
      char what[160];
      std::snprintf(what, sizeof(what), "no accepted pose for %.1f s: landing", age);
      Event(what);
      if (r_.error.empty()) r_.error = what;
      StartLanding(v_.p_est, MissionOutcome::kLandedOnFault, MissionPhase::kFaultLanding);
      return true;
    }
    if (phase_ != MissionPhase::kHolding) {
      if (age <= o_.hold_after_s) return false;
      char what[160];
      std::snprintf(what, sizeof(what), "hold: no accepted pose for %.1f s (was %s)", age,
                    MissionPhaseName(phase_));
      Event(what);
      ++r_.holds;
      paused_ = phase_;
      hold_started_ = t_;
      hold_p_ = v_.p_est;
      const Status s = d_.Hold(hold_p_, yaw_);
      if (!s.ok()) Event("hold: " + s.ToString());
      phase_ = MissionPhase::kHolding;
      return true;
    }
    // Holding: resume on fresh poses.
    if (age >= o_.resume_below_s) return true;
    Event("resume (" + std::string(MissionPhaseName(paused_)) + ")");
    phase_ = paused_;
    switch (paused_) {
      case MissionPhase::kFlying:
      case MissionPhase::kPlanning:
        // The leg's trajectory ran on while the vehicle held: plan again from here.
        leg_start_ = hold_p_;
        replan_ = true;
        turning_ = false;
        phase_ = MissionPhase::kPlanning;
        break;
      case MissionPhase::kHovering:
        hover_until_ += t_ - hold_started_;
        (void)d_.GoTo(m_.goals[goal_].position, GoalYaw(goal_), o_.takeoff_limits);
        break;
      case MissionPhase::kTakingOff:
        (void)d_.GoTo(takeoff_point_, yaw_, o_.takeoff_limits);
        break;
      case MissionPhase::kLanding:
        landing_stage_ = LandingStage::kMove;  // back over the landing column, then down
        (void)d_.GoTo({landing_target_.x(), landing_target_.y(), hold_p_.z()}, yaw_,
                      o_.takeoff_limits);
        break;
      default:
        break;
    }
    return true;
  }

  void Wait() {
    if (t_ > o_.arm_timeout_s) {
      Finish(MissionOutcome::kAborted, "the estimator did not converge within arm_timeout_s = " +
                                           std::to_string(o_.arm_timeout_s) + " s (no take-off)");
      return;
    }
    if (!v_.estimator_converged || v_.pose_age_s > o_.hold_after_s) return;
    const Status s = d_.Arm();
    if (!s.ok()) return;  // tried again next tick
    yaw_ = v_.yaw_est_rad;
    takeoff_point_ = m_.start + Eigen::Vector3d(0, 0, m_.altitude_m);
    const Status go = d_.GoTo(takeoff_point_, yaw_, o_.takeoff_limits);
    if (!go.ok()) {
      Abort("take-off: " + go.ToString());
      return;
    }
    Event("armed, taking off to " + FormatPoint(takeoff_point_));
    phase_ = MissionPhase::kTakingOff;
  }

  void TakeOff() {
    if (v_.moving || (v_.p_est - takeoff_point_).norm() > o_.takeoff_tolerance_m) return;
    r_.takeoff_t_s = t_;
    goal_ = 0;
    leg_start_ = takeoff_point_;
    phase_ = MissionPhase::kPlanning;
  }

  void PlanLeg() {
    const double yaw = GoalYaw(goal_);
    if (turning_) {
      if (v_.moving) return;
      turning_ = false;
      yaw_ = yaw;
    } else if (std::abs(WrapAngle(yaw - yaw_)) > 0.02) {
      // Turn in place first: the leg itself keeps a constant yaw.
      const Status s = d_.GoTo(leg_start_, yaw, o_.takeoff_limits);
      if (!s.ok()) return Abort(GoalName(goal_) + ": turning to its yaw: " + s.ToString());
      turning_ = true;
      return;
    }
    Result<LegPlan> plan = d_.Plan(leg_start_, m_.goals[goal_].position, yaw_);
    ++r_.plans;
    if (!plan.ok()) {
      return Abort(GoalName(goal_) + ": no plan from " + FormatPoint(leg_start_) + ": " +
                   plan.status().message());
    }
    const Status s = d_.Follow(plan->trajectory);
    if (!s.ok()) return Abort(GoalName(goal_) + ": following its plan: " + s.ToString());
    leg_ = plan->trajectory;
    leg_t0_ = t_;
    LegReport leg;
    leg.goal = goal_;
    leg.replan = replan_;
    leg.t_s = t_;
    leg.path = plan->path;
    leg.length_m = plan->length_m;
    leg.duration_s = plan->duration_s;
    r_.legs.push_back(std::move(leg));
    if (replan_) ++r_.replans;
    replan_ = false;
    phase_ = MissionPhase::kFlying;
  }

  // The map changed during a leg: when the rest of the leg (from lookahead on) is no longer a
  // place the vehicle may be, it holds and the leg is planned again from there. True if so.
  bool ReplanIfBlocked() {
    constexpr double kLookaheadS = 0.5, kStepS = 0.1;
    for (double tau = t_ - leg_t0_ + kLookaheadS; tau <= leg_.duration_s(); tau += kStepS) {
      const Eigen::Vector3d p = leg_.Evaluate(tau).position;
      const Status s = d_.CheckPoint(p);
      if (s.ok()) continue;
      Event("the map now blocks the leg at " + FormatPoint(p) + " (" + s.message() +
            "): re-planning from " + FormatPoint(v_.p_est));
      if (Status hold = d_.Hold(v_.p_est, yaw_); !hold.ok()) Event("hold: " + hold.ToString());
      leg_start_ = v_.p_est;
      replan_ = true;
      phase_ = MissionPhase::kPlanning;
      return true;
    }
    return false;
  }

  void Hover() {
    if (t_ < hover_until_) return;
    GoalReport& g = r_.goals[goal_];
    g.visited = true;
    g.reached_at_s = t_;
    g.estimate_error_m = (v_.p_est - g.goal).norm();
    if (v_.truth) g.error_m = (v_.truth->p_world - g.goal).norm();
    g.reached = (g.error_m >= 0 ? g.error_m : g.estimate_error_m) <= o_.goal_tolerance_m;
    char what[160];
    std::snprintf(what, sizeof(what), "goal %d of %zu %s: error %.3f m (estimate %.3f m)",
                  goal_ + 1, m_.goals.size(), g.reached ? "reached" : "missed", g.error_m,
                  g.estimate_error_m);
    Event(what);
    if (goal_ + 1 < static_cast<int>(m_.goals.size())) {
      leg_start_ = g.goal;
      ++goal_;
      phase_ = MissionPhase::kPlanning;
      return;
    }
    if (m_.land) {
      StartLanding(g.goal, MissionOutcome::kCompleted, MissionPhase::kLanding);
    } else {
      Finish(MissionOutcome::kCompleted, "");
    }
  }

  void Land() {
    if (!v_.armed) return Finish(landing_outcome_, "");
    if (landing_stage_ != LandingStage::kFinal) {
      if (v_.moving) return;
      if (landing_stage_ == LandingStage::kMove) return Approach();
      return StartDescent();
    }
    if (t_ - descent_started_ < landed_after_ || v_.v_est.norm() > o_.landed_speed_mps) {
      landed_since_ = -1;
      return;
    }
    if (landed_since_ < 0) landed_since_ = t_;
    if (t_ - landed_since_ < o_.landed_hold_s) return;
    const Status s = d_.Disarm();
    if (!s.ok()) Event("disarm: " + s.ToString());
    Event("landed at " + FormatPoint(v_.p_est));
    Finish(landing_outcome_, "");
  }

  const dataset::MissionSpec& m_;
  const MissionOptions& o_;
  MissionDriver& d_;
  MissionReport r_;
  VehicleView v_;
  int64_t t0_ns_ = 0;
  double t_ = 0;
  MissionPhase phase_ = MissionPhase::kWaiting;
  MissionPhase paused_ = MissionPhase::kWaiting;
  int goal_ = -1;
  double yaw_ = 0;
  Eigen::Vector3d takeoff_point_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d leg_start_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d hold_p_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d landing_target_ = Eigen::Vector3d::Zero();
  MissionOutcome landing_outcome_ = MissionOutcome::kCompleted;
  geometry::PolynomialTrajectory leg_;  // the leg being flown, started at leg_t0_
  double leg_t0_ = 0;
  uint64_t map_version_ = 0;
  double hover_until_ = 0, hold_started_ = 0, landed_since_ = -1, descent_started_ = 0,
         landed_after_ = 0;
  // The landing's moves: to the free column at the current height, down to the approach
  // height, the final descent.
  enum class LandingStage { kMove, kApproach, kFinal };
  LandingStage landing_stage_ = LandingStage::kMove;
  bool replan_ = false, turning_ = false, seeded_ = false;
};

}  // namespace

Result<MissionReport> RunMission(const dataset::MissionSpec& mission, const MissionOptions& options,
                                 MissionDriver& driver, const MissionProgressCallback& progress) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("mission options: " + why);
  if (!mission.IsValid(&why)) {
    return Status::InvalidArgument((mission.source.empty() ? "mission" : mission.source) + ": " +
                                   why);
  }
  Runner runner(mission, options, driver);
  return runner.Run(progress);
}

}  // namespace mav::mission
