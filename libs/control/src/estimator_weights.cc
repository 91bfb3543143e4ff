#include "mav/control/estimator_weights.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

#include <Eigen/LU>

#include "mav/common/time.h"
#include "mav/control/vehicle.h"

namespace mav::control {

CorrectionWeights CorrectionWeights::Decoupled(double position, double velocity,
                                               double accel_offset, double orientation,
                                               double gyro_offset) {
  CorrectionWeights w;
  w.horizontal(0, 0) = position;
  w.horizontal(1, 0) = velocity;
  w.horizontal(2, 0) = accel_offset;
  w.horizontal(3, 1) = orientation;
  w.horizontal(4, 1) = gyro_offset;
  w.vertical = Eigen::Vector3d(position, velocity, accel_offset);
  w.heading = Eigen::Vector2d(orientation, gyro_offset);
  return w;
}

bool WeightModel::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  auto positive = [](double x) { return x > 0 && std::isfinite(x); };
  auto non_negative = [](double x) { return x >= 0 && std::isfinite(x); };
  if (!positive(imu_rate_hz) || imu_rate_hz > 10000) {
    return fail("imu_rate_hz: must be in (0, 10000]");
  }
  if (!positive(accel_noise_sigma)) return fail("accel_noise_sigma: must be positive");
  if (!positive(gyro_noise_sigma)) return fail("gyro_noise_sigma: must be positive");
  if (!non_negative(trust_tilt_s) || trust_tilt_s > 60) {
    return fail("trust_tilt_s: must be in [0, 60]");
  }
  if (!non_negative(accel_offset_random_walk)) {
    return fail("accel_offset_random_walk: must be >= 0");
  }
  if (!non_negative(gyro_offset_random_walk)) return fail("gyro_offset_random_walk: must be >= 0");
  if (!positive(initial_velocity_sigma)) return fail("initial_velocity_sigma: must be positive");
  if (!non_negative(initial_accel_offset_sigma)) {
    return fail("initial_accel_offset_sigma: must be >= 0");
  }
  if (!non_negative(initial_gyro_offset_sigma)) {
    return fail("initial_gyro_offset_sigma: must be >= 0");
  }
  if (pose_sources.empty()) return fail("pose_sources: at least one pose source");
  for (size_t i = 0; i < pose_sources.size(); ++i) {
    const std::string f = "pose_sources[" + std::to_string(i) + "].";
    if (!positive(pose_sources[i].rate_hz) || pose_sources[i].rate_hz > imu_rate_hz) {
      return fail(f + "rate_hz: must be in (0, imu_rate_hz]");
    }
    if (!positive(pose_sources[i].position_sigma_m))
      return fail(f + "position_sigma_m: must be > 0");
    if (!positive(pose_sources[i].orientation_sigma_rad)) {
      return fail(f + "orientation_sigma_rad: must be > 0");
    }
    if (!(pose_sources[i].tilt_sigma_rad >= 0 && std::isfinite(pose_sources[i].tilt_sigma_rad))) {
      return fail(f + "tilt_sigma_rad: must be >= 0 (0 = orientation_sigma_rad)");
    }
  }
  return true;
}

