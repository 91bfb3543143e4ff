#pragma once
// The state estimator of Holzmann et al. 2015 (Sec. 3), a discretised nonlinear complementary
// filter after Mahony, Hamel, Pflimlin, "Nonlinear complementary filters on the special
// orthogonal group", IEEE TAC 53(5), 2008, with delayed poses merged by re-application:
//
//  * prediction (every IMU sample, Euler steps of the IMU period h):
//      w = gyro - b_g,  a = R (accel - b_a) + g,  p += h v + h^2 a / 2,  v += h a,
//      q = q Exp(h w);
//  * correction (a pose of source s stamped t_s arrives late): the buffered estimate at t_s is
//    corrected with the a-priori weights K (estimator_weights.h):
//      r_p = p_meas - (p + R t_bs),  r_t = Log(q_meas q^-1)           (q_meas = q_ws q_bs^-1)
//      [dp, dv, db_a, dtheta, db_g] = K [r_p, r_t],  p += dp, v += dv, q = Exp(dtheta) q,
//      b_a += R^T db_a, b_g += R^T db_g,
//    i.e. the orientation turns part way about the relative rotation axis (the paper's
//    decoupled weights when EstimatorOptions::couple_tilt is false; by default the tilt's
//    coupling with the horizontal position is kept); then every buffered IMU sample after t_s is
//    re-applied, which gives the estimate a filter fed on time would have (T_body_sensor =
//    (q_bs, t_bs) is the pose sensor's mounting);
//  * several pose sources (EstimatorOptions::pose_sources), each with its rate, noise and mounting;
//  * optionally, per source, a gravity alignment of a source whose world tilts as it drifts (a
//    VO): the tilt is weighted by its own noise (tilt_sigma_rad: loose, so that the estimate's
//    tilt comes from the IMU's specific force against the positions), and each pose is first
//    mapped through a correction of the source's frame that turns its tilt toward the
//    estimate's, about the body's position, with time constant align_tilt_s (source_frame()).
//
// Fed synchronously, as OpenVINS' VioManager: FeedImu / FeedPose in arrival order; no threads,
// no files, no allocation after construction (fixed ring buffer). Not thread-safe.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/common/status.h"
#include "mav/control/estimator_weights.h"
#include "mav/control/vehicle.h"
#include "mav/geometry/se3.h"

namespace mav::control {

struct PoseSourceOptions {
  double rate_hz = 10;                   // nominal rate, for the weights
  double position_sigma_m = 0.01;        // per axis
  double orientation_sigma_rad = 0.017;  // per axis
  // The tilt's (roll and pitch) noise in the weights; 0 = orientation_sigma_rad
  // (PoseSourceNoise::tilt_sigma_rad).
  double tilt_sigma_rad = 0;
  // Gravity alignment of a source whose frame drifts in tilt (a VO, whose keyframe chain slowly
  // tips its world): > 0 keeps a correction of the source's frame (source_frame()) that turns
  // each pose's tilt toward the estimate's at its stamp, about the pose's position, with this
  // time constant; the corrected pose is the one merged. The estimate's tilt must then come from
  // gravity (a large tilt_sigma_rad), or the two follow each other. 0 = off.
  double align_tilt_s = 0;
  // The sensor's mounting: the measured poses are T_world_sensor = T_world_body T_body_sensor.
  geometry::SE3 T_body_sensor;
};

struct EstimatorOptions {
  double imu_rate_hz = 100;  // nominal IMU rate (the weights' step h)
  // IMU history kept for re-application; a pose older than this is dropped. Must exceed the
  // largest pose delay (the contest's: 100 ms).
  double buffer_s = 1.0;
  // IMU noise per sample and the offsets' drift, as the contest's IMU (docs/control.md, "The
  // sensors"): white noise 0.04 m/s^2 and 0.0033937 rad/s; the offsets drift about 0.09 m/s^2 and
  // 6e-4 rad/s (1 sigma) over 240 s, i.e. random walks of 0.09/sqrt(240) and 6e-4/sqrt(240).
  double accel_noise_sigma = 0.04;
  double gyro_noise_sigma = 0.0033937;
  double accel_offset_random_walk = 0.09 / 15.491933384829668;  // m/s^2/sqrt(s)
  double gyro_offset_random_walk = 6e-4 / 15.491933384829668;   // rad/s/sqrt(s)
  // Prior of the unknowns at the first pose (the transient weights).
  double initial_velocity_sigma = 0.2;      // m/s
  double initial_accel_offset_sigma = 0.5;  // m/s^2
  double initial_gyro_offset_sigma = 0.05;  // rad/s
  std::vector<PoseSourceOptions> pose_sources = std::vector<PoseSourceOptions>(1);
  // false: the IMU offsets stay at zero (for tests and the ablation).
  bool estimate_offsets = true;
  // false: the steady-state weights from the first pose on (slow offset learning).
  bool transient_weights = true;
  // false: the paper's decoupled weights (see estimator_weights.h); true: the tilt's coupling of
  // orientation and horizontal position is kept in the model.
  bool couple_tilt = true;
  // Explicit weights for every source instead of the computed ones.
  std::optional<CorrectionWeights> explicit_weights;
  // The health gate (0 = off, the default): a pose whose position differs from the estimate
  // at its stamp (through the source's mounting) by more than
  //   pose_gate_m + pose_gate_growth_mps * (time since the last accepted pose's stamp)
  // or whose orientation differs by more than pose_gate_rad is rejected (FailedPrecondition,
  // counted in poses_rejected): a localization that jumped must not pull the vehicle with it.
  // The growth lets the gate open as the estimate drifts on the IMU alone.
  double pose_gate_m = 0;
  double pose_gate_growth_mps = 0.3;
  double pose_gate_rad = 0;
  // The estimate counts as converged this long after the first pose (the transient gains
  // have then learnt the offsets to a few percent).
  double converge_s = 4.0;

