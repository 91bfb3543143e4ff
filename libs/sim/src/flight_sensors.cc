#include "mav/sim/flight_sensors.h"

#include <cmath>

#include "mav/common/check.h"
#include "mav/common/time.h"
#include "random.h"

namespace mav::sim {

namespace {

// Counter-based normal deviates: state advanced by the generator of random.h.
double NextNormal(uint64_t* state) {
  internal::Rng rng(*state);
  *state = rng.Next();
  return rng.Normal();
}

}  // namespace

FlightImu::FlightImu(const dataset::FlightImuSpec& spec, uint64_t seed)
    : spec_(spec),
      rng_state_(internal::HashCombine(seed, 0x1A1ULL)),
      accel_offset_(spec.accel_offset),
      gyro_offset_(spec.gyro_offset) {}

double FlightImu::Normal() { return NextNormal(&rng_state_); }

dataset::ImuSample FlightImu::Sample(int64_t t_ns, const Eigen::Vector3d& omega_body,
                                     const Eigen::Vector3d& specific_force_body) {
  if (last_t_ns_ >= 0 && t_ns > last_t_ns_) {
    const double scale = std::sqrt(NsToSeconds(t_ns - last_t_ns_) / spec_.drift_horizon_s);
    for (int a = 0; a < 3; ++a) accel_offset_[a] += spec_.accel_drift_sigma * scale * Normal();
    for (int a = 0; a < 3; ++a) gyro_offset_[a] += spec_.gyro_drift_sigma * scale * Normal();
  }
  last_t_ns_ = t_ns;
  dataset::ImuSample s;
  s.t_ns = t_ns;
  for (int a = 0; a < 3; ++a) {
    s.gyro[a] = omega_body[a] + gyro_offset_[a] + spec_.gyro_noise_sigma * Normal();
  }
  for (int a = 0; a < 3; ++a) {
    s.accel[a] = specific_force_body[a] + accel_offset_[a] + spec_.accel_noise_sigma * Normal();
  }
  return s;
}

FlightPoseSensor::FlightPoseSensor(const dataset::FlightPoseSensorSpec& spec, int index,
                                   uint64_t seed)
    : spec_(spec),
      index_(index),
      T_body_sensor_(spec.T_body_sensor()),
      rng_state_(internal::HashCombine(seed, 0x9053ULL + static_cast<uint64_t>(index))),
      period_ns_(PeriodNs(spec.rate_hz)),
      delay_ns_(SecondsToNs(spec.delay_s)),
      stamp_offset_ns_(SecondsToNs(spec.stamp_offset_s)) {
  MAV_CHECK(period_ns_ > 0) << "pose sensor rate " << spec.rate_hz;
  next_sample_ns_ = std::isfinite(spec.active_from_s) ? SecondsToNs(spec.active_from_s) : 0;
  // Samples in flight: the delay over the period, plus slack.
  queue_.resize(static_cast<size_t>(delay_ns_ / period_ns_) + 4);
}

double FlightPoseSensor::Normal() { return NextNormal(&rng_state_); }

void FlightPoseSensor::Observe(int64_t t_ns, const geometry::SE3& T_world_body) {
  if (t_ns < next_sample_ns_) return;
  // Catch up if the caller steps slower than the sensor's period (one sample per call).
  while (next_sample_ns_ + period_ns_ <= t_ns) next_sample_ns_ += period_ns_;
  next_sample_ns_ += period_ns_;
  if (std::isfinite(spec_.active_until_s) && t_ns >= SecondsToNs(spec_.active_until_s)) return;
  const geometry::SE3 T_world_sensor = T_world_body * T_body_sensor_;
  Eigen::Vector3d dp, dr;
  for (int a = 0; a < 3; ++a) dp[a] = spec_.position_sigma_m * Normal();
  for (int a = 0; a < 3; ++a) dr[a] = spec_.orientation_sigma_rad * Normal();
  PoseSample s;
  s.sensor = index_;
  s.t_ns = t_ns + stamp_offset_ns_;
  s.arrival_t_ns = t_ns + delay_ns_;
  s.T_world_sensor = geometry::SE3(T_world_sensor.Rotation() * geometry::ExpSO3(dr),
                                   T_world_sensor.Translation() + dp);
  MAV_CHECK(size_ < queue_.size()) << "pose sensor queue overflow";
  queue_[(head_ + size_) % queue_.size()] = s;
  ++size_;
}

int FlightPoseSensor::Deliver(int64_t t_ns, std::vector<PoseSample>* out) {
  int n = 0;
  while (size_ > 0 && queue_[head_].arrival_t_ns <= t_ns) {
    out->push_back(queue_[head_]);
    head_ = (head_ + 1) % queue_.size();
    --size_;
    ++n;
  }
  return n;
}

}  // namespace mav::sim
