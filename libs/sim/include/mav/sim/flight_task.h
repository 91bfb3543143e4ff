#pragma once
// The EuRoC 2014 Challenge 3 simulation tasks as data (docs/control.md, "The
// tasks"; the task types are in mav/dataset/flight_task.h, every figure overridable
// from a task file, mav/dataset/flight_task_io.h):
//   t3_1  hover at (0, 0, 1); the set point is published at 10 s, scored 15-25 s.
//   t3_2  t3_1 + a constant 2 N along normalise(1, 1, -0.3) from 40 s (to 240 s).
//   t3_3  t3_1 + a 5 N gust along normalise(1, 1, 0) from 40 s to 42 s.
//   t4_1  waypoints (20,0,9) (20,20,1) (0,20,9) (0,0,1), one every 60 s from 10 s.
//   t4_2  t4_1 + a second pose sensor: 20 Hz, 80 ms late, 1 ms stamp offset, mounted at
//         (-0.05, 0.08, 0.1) m, rpy (-0.1, 0.2, -0.3) rad.
//   t4_3  the power plant (power_plant.bt): (2,-27,15) (20,-15,15) (25,0,5) (0,0,1), 110 s
//         each from 10 s, yaw 0, spawning on the ground at z = 0.18 m.
// Where the contest's files leave a figure open (the initial state and the t3 set point, which
// our sources do not give), the vehicle spawns resting on the ground, takes off to the task's
// takeoff_position once its estimator has converged, and the first goal is published at 10 s.
// The pose sensors are the contest's: 10 Hz, 100 ms late, sigma 0.01 m / 0.017 rad, mounted at
// (0.03, -0.07, 0.1) m / rpy (0.2, -0.1, 0.3) rad; the IMU: 100 Hz with offsets
// (0.2, 0.1, -0.3) m/s^2 and (-0.02, 0.008, -0.01) rad/s, noise 0.04 m/s^2 and 0.0033937 rad/s,
// drift 0.09 m/s^2 and 6e-4 rad/s (1 sigma over 240 s).

#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/dataset/flight_task.h"

namespace mav::sim {

// t3_1, t3_2, t3_3, t4_1, t4_2, t4_3.
const std::vector<std::string>& FlightTaskNames();

// Where the contest's power-plant map (the OctoMap t4_3 flies in) is: $MAV_PLANT_MAP when set
// (the container images set it), otherwise the copy in the source tree, maps/power_plant.bt.
std::string DefaultPlantMapPath();

// NotFound naming the known tasks for an unknown name. t4_3's map_path is `plant_map_path`.
Result<dataset::FlightTask> BuiltinFlightTask(const std::string& name,
                                              const std::string& plant_map_path);
inline Result<dataset::FlightTask> BuiltinFlightTask(const std::string& name) {
  return BuiltinFlightTask(name, DefaultPlantMapPath());
}

// A built-in task name (t3_1 ... t4_3) or a task file (*.yaml, over t3_1 unless it names its
// base, mav/dataset/flight_task_io.h). NotFound / InvalidArgument naming the task or the file's
// key.
Result<dataset::FlightTask> FlightTaskFromSpec(const std::string& name_or_file,
                                               const std::string& plant_map_path);

}  // namespace mav::sim
