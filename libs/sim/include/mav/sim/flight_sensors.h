#pragma once
// The contest's sensors for a stepped vehicle (specs in mav/dataset/flight_task.h), each
// deterministic for its seed (the library's portable generator, identical on every platform).
//
//  * FlightImu: gyro = w + b_g + n_g, accel = f + b_a + n_a (f the specific force, body frame),
//    n white with the spec's sigma per sample; the offsets b start at the spec's values and
//    drift as random walks whose change over drift_horizon_s has sigma *_drift_sigma, i.e. a
//    step of sigma * sqrt(dt / horizon) per sample.
//  * FlightPoseSensor: at each multiple of its period inside its active window it measures
//    T_world_sensor = T_world_body T_body_sensor with position noise (world, per axis) and a
//    rotation-vector noise in the sensor frame, stamps it (sampling time + stamp_offset_s) and
//    releases it delay_s later. The queue has fixed capacity (no allocation per step).

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "mav/dataset/flight_task.h"
#include "mav/dataset/types.h"
#include "mav/geometry/se3.h"

namespace mav::sim {

class FlightImu {
 public:
  FlightImu(const dataset::FlightImuSpec& spec, uint64_t seed);
  // A reading at t_ns for the true body rate and specific force; advances the drift by the time
  // since the previous reading.
  dataset::ImuSample Sample(int64_t t_ns, const Eigen::Vector3d& omega_body,
                            const Eigen::Vector3d& specific_force_body);
  const Eigen::Vector3d& accel_offset() const { return accel_offset_; }
  const Eigen::Vector3d& gyro_offset() const { return gyro_offset_; }

 private:
  dataset::FlightImuSpec spec_;
  uint64_t rng_state_;
  Eigen::Vector3d accel_offset_, gyro_offset_;
  int64_t last_t_ns_ = -1;
  double Normal();
};

// A pose as a pose sensor delivers it.
struct PoseSample {
  int sensor = 0;
  int64_t t_ns = 0;          // its stamp (sampling time + stamp offset)
  int64_t arrival_t_ns = 0;  // when it is delivered
  geometry::SE3 T_world_sensor;
};

class FlightPoseSensor {
 public:
  FlightPoseSensor(const dataset::FlightPoseSensorSpec& spec, int index, uint64_t seed);
  // Called at every simulation step with the true pose: takes a sample when one is due at t_ns.
  void Observe(int64_t t_ns, const geometry::SE3& T_world_body);
  // Moves the samples whose arrival time is <= t_ns to `out` (appending); returns how many.
  int Deliver(int64_t t_ns, std::vector<PoseSample>* out);
  const geometry::SE3& T_body_sensor() const { return T_body_sensor_; }
  const dataset::FlightPoseSensorSpec& spec() const { return spec_; }

 private:
  double Normal();
  dataset::FlightPoseSensorSpec spec_;
  int index_;
  geometry::SE3 T_body_sensor_;
  uint64_t rng_state_;
  int64_t period_ns_, delay_ns_, stamp_offset_ns_;
  int64_t next_sample_ns_ = 0;
  std::vector<PoseSample> queue_;  // ring of pending samples
  size_t head_ = 0, size_ = 0;
};

}  // namespace mav::sim
