// mav-control: the Control gRPC service (control plane) running the delayed-pose estimator and
// the paper's (or Lee's) controller on mav/sensors/imu and mav/localization/pose, publishing the
// rotor speeds on mav/control/actuators (Cyclone DDS, data plane). docs/services.md lists flags.

#include "mav/common/log.h"
#include "mav/common/text.h"
#include "mav/sim/flight_task.h"
#include "mav/transport/service_main.h"
#include "services/control/control_core.h"
#include "services/control/control_service.h"
#include "services/control/convert.h"
#include "services/control/dds_io.h"

int main(int argc, char** argv) {
  mav::transport::ServiceRunner runner(
      {"mav-control",
       "Serves mav.v1.Control over gRPC: state estimation and trajectory tracking on\n"
       "mav/sensors/imu and mav/localization/pose, rotor speeds on mav/control/actuators\n"
       "(Cyclone DDS).",
       50055, "MAV_CONTROL_PORT"});
  std::string task;
  std::string controller = "paper";
  bool lockstep = false;
  bool takeover = false;
  std::string plant_map = mav::sim::DefaultPlantMapPath();
  mav::control_service::ControlServiceOptions options;
  runner.flags().AddString("task", &task,
                           "optional: configure at start-up for this flight task (t3_1 ... t4_3 "
                           "or a task file .yaml): what the contest told the teams");
  runner.flags().AddString("controller", &controller, "--task: paper|lee");
  runner.flags().AddBool("lockstep", &lockstep,
                         "--task: the IMU comes from a lock-stepped simulator (no wall-clock "
                         "IMU watchdog)");
  runner.flags().AddBool("takeover", &takeover,
                         "--task: take over a vehicle already in the air (a controller restarted "
                         "mid-flight): arm in the air once 0.5 s of poses are merged and hold "
                         "where it is; on the ground stay disarmed");
  runner.flags().AddString("plant-map", &plant_map, "--task t4_3: the power plant's OctoMap");
  runner.flags().AddInt("planning-timeout-ms", &options.planning_timeout_ms,
                        "longest wait for Planning.GetPlan in SetTrajectory");
  runner.ParseFlagsOrExit(argc, argv);
  if (controller != "paper" && controller != "lee") {
    return runner.Usage("--controller: " + mav::QuoteForError(controller) + " is not paper or lee");
  }
  if (task.empty() && (lockstep || takeover || runner.flags().WasSet("controller"))) {
    return runner.Usage("--controller/--lockstep/--takeover need --task");
  }
  if (std::string why; !options.IsValid(&why)) return runner.Usage(why);

  // The DdsIo publishes the core's commands and feeds it the samples: created first, destroyed
  // last; the input is switched off before the core goes away.
  auto dds = mav::control_service::DdsIo::Create(runner.dds_options());
  if (!dds.ok()) return runner.Fail(dds.status());
  mav::control_service::ControlCore core(dds->get());
  (*dds)->Attach(&core);
  mav::control_service::ControlService service(&core, dds->get(), options);

  if (!task.empty()) {
    auto spec = mav::sim::FlightTaskFromSpec(task, plant_map);
    if (!spec.ok()) return runner.Fail(spec.status().WithContext("--task"));
    mav::v1::ControlConfigureRequest request;
    mav::control_service::ToProto(mav::control_service::ConfigForFlightTask(
                                      *spec,
                                      controller == "lee" ? mav::control::ControllerType::kLee
                                                          : mav::control::ControllerType::kPaper,
                                      lockstep),
                                  &request);
    mav::v1::ControlStatus status;
    const grpc::Status configured = service.ApplyConfigure(request, {}, &status);
    if (!configured.ok()) {
      return runner.Fail(mav::Status::InvalidArgument("--task: " + configured.error_message()));
    }
    if (takeover) {
      if (mav::Status s = core.SetTakeover(true); !s.ok()) return runner.Fail(s);
      MAV_LOG(kInfo) << "--takeover: arming in the air once the estimate has settled";
    }
  }
  return runner.Serve({&service}, {mav::v1::Control::service_full_name()}, [&] {
    (void)(*dds)->SetInput(false);
    MAV_LOG(kInfo) << "received " << (*dds)->imu_received() << " IMU samples and "
                   << (*dds)->poses_received() << " poses, published "
                   << core.GetStatus().commands_published << " commands";
  });
}
