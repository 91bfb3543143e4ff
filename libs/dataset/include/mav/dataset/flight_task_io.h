#pragma once
// Task files: a YAML mapping that overrides figures of a built-in flight task (flight_task.h).
// Every key is optional; a key the reader does not know, a value of the wrong type or out of
// range is an InvalidArgument naming the file and the key ("f.yaml: forces[0].start_s: 'x' is
// not a number"). The result is checked with FlightTask::IsValid.
//
//   base: t3_2                   # the built-in task to start from (else the caller's default)
//   name: t3_2_strong            # default: the base's name
//   duration_s: 80
//   setpoint: [0, 0, 1.5]        # kHover/kDisturbance: the (only) goal's position
//   goals:                       # replaces the goals
//     - {publish_s: 10, position: [0, 0, 1], yaw_rad: 0}
//   waypoints: [[20, 0, 9], [20, 20, 1]]   # replaces the goals, one every waypoint_interval_s
//   waypoint_interval_s: 60      #   (first at waypoint_start_s, default 0)
//   spawn: {position: [0, 0, 0.08], yaw_rad: 0}
//   ground_z_m: 0
//   takeoff_position: [0, 0, 1]
//   forces:                      # replaces the forces; force_n or magnitude_n + direction
//     - {magnitude_n: 2, direction: [1, 1, -0.3], start_s: 40, end_s: 240}
//   imu: {rate_hz, accel_offset, gyro_offset, accel_noise_sigma, gyro_noise_sigma,
//         accel_drift_sigma, gyro_drift_sigma, drift_horizon_s}
//   pose_sensors:                # entry i overrides the base's sensor i (a new i adds one,
//     - {rate_hz, delay_s, stamp_offset_s, position_sigma_m, orientation_sigma_rad,
//        mount_xyz_m, mount_rpy_rad, active_from_s, active_until_s}   # starting from sensor 0)
//   pose_sensor_count: 1         # drop sensors beyond this many
//   map: FILE.bt                 (an OctoMap; a relative path is from the task file's folder)
//   vehicle_radius_m: 0.35
//   scoring: {window_s, hover_delay_s, settle_radius_m, settle_hold_s, settle_limit_s,
//             position_limit_m, angular_rate_limit_radps}

#include <functional>
#include <string>

#include "mav/common/status.h"
#include "mav/dataset/flight_task.h"

namespace mav::dataset {

// Returns the built-in task of a name (NotFound / InvalidArgument for an unknown one).
using FlightTaskResolver = std::function<Result<FlightTask>(const std::string& name)>;

// Parses `text` (named `source` in messages) over the task `base:` names, or `default_base`.
Result<FlightTask> ParseFlightTaskYaml(const std::string& text, const std::string& source,
                                       const FlightTaskResolver& resolve,
                                       const std::string& default_base);
// Reads and parses a task file; NotFound / IoError when it cannot be read.
Result<FlightTask> ReadFlightTaskFile(const std::string& path, const FlightTaskResolver& resolve,
                                      const std::string& default_base);

}  // namespace mav::dataset
