#include "mav/control/estimator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "mav/common/time.h"

namespace mav::control {

using geometry::ExpSO3;
using geometry::LogSO3;

bool EstimatorOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(buffer_s > 0 && buffer_s <= 10)) return fail("buffer_s: must be in (0, 10]");
  if (!(converge_s >= 0 && std::isfinite(converge_s))) return fail("converge_s: must be >= 0");
  if (!(pose_gate_m >= 0 && std::isfinite(pose_gate_m))) {
    return fail("pose_gate_m: must be >= 0 (0 = off)");
  }
  if (!(pose_gate_growth_mps >= 0 && std::isfinite(pose_gate_growth_mps))) {
    return fail("pose_gate_growth_mps: must be >= 0");
  }
  if (!(pose_gate_rad >= 0 && std::isfinite(pose_gate_rad))) {
    return fail("pose_gate_rad: must be >= 0 (0 = off)");
  }
  for (size_t i = 0; i < pose_sources.size(); ++i) {
    const Eigen::Vector3d t = pose_sources[i].T_body_sensor.Translation();
    if (!t.allFinite() || !pose_sources[i].T_body_sensor.Rotation().coeffs().allFinite()) {
      return fail("pose_sources[" + std::to_string(i) + "].T_body_sensor: must be finite");
    }
    if (!(pose_sources[i].align_tilt_s >= 0 && std::isfinite(pose_sources[i].align_tilt_s))) {
      return fail("pose_sources[" + std::to_string(i) + "].align_tilt_s: must be >= 0 (0 = off)");
    }
  }
  if (explicit_weights) {
    const CorrectionWeights& w = *explicit_weights;
    if (!w.horizontal.allFinite() || !w.vertical.allFinite() || !w.heading.allFinite()) {
      return fail("explicit_weights: must be finite");
    }
    if (!(w.position() > 0 && w.position() <= 1)) {
      return fail("explicit_weights.position: must be in (0, 1]");
    }
    if (!(w.orientation() > 0 && w.orientation() <= 1)) {
      return fail("explicit_weights.orientation: must be in (0, 1]");
    }
  }
  return ToWeightModel().IsValid(why);
}

WeightModel EstimatorOptions::ToWeightModel() const {
  WeightModel m;
  m.imu_rate_hz = imu_rate_hz;
  m.accel_noise_sigma = accel_noise_sigma;
  m.gyro_noise_sigma = gyro_noise_sigma;
  m.accel_offset_random_walk = accel_offset_random_walk;
  m.gyro_offset_random_walk = gyro_offset_random_walk;
  m.initial_velocity_sigma = initial_velocity_sigma;
  m.initial_accel_offset_sigma = initial_accel_offset_sigma;
  m.initial_gyro_offset_sigma = initial_gyro_offset_sigma;
  m.couple_tilt = couple_tilt;
  // The offsets are learnt against the sources' own tilt while the estimate converges.
  m.trust_tilt_s = std::min(converge_s, 60.0);
  m.pose_sources.clear();
  for (const PoseSourceOptions& s : pose_sources) {
    m.pose_sources.push_back(
        {s.rate_hz, s.position_sigma_m, s.orientation_sigma_rad, s.tilt_sigma_rad});
  }
  return m;
}

Result<Estimator> Estimator::Create(const EstimatorOptions& options) {
  if (std::string why; !options.IsValid(&why)) return Status::InvalidArgument(why);
  MAV_ASSIGN_OR_RETURN(WeightSchedule weights, ComputeWeightSchedule(options.ToWeightModel()));
  return Estimator(options, std::move(weights));
}

Estimator::Estimator(const EstimatorOptions& options, WeightSchedule weights)
    : options_(options), weights_(std::move(weights)) {
  // Room for the buffer at up to twice the nominal rate.
  const size_t capacity =
      static_cast<size_t>(std::ceil(2.0 * options.buffer_s * options.imu_rate_hz)) + 4;
  ring_.resize(capacity);
  updates_per_source_.assign(options.pose_sources.size(), 0);
  frames_.assign(options.pose_sources.size(), geometry::SE3());
  // Room for every pose of every source within the buffer at up to 4x its nominal rate.
  double poses = 0;
  for (const PoseSourceOptions& s : options.pose_sources)
    poses += 4.0 * s.rate_hz * options.buffer_s;
  applied_.resize(static_cast<size_t>(std::ceil(poses)) + 4);
}

