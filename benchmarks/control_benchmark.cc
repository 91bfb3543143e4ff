// Hot paths of the flight stack: one estimator + controller + allocation step of the autopilot
// (target <= 20 us on one core), one simulation step (1 kHz RK4 over a 10 ms IMU period, sensors,
// collision check), the a-priori weight computation, and a whole lock-stepped 60 s hover.
//   taskset -c 1 build/bin/benchmarks/control_benchmark --benchmark_min_time=2

#include <benchmark/benchmark.h>

#include "mav/common/time.h"
#include "mav/control/autopilot.h"
#include "mav/eval/flight_mission.h"
#include "mav/sim/flight_simulation.h"
#include "mav/sim/flight_task.h"

namespace {

using namespace mav;  // NOLINT(build/namespaces): a benchmark program

// A simulation and an autopilot hovering at 1 m (armed, converged).
struct Hovering {
  sim::FlightSimulation sim;
  control::Autopilot ap;
  const sim::FlightStep* out;

  static Hovering Make(control::ControllerType c) {
    const dataset::FlightTask t = *sim::BuiltinFlightTask("t3_1");
    Hovering h{*sim::FlightSimulation::Create(t, 3),
               *control::Autopilot::Create(eval::AutopilotOptionsForTask(t, c)), nullptr};
    h.out = &h.sim.Initial();
    while (NsToSeconds(h.sim.t_ns()) < 12) {
      if (!h.ap.armed() && h.ap.estimator().converged()) {
        (void)h.ap.Arm();
        (void)h.ap.Hover(Eigen::Vector3d(0, 0, 1), 0);
      }
      h.Step();
    }
    return h;
  }
  // One lock-step; returns the autopilot's time for it (ns).
  int64_t Step() {
    const int64_t start = MonotonicNowNs();
    for (const sim::PoseSample& p : out->poses) {
      (void)ap.FeedPose(control::PoseMeasurement{p.t_ns, p.sensor, p.T_world_sensor});
    }
    const control::RotorVector& cmd =
        ap.FeedImu(control::ImuMeasurement{out->imu.t_ns, out->imu.gyro, out->imu.accel});
    const int64_t ns = MonotonicNowNs() - start;
    sim::RotorVector c(cmd.size());
    for (int i = 0; i < cmd.size(); ++i) c[i] = cmd[i];
    out = &sim.Step(c);
    return ns;
  }
};

// Per IMU sample: FeedPose (every 10th sample: merge at the stamp and re-apply 10 samples) +
// FeedImu (prediction, disturbance observer, controller, allocation).
void BM_AutopilotStep(benchmark::State& state) {
  Hovering h = Hovering::Make(static_cast<control::ControllerType>(state.range(0)));
  for (auto _ : state) state.SetIterationTime(h.Step() * 1e-9);
  state.SetLabel(state.range(0) == 0 ? "paper" : "lee");
}
BENCHMARK(BM_AutopilotStep)->Arg(0)->Arg(1)->UseManualTime()->Unit(benchmark::kMicrosecond);

void BM_SimulationStep(benchmark::State& state) {
  Hovering h = Hovering::Make(control::ControllerType::kPaper);
  const dataset::FlightTask t = *sim::BuiltinFlightTask("t3_1");
  sim::FlightSimulation s = *sim::FlightSimulation::Create(t, 3);
  sim::RotorVector hover = sim::RotorVector::Constant(6, 650);
  for (auto _ : state) benchmark::DoNotOptimize(s.Step(hover).t_ns);
}
BENCHMARK(BM_SimulationStep)->Unit(benchmark::kMicrosecond);

void BM_WeightSchedule(benchmark::State& state) {
  control::WeightModel m;
  if (state.range(0) == 2) m.pose_sources.push_back({20, 0.01, 0.017});
  for (auto _ : state) benchmark::DoNotOptimize(control::ComputeWeightSchedule(m)->iterations);
  state.SetLabel(std::to_string(state.range(0)) + " pose source(s)");
}
BENCHMARK(BM_WeightSchedule)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// A whole 60 s t3_1 lock-stepped (simulation + autopilot + mission + record): wall time.
void BM_Hover60s(benchmark::State& state) {
  dataset::FlightTask t = *sim::BuiltinFlightTask("t3_1");
  t.duration_s = 60;
  eval::FlightMissionOptions o;
  o.controller = static_cast<control::ControllerType>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(eval::FlyTask(t, o)->samples.size());
  state.counters["realtime_factor"] =
      benchmark::Counter(60.0 * state.iterations(), benchmark::Counter::kIsRate);
  state.SetLabel(state.range(0) == 0 ? "paper" : "lee");
}
BENCHMARK(BM_Hover60s)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
