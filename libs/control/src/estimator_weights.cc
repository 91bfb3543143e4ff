#include "mav/control/estimator_weights.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

#include <Eigen/Core>

#include "mav/common/time.h"

namespace mav::control {

bool WeightModel::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  auto positive = [](double x) { return x > 0 && std::isfinite(x); };
  auto non_negative = [](double x) { return x >= 0 && std::isfinite(x); };
  if (!positive(imu_rate_hz) || imu_rate_hz > 10000)
    return fail("imu_rate_hz: must be in (0, 10000]");
  if (!positive(accel_noise_sigma)) return fail("accel_noise_sigma: must be positive");
  if (!positive(gyro_noise_sigma)) return fail("gyro_noise_sigma: must be positive");
  if (!non_negative(accel_offset_random_walk))
    return fail("accel_offset_random_walk: must be >= 0");
  if (!non_negative(gyro_offset_random_walk)) return fail("gyro_offset_random_walk: must be >= 0");
  if (!positive(initial_velocity_sigma)) return fail("initial_velocity_sigma: must be positive");
  if (!non_negative(initial_accel_offset_sigma)) {
    return fail("initial_accel_offset_sigma: must be >= 0");
  }
  if (!non_negative(initial_gyro_offset_sigma)) {
    return fail("initial_gyro_offset_sigma: must be >= 0");
  }
  if (sources.empty()) return fail("sources: at least one pose source");
  for (size_t i = 0; i < sources.size(); ++i) {
    const std::string f = "sources[" + std::to_string(i) + "].";
    if (!positive(sources[i].rate_hz) || sources[i].rate_hz > imu_rate_hz) {
      return fail(f + "rate_hz: must be in (0, imu_rate_hz]");
    }
    if (!positive(sources[i].position_sigma_m)) return fail(f + "position_sigma_m: must be > 0");
    if (!positive(sources[i].orientation_sigma_rad)) {
      return fail(f + "orientation_sigma_rad: must be > 0");
    }
  }
  return true;
}

namespace {

// One decoupled axis model (translation: 3 states, rotation: 2 states) run through the Riccati
// recursion. Fixed-size matrices: N = 3 or 2.
template <int N>
struct AxisFilter {
  using Mat = Eigen::Matrix<double, N, N>;
  using Vec = Eigen::Matrix<double, N, 1>;
  Mat F, Q, P;
  void Predict() { P = F * P * F.transpose() + Q; }
  // Measurement of state 0 with variance r; returns the gain and updates P (Joseph form).
  Vec Update(double r) {
    const Vec k = P.col(0) / (P(0, 0) + r);
    Mat ikh = Mat::Identity();
    ikh.col(0) -= k;
    P = ikh * P * ikh.transpose() + r * k * k.transpose();
    return k;
  }
};

}  // namespace