void Estimator::Reset() {
  head_ = size_ = 0;
  initialized_ = false;
  current_ = EstimatorState();
  counters_ = EstimatorCounters();
  updates_per_source_.assign(options_.pose_sources.size(), 0);
  frames_.assign(options_.pose_sources.size(), geometry::SE3());
  applied_size_ = 0;
}

bool Estimator::converged() const {
  return initialized_ && current_.t_ns - init_t_ns_ >= SecondsToNs(options_.converge_s);
}

void Estimator::Propagate(const ImuMeasurement& imu, double dt_s, EstimatorState* x) const {
  const Eigen::Vector3d omega = imu.gyro - x->gyro_offset;
  const Eigen::Vector3d a =
      x->q_world_body * (imu.accel - x->accel_offset) - Eigen::Vector3d(0, 0, kGravity);
  // Position with the second-order term of the constant-acceleration step (the velocity step
  // is Euler's); it removes most of the discretisation error of a moving body at no cost.
  x->p_world += dt_s * x->v_world + 0.5 * dt_s * dt_s * a;
  x->v_world += dt_s * a;
  x->q_world_body = (x->q_world_body * ExpSO3(dt_s * omega)).normalized();
  x->omega_body = omega;
  x->a_world = a;
}

void Estimator::FeedImu(const ImuMeasurement& imu) {
  ++counters_.imu_samples;
  if (size_ > 0 && imu.t_ns <= At(size_ - 1).imu.t_ns) return;  // out of order: ignored
  const int64_t t_prev = size_ > 0 ? At(size_ - 1).imu.t_ns : imu.t_ns;
  // Drop entries older than the buffer span (and make room).
  const int64_t keep_ns = SecondsToNs(options_.buffer_s);
  while (size_ > 0 &&
         (imu.t_ns - At(0).imu.t_ns > keep_ns || size_ >= static_cast<int>(ring_.size()))) {
    head_ = (head_ + 1) % static_cast<int>(ring_.size());
    --size_;
  }
  EstimatorState x = current_;
  if (initialized_) Propagate(imu, NsToSeconds(imu.t_ns - t_prev), &x);
  x.t_ns = imu.t_ns;
  Entry& e = At(size_);
  ++size_;
  e.imu = imu;
  e.state = x;
  current_ = x;
}

CorrectionWeights Estimator::NextWeights(int source) {
  const uint64_t k = updates_per_source_[source]++;
  if (options_.explicit_weights) return *options_.explicit_weights;
  const auto& transient = weights_.transient[source];
  return options_.transient_weights && k < transient.size() ? transient[k]
                                                            : weights_.steady[source];
}

void Estimator::Correct(const PoseMeasurement& pose, const CorrectionWeights& w,
                        EstimatorState* x) {
  const PoseSourceOptions& src = options_.pose_sources[pose.source];
  const Eigen::Quaterniond q_meas =
      pose.T_world_sensor.Rotation() * src.T_body_sensor.Rotation().conjugate();
  const Eigen::Vector3d r_p = pose.T_world_sensor.Translation() -
                              (x->p_world + x->q_world_body * src.T_body_sensor.Translation());
  // The rotation residual in the world frame: q_meas = Exp(r_t) q.
  const Eigen::Vector3d r_t = LogSO3(q_meas * x->q_world_body.conjugate());
  Eigen::Vector3d dp, dv, db_a, dtheta, db_g;
  // x pairs with the tilt theta_y, y with -theta_x (a tilt about y pushes the thrust along +x).
  const Eigen::Matrix<double, 5, 1> cx = w.horizontal * Eigen::Vector2d(r_p.x(), r_t.y());
  const Eigen::Matrix<double, 5, 1> cy = w.horizontal * Eigen::Vector2d(r_p.y(), -r_t.x());
  const Eigen::Vector3d cz = w.vertical * r_p.z();
  const Eigen::Vector2d cpsi = w.heading * r_t.z();
  dp << cx[0], cy[0], cz[0];
  dv << cx[1], cy[1], cz[1];
  db_a << cx[2], cy[2], cz[2];
  dtheta << -cy[3], cx[3], cpsi[0];
  db_g << -cy[4], cx[4], cpsi[1];
  x->p_world += dp;
  x->v_world += dv;
  x->q_world_body = (ExpSO3(dtheta) * x->q_world_body).normalized();
  if (options_.estimate_offsets) {
    // The offsets are subtracted from the body-frame readings; the model's are world-frame.
    x->accel_offset += x->q_world_body.conjugate() * db_a;
    x->gyro_offset += x->q_world_body.conjugate() * db_g;
  }
  counters_.last_position_residual = r_p;
}