namespace {

// One axis model run through the Riccati recursion: N states, M measured (the first M rows of
// `measured` select them).
template <int N, int M>
struct AxisFilter {
  using Mat = Eigen::Matrix<double, N, N>;
  Mat F, Q, P;
  Eigen::Matrix<double, M, N> H;
  void Predict() { P = F * P * F.transpose() + Q; }
  // Joint update with measurement variances r; returns the gain, updates P (Joseph form).
  Eigen::Matrix<double, N, M> Update(const Eigen::Matrix<double, M, 1>& r) {
    const Eigen::Matrix<double, M, M> s =
        H * P * H.transpose() + Eigen::Matrix<double, M, M>(r.asDiagonal());
    Eigen::Matrix<double, N, M> k = P * H.transpose() * s.inverse();
    const Mat ikh = Mat::Identity() - k * H;
    P = ikh * P * ikh.transpose() + k * r.asDiagonal() * k.transpose();
    return k;
  }
};

double RelativeChange(const CorrectionWeights& a, const CorrectionWeights& b) {
  auto rel = [](double x, double y) { return std::abs(x - y) / std::max(std::abs(y), 1e-300); };
  double m = 0;
  for (int i = 0; i < 10; ++i) {
    // Entries that are zero in the model stay exactly zero.
    const double x = a.horizontal.data()[i], y = b.horizontal.data()[i];
    if (x != 0 || y != 0) m = std::max(m, rel(x, y));
  }
  for (int i = 0; i < 3; ++i) m = std::max(m, rel(a.vertical[i], b.vertical[i]));
  for (int i = 0; i < 2; ++i) m = std::max(m, rel(a.heading[i], b.heading[i]));
  return m;
}

}  // namespace