Result<WeightSchedule> ComputeWeightSchedule(const WeightModel& model) {
  if (std::string why; !model.IsValid(&why)) return Status::InvalidArgument(why);
  const int64_t imu_ns = PeriodNs(model.imu_rate_hz);
  const double h = NsToSeconds(imu_ns);
  const int num_sources = static_cast<int>(model.sources.size());

  // Each source's samples fall on the IMU tick nearest to a multiple of its period; the schedule
  // repeats after the least common multiple of the periods in ticks (capped at 10 s: beyond it
  // the average over the capped window is used).
  std::vector<int64_t> period_ticks(num_sources);
  int64_t hyper = 1;
  for (int s = 0; s < num_sources; ++s) {
    period_ticks[s] = std::max<int64_t>(
        1, std::llround(static_cast<double>(PeriodNs(model.sources[s].rate_hz)) / imu_ns));
    hyper = std::lcm(hyper, period_ticks[s]);
    hyper = std::min<int64_t>(hyper, std::llround(10.0 / h));
  }

  AxisFilter<3> tr;
  tr.F << 1, h, 0, 0, 1, -h, 0, 0, 1;
  tr.Q.setZero();
  tr.Q(1, 1) = h * h * model.accel_noise_sigma * model.accel_noise_sigma;
  tr.Q(2, 2) = h * model.accel_offset_random_walk * model.accel_offset_random_walk;
  AxisFilter<2> rot;
  rot.F << 1, -h, 0, 1;
  rot.Q.setZero();
  rot.Q(0, 0) = h * h * model.gyro_noise_sigma * model.gyro_noise_sigma;
  rot.Q(1, 1) = h * model.gyro_offset_random_walk * model.gyro_offset_random_walk;
  // The first pose initialises position and orientation with that source's noise.
  const PoseSourceNoise& first = model.sources[0];
  tr.P = Eigen::Vector3d(first.position_sigma_m * first.position_sigma_m,
                         model.initial_velocity_sigma * model.initial_velocity_sigma,
                         model.initial_accel_offset_sigma * model.initial_accel_offset_sigma)
             .asDiagonal();
  rot.P = Eigen::Vector2d(first.orientation_sigma_rad * first.orientation_sigma_rad,
                          model.initial_gyro_offset_sigma * model.initial_gyro_offset_sigma)
              .asDiagonal();

  auto gains = [](const Eigen::Vector3d& kt, const Eigen::Vector2d& kr) {
    return CorrectionWeights{kt[0], kt[1], kt[2], kr[0], kr[1]};
  };
  auto distance = [](const CorrectionWeights& a, const CorrectionWeights& b) {
    // Relative change per weight (the offset gains are tiny in absolute terms).
    auto rel = [](double x, double y) { return std::abs(x - y) / std::max(std::abs(y), 1e-300); };
    return std::max({rel(a.position, b.position), rel(a.velocity, b.velocity),
                     rel(a.accel_offset, b.accel_offset), rel(a.orientation, b.orientation),
                     rel(a.gyro_offset, b.gyro_offset)});
  };

  WeightSchedule out;
  out.transient.assign(num_sources, {});
  std::vector<std::vector<CorrectionWeights>> period_gains(num_sources), last_period;
  // The transient schedule keeps each source's gains until they are within 1e-3 (relative) of the
  // steady state, which is only known at the end: store them all, trim afterwards.
  constexpr int kMaxPeriods = 200000;
  bool converged = false;
  int periods = 0;
  for (; periods < kMaxPeriods && !converged; ++periods) {
    for (auto& g : period_gains) g.clear();
    for (int64_t tick = 1; tick <= hyper; ++tick) {
      tr.Predict();
      rot.Predict();
      for (int s = 0; s < num_sources; ++s) {
        if (tick % period_ticks[s] != 0) continue;
        const PoseSourceNoise& src = model.sources[s];
        const Eigen::Vector3d kt = tr.Update(src.position_sigma_m * src.position_sigma_m);
        const Eigen::Vector2d kr =
            rot.Update(src.orientation_sigma_rad * src.orientation_sigma_rad);
        period_gains[s].push_back(gains(kt, kr));
        if (out.transient[s].size() < 100000) out.transient[s].push_back(gains(kt, kr));
      }
    }
    if (!last_period.empty()) {
      double change = 0;
      for (int s = 0; s < num_sources; ++s) {
        for (size_t k = 0; k < period_gains[s].size(); ++k) {
          change = std::max(change, distance(period_gains[s][k], last_period[s][k]));
        }
      }
      converged = change < 1e-12;
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
      mean.position += g.position / n;
      mean.velocity += g.velocity / n;
      mean.accel_offset += g.accel_offset / n;
      mean.orientation += g.orientation / n;
      mean.gyro_offset += g.gyro_offset / n;
    }
    out.steady[s] = mean;
    // Trim the transient where every gain is within 1e-3 of its periodic steady value (the
    // same position in the schedule's period) from then on.
    auto& tr_s = out.transient[s];
    const size_t m = period_gains[s].size();
    size_t keep = tr_s.size();
    while (keep > 0 && distance(tr_s[keep - 1], period_gains[s][(keep - 1) % m]) < 1e-3) --keep;
    tr_s.resize(keep);
  }
  return out;
}

}  // namespace mav::control