Status Estimator::Gate(const PoseMeasurement& pose, const EstimatorState& x) {
  if (options_.pose_gate_m <= 0 && options_.pose_gate_rad <= 0) return Status::Ok();
  const PoseSourceOptions& src = options_.pose_sources[pose.source];
  const Eigen::Vector3d r_p = pose.T_world_sensor.Translation() -
                              (x.p_world + x.q_world_body * src.T_body_sensor.Translation());
  const Eigen::Quaterniond q_meas =
      pose.T_world_sensor.Rotation() * src.T_body_sensor.Rotation().conjugate();
  const double r_t = LogSO3(q_meas * x.q_world_body.conjugate()).norm();
  const double since_s =
      std::max(0.0, NsToSeconds(pose.t_ns - std::max(counters_.last_accepted_t_ns, init_t_ns_)));
  const double gate_m = options_.pose_gate_m + options_.pose_gate_growth_mps * since_s;
  char why[160] = "";
  if (options_.pose_gate_m > 0 && r_p.norm() > gate_m) {
    std::snprintf(why, sizeof(why), "pose rejected: position residual %.3f m > gate %.3f m",
                  r_p.norm(), gate_m);
  } else if (options_.pose_gate_rad > 0 && r_t > options_.pose_gate_rad) {
    std::snprintf(why, sizeof(why), "pose rejected: rotation residual %.3f rad > gate %.3f rad",
                  r_t, options_.pose_gate_rad);
  }
  if (why[0] == '\0') return Status::Ok();
  ++counters_.poses_rejected;
  return Status::FailedPrecondition(why);
}

PoseMeasurement Estimator::Aligned(const PoseMeasurement& pose, const EstimatorState& x,
                                   geometry::SE3* frame) const {
  const PoseSourceOptions& src = options_.pose_sources[pose.source];
  *frame = frames_[pose.source];
  PoseMeasurement out = pose;
  out.T_world_sensor = *frame * pose.T_world_sensor;
  if (src.align_tilt_s <= 0) return out;
  // The world's up in the body frame, by the estimate and by the pose: the rotation Q (about a
  // horizontal axis, so the heading stays) that takes the pose's up onto the estimate's is its
  // tilt error; a fraction of it per pose is the first-order filter of time constant
  // align_tilt_s.
  const Eigen::Quaterniond q_meas =
      out.T_world_sensor.Rotation() * src.T_body_sensor.Rotation().conjugate();
  const Eigen::Vector3d up_body = x.q_world_body.conjugate() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_seen = q_meas * up_body;
  const Eigen::AngleAxisd full(
      Eigen::Quaterniond::FromTwoVectors(up_seen, Eigen::Vector3d::UnitZ()));
  const double fraction = std::min(1.0, 1.0 / (src.rate_hz * src.align_tilt_s));
  const Eigen::Quaterniond q_fix(Eigen::AngleAxisd(fraction * full.angle(), full.axis()));
  // Turned about the body's position (whichever sensor the source reports): the corrected
  // track stays continuous, and the frame is the same for any mounting.
  const Eigen::Vector3d c = (out.T_world_sensor * src.T_body_sensor.Inverse()).Translation();
  const geometry::SE3 turn(q_fix, c - q_fix * c);
  *frame = turn * *frame;
  out.T_world_sensor = turn * out.T_world_sensor;
  return out;
}