  bool IsValid(std::string* why) const;
  WeightModel ToWeightModel() const;
};

// The estimate at t_ns.
struct EstimatorState {
  int64_t t_ns = 0;
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_world = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_world_body = Eigen::Quaterniond::Identity();
  Eigen::Vector3d accel_offset = Eigen::Vector3d::Zero();  // m/s^2, body
  Eigen::Vector3d gyro_offset = Eigen::Vector3d::Zero();   // rad/s, body
  // From the latest IMU sample with the offsets removed:
  Eigen::Vector3d omega_body = Eigen::Vector3d::Zero();  // rad/s
  Eigen::Vector3d a_world = Eigen::Vector3d::Zero();     // m/s^2, kinematic (gravity removed)
};

struct EstimatorCounters {
  uint64_t imu_samples = 0;
  uint64_t poses_merged = 0;
  uint64_t poses_dropped = 0;      // older than the buffer, or before any IMU
  uint64_t poses_rejected = 0;     // by the gate (EstimatorOptions::pose_gate_m)
  int64_t last_accepted_t_ns = 0;  // stamp of the newest accepted pose
  int64_t last_pose_t_ns = 0;      // stamp of the last merged pose
  Eigen::Vector3d last_position_residual = Eigen::Vector3d::Zero();
};

class Estimator {
 public:
  // InvalidArgument naming the field for bad options.
  static Result<Estimator> Create(const EstimatorOptions& options);

  // One IMU sample; samples must come in increasing time (others are ignored and counted as
  // dropped poses would be: see counters()).
  void FeedImu(const ImuMeasurement& imu);
  // A pose, in arrival order (its stamp may be up to buffer_s old). InvalidArgument for an
  // unknown source; OutOfRange (pose dropped) when older than the buffer or no IMU has arrived;
  // FailedPrecondition when the gate rejects it (see EstimatorOptions::pose_gate_m).
  Status FeedPose(const PoseMeasurement& pose);

  bool initialized() const { return initialized_; }
  // The IMU time the first pose initialised the estimate at (0 before).
  int64_t initialized_t_ns() const { return initialized_ ? init_t_ns_ : 0; }
  // Initialised for at least converge_s.
  bool converged() const;
  const EstimatorState& state() const { return current_; }
  const EstimatorCounters& counters() const { return counters_; }
  const WeightSchedule& weights() const { return weights_; }
  const EstimatorOptions& options() const { return options_; }
  // The correction of source s's frame (T_world_sourceworld: a pose of the source maps to
  // source_frame(s) * pose); the identity unless PoseSourceOptions::align_tilt_s is set. To
  // restart such a source at a world pose T, start it at source_frame(s).Inverse() * T.
  const geometry::SE3& source_frame(int source) const { return frames_[source]; }
  // Forgets everything (the next pose initialises again).
  void Reset();

 private:
  struct Entry {
    ImuMeasurement imu;
    EstimatorState state;  // the estimate at imu.t_ns
  };
  Estimator(const EstimatorOptions& options, WeightSchedule weights);
  void Propagate(const ImuMeasurement& imu, double dt_s, EstimatorState* x) const;
  struct Applied {
    PoseMeasurement pose;
    CorrectionWeights weights;
  };
  CorrectionWeights NextWeights(int source);
  Status Gate(const PoseMeasurement& pose, const EstimatorState& x);
  // The pose through its source's frame, aligned in tilt to x (align_tilt_s); *frame gets the
  // source's updated frame.
  PoseMeasurement Aligned(const PoseMeasurement& pose, const EstimatorState& x,
                          geometry::SE3* frame) const;
  void Correct(const PoseMeasurement& pose, const CorrectionWeights& w, EstimatorState* x);
  Entry& At(int k) { return ring_[(head_ + k) % ring_.size()]; }

  EstimatorOptions options_;
  WeightSchedule weights_;
  std::vector<Entry> ring_;  // oldest at head_
  int head_ = 0, size_ = 0;
  std::vector<uint64_t> updates_per_source_;
  std::vector<geometry::SE3> frames_;  // per source (source_frame())
  // The poses merged within the buffer, in stamp order (re-applied when an older one arrives).
  std::vector<Applied> applied_;
  int applied_size_ = 0;
  bool initialized_ = false;
  int64_t init_t_ns_ = 0;
  EstimatorState current_;
  EstimatorCounters counters_;
};

}  // namespace mav::control