Result<WeightSchedule> ComputeWeightSchedule(const WeightModel& model) {
  if (std::string why; !model.IsValid(&why)) return Status::InvalidArgument(why);
  const int64_t imu_ns = PeriodNs(model.imu_rate_hz);
  const double h = NsToSeconds(imu_ns);
  const int num_sources = static_cast<int>(model.pose_sources.size());

  // Each source's samples fall on the IMU tick nearest to a multiple of its period; the schedule
  // repeats after the least common multiple of the periods in ticks (capped at 10 s: beyond it
  // the average over the capped window is used).
  std::vector<int64_t> period_ticks(num_sources);
  int64_t hyper = 1;
  for (int s = 0; s < num_sources; ++s) {
    period_ticks[s] = std::max<int64_t>(
        1, std::llround(static_cast<double>(PeriodNs(model.pose_sources[s].rate_hz)) / imu_ns));
    hyper = std::lcm(hyper, period_ticks[s]);
    hyper = std::min<int64_t>(hyper, std::llround(10.0 / h));
  }

  // Offsets that never drift would make their gains decay like 1/k for ever; a floor far below
  // any real IMU's drift keeps the recursion convergent.
  const double qa = h * model.accel_noise_sigma * model.accel_noise_sigma * h;
  const double qg = h * model.gyro_noise_sigma * model.gyro_noise_sigma * h;
  const double walk_a = std::max(model.accel_offset_random_walk, 1e-5);
  const double walk_g = std::max(model.gyro_offset_random_walk, 1e-7);
  const double qba = h * walk_a * walk_a, qbg = h * walk_g * walk_g;
  const PoseSourceNoise& first = model.pose_sources[0];
  const double p0 = first.position_sigma_m * first.position_sigma_m;
  const double t0 = first.orientation_sigma_rad * first.orientation_sigma_rad;
  const double v0 = model.initial_velocity_sigma * model.initial_velocity_sigma;
  const double ba0 = model.initial_accel_offset_sigma * model.initial_accel_offset_sigma;
  const double bg0 = model.initial_gyro_offset_sigma * model.initial_gyro_offset_sigma;
  const double g_tilt = model.couple_tilt ? kGravity : 0.0;

  AxisFilter<5, 2> hor;         // [p, v, b_a, theta, b_g]
  hor.F << 1, h, 0, 0, 0,       //
      0, 1, -h, h * g_tilt, 0,  //
      0, 0, 1, 0, 0,            //
      0, 0, 0, 1, -h,           //
      0, 0, 0, 0, 1;
  hor.Q = Eigen::Matrix<double, 5, 1>(0, qa, qba, qg, qbg).asDiagonal();
  hor.P = Eigen::Matrix<double, 5, 1>(p0, v0, ba0, t0, bg0).asDiagonal();
  hor.H.setZero();
  hor.H(0, 0) = 1;
  hor.H(1, 3) = 1;
  AxisFilter<3, 1> ver;  // [p, v, b_a]
  ver.F << 1, h, 0, 0, 1, -h, 0, 0, 1;
  ver.Q = Eigen::Vector3d(0, qa, qba).asDiagonal();
  ver.P = Eigen::Vector3d(p0, v0, ba0).asDiagonal();
  ver.H << 1, 0, 0;
  AxisFilter<2, 1> yaw;  // [psi, b_g]
  yaw.F << 1, -h, 0, 1;
  yaw.Q = Eigen::Vector2d(qg, qbg).asDiagonal();
  yaw.P = Eigen::Vector2d(t0, bg0).asDiagonal();
  yaw.H << 1, 0;

  WeightSchedule out;
  out.transient.assign(num_sources, {});
  std::vector<std::vector<CorrectionWeights>> period_gains(num_sources), last_period;
  constexpr int kMaxPeriods = 200000;
  constexpr size_t kMaxTransient = 100000;
  bool converged = false;
  int periods = 0;
  for (; periods < kMaxPeriods && !converged; ++periods) {
    for (auto& g : period_gains) g.clear();
    for (int64_t tick = 1; tick <= hyper; ++tick) {
      hor.Predict();
      ver.Predict();
      yaw.Predict();
      for (int s = 0; s < num_sources; ++s) {
        if (tick % period_ticks[s] != 0) continue;
        const PoseSourceNoise& src = model.pose_sources[s];
        const double rp = src.position_sigma_m * src.position_sigma_m;
        const double rt = src.orientation_sigma_rad * src.orientation_sigma_rad;
        // The source's own tilt weighs in until trust_tilt_s (see WeightModel).
        const double tilt_sigma =
            NsToSeconds((periods * hyper + tick) * imu_ns) < model.trust_tilt_s
                ? src.orientation_sigma_rad
                : src.TiltSigma();
        const double rtilt = tilt_sigma * tilt_sigma;
        CorrectionWeights w;
        w.horizontal = hor.Update(Eigen::Vector2d(rp, rtilt));
        w.vertical = ver.Update(Eigen::Matrix<double, 1, 1>(rp));
        w.heading = yaw.Update(Eigen::Matrix<double, 1, 1>(rt));
        period_gains[s].push_back(w);
        if (out.transient[s].size() < kMaxTransient) out.transient[s].push_back(w);
      }
    }
    if (!last_period.empty()) {
      double change = 0;
      for (int s = 0; s < num_sources; ++s) {
        for (size_t k = 0; k < period_gains[s].size(); ++k) {
          change = std::max(change, RelativeChange(period_gains[s][k], last_period[s][k]));
        }
      }
      // (Not before the sources' tilt changes its weight.)
      converged =
          change < 1e-12 && NsToSeconds((periods + 1) * hyper * imu_ns) > model.trust_tilt_s;
    }
    last_period = period_gains;
  }
  if (!converged) {
    return Status::Internal("estimator weights: the Riccati recursion did not converge");
  }
  out.iterations = periods;
  out.steady.resize(num_sources);
  for (int s = 0; s < num_sources; ++s) {
    CorrectionWeights mean;
    const double n = static_cast<double>(period_gains[s].size());
    for (const CorrectionWeights& g : period_gains[s]) {
      mean.horizontal += g.horizontal / n;
      mean.vertical += g.vertical / n;
      mean.heading += g.heading / n;
    }
    out.steady[s] = mean;
    // Trim the transient where every gain is within 1e-3 of its periodic steady value (the
    // same position in the schedule's period) from then on.
    auto& tr_s = out.transient[s];
    const size_t m = period_gains[s].size();
    size_t keep = tr_s.size();
    while (keep > 0 && RelativeChange(tr_s[keep - 1], period_gains[s][(keep - 1) % m]) < 1e-3) {
      --keep;
    }
    tr_s.resize(keep);
  }
  return out;
}

}  // namespace mav::control