Status Estimator::FeedPose(const PoseMeasurement& raw) {
  PoseMeasurement pose = raw;
  if (pose.source < 0 || pose.source >= static_cast<int>(options_.pose_sources.size())) {
    return Status::InvalidArgument("source: unknown pose source " + std::to_string(pose.source));
  }
  if (size_ == 0 || pose.t_ns < At(0).imu.t_ns || (initialized_ && pose.t_ns < init_t_ns_)) {
    ++counters_.poses_dropped;
    return Status::OutOfRange("pose stamp older than the IMU buffer (or no IMU yet)");
  }
  // The last buffered sample at or before the stamp (binary search over the ring).
  int lo = 0, hi = size_ - 1;
  while (lo < hi) {
    const int mid = (lo + hi + 1) / 2;
    if (At(mid).imu.t_ns <= pose.t_ns) {
      lo = mid;
    } else {
      hi = mid - 1;
    }
  }
  const int j = lo;
  const int64_t t_j = At(j).imu.t_ns;
  EstimatorState x = At(j).state;
  if (!initialized_) {
    // The first pose initialises position and orientation (at the sample before its stamp).
    const PoseSourceOptions& src = options_.pose_sources[pose.source];
    const geometry::SE3 T_world_body = pose.T_world_sensor * src.T_body_sensor.Inverse();
    x = EstimatorState();
    x.p_world = T_world_body.Translation();
    x.q_world_body = T_world_body.Rotation();
    x.t_ns = t_j;
    At(j).state = x;
    initialized_ = true;
    init_t_ns_ = t_j;
    ++updates_per_source_[pose.source];
    applied_size_ = 0;
  } else {
    geometry::SE3 frame;
    pose = Aligned(raw, x, &frame);
    if (Status gate = Gate(pose, x); !gate.ok()) return gate;
    frames_[pose.source] = frame;
    // Remember the pose (stamp order) with its weights, forgetting those older than the buffer.
    const int64_t oldest = At(0).imu.t_ns;
    int keep = 0;
    for (int i = 0; i < applied_size_; ++i) {
      if (applied_[i].pose.t_ns >= oldest) applied_[keep++] = applied_[i];
    }
    applied_size_ = keep;
    if (applied_size_ == static_cast<int>(applied_.size())) {  // full: drop the oldest
      std::move(applied_.begin() + 1, applied_.end(), applied_.begin());
      --applied_size_;
    }
    int pos = applied_size_;
    while (pos > 0 && applied_[pos - 1].pose.t_ns > pose.t_ns) {
      applied_[pos] = applied_[pos - 1];
      --pos;
    }
    applied_[pos] = Applied{pose, NextWeights(pose.source)};
    ++applied_size_;
  }
  counters_.last_accepted_t_ns = std::max(counters_.last_accepted_t_ns, pose.t_ns);
  // Re-apply the IMU after t_j, and every pose stamped from t_j on at its stamp (in stamp order):
  // the state stored at each sample holds the corrections stamped before it, so a late pose, or
  // one arriving out of stamp order, leaves the estimate a filter fed in stamp order would have.
  int next = 0;
  while (next < applied_size_ && applied_[next].pose.t_ns < t_j) ++next;
  int64_t t_x = t_j;
  for (int k = j + 1; k <= size_; ++k) {
    const bool last = k == size_;
    const int64_t t_k = last ? std::numeric_limits<int64_t>::max() : At(k).imu.t_ns;
    while (next < applied_size_ && applied_[next].pose.t_ns < t_k) {
      const Applied& a = applied_[next++];
      // Poses stamped after the newest sample are applied at it.
      const int64_t t_a = last ? t_x : a.pose.t_ns;
      if (t_a > t_x) {
        Propagate(At(k).imu, NsToSeconds(t_a - t_x), &x);
        t_x = t_a;
      }
      Correct(a.pose, a.weights, &x);
    }
    if (last) break;
    Entry& e = At(k);
    Propagate(e.imu, NsToSeconds(e.imu.t_ns - t_x), &x);
    t_x = e.imu.t_ns;
    x.t_ns = t_x;
    e.state = x;
  }
  x.t_ns = At(size_ - 1).imu.t_ns;
  // The latest sample's rates with the corrected offset.
  x.omega_body = At(size_ - 1).imu.gyro - x.gyro_offset;
  current_ = x;
  ++counters_.poses_merged;
  counters_.last_pose_t_ns = std::max(counters_.last_pose_t_ns, pose.t_ns);
  return Status::Ok();
}

}  // namespace mav::control
