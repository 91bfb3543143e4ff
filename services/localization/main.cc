// mav-localization: the Localization gRPC service (control plane) running stereo visual odometry
// on mav/sensors/stereo and publishing mav/localization/pose on Cyclone DDS (data plane).
// docs/services.md lists flags and environment.

#include "mav/common/log.h"
#include "mav/common/text.h"
#include "mav/localization/odometry.h"
#include "mav/transport/service_main.h"
#include "services/common/calibration_source.h"
#include "services/localization/convert.h"
#include "services/localization/dds_io.h"
#include "services/localization/localization_service.h"
#include "services/localization/localizer.h"

int main(int argc, char** argv) {
  mav::transport::ServiceRunner runner(
      {"mav-localization",
       "Serves mav.v1.Localization over gRPC: stereo visual odometry on mav/sensors/stereo,\n"
       "poses on mav/localization/pose (Cyclone DDS).",
       50052, "MAV_LOCALIZATION_PORT"});
  std::string method;
  mav::service_common::CalibrationFlags calibration;
  runner.flags().AddString("method", &method,
                           "optional: configure at start-up with this method "
                           "(sparse-pixel|sparse-subpixel|dense); needs --euroc or --simulator");
  calibration.Register(&runner.flags(), "--method");
  runner.ParseFlagsOrExit(argc, argv);
  // Its large blocks are the stereo samples, their images and the VO's per-frame buffers, all
  // recycled at frame rate: kept in the heap instead of mapped afresh for each frame.
  mav::transport::KeepLargeSampleBuffers();

  mav::v1::LocalizationConfigureRequest startup;
  if (!method.empty()) {
    const auto parsed = mav::localization::ParseMethod(method);
    if (!parsed.has_value()) {
      return runner.Usage("--method: unknown method " + mav::QuoteForError(method) +
                          " (sparse-pixel|sparse-subpixel|dense)");
    }
    startup.set_method(mav::localization_service::ToProto(*parsed));
  }
  auto source = calibration.Source(!method.empty(), "--method");
  if (!source.ok()) return runner.Usage(source.status().message());
  if (source->has_value()) *startup.mutable_calibration() = **source;

  // The DdsIo publishes the localizer's poses and feeds it live frames: it is created first and
  // destroyed last; the input is switched off before the localizer goes away.
  auto dds = mav::localization_service::DdsIo::Create(runner.dds_options());
  if (!dds.ok()) return runner.Fail(dds.status());
  mav::localization_service::Localizer localizer(dds->get());
  (*dds)->Attach(&localizer);
  mav::localization_service::LocalizationService service(&localizer, dds->get());

  if (!method.empty()) {
    mav::v1::LocalizationStatus status;
    const grpc::Status configured = service.ApplyConfigure(startup, {}, &status);
    if (!configured.ok()) {
      return runner.Fail(mav::Status::InvalidArgument("--method: " + configured.error_message()));
    }
  }
  return runner.Serve({&service}, {mav::v1::Localization::service_full_name()}, [&] {
    (void)(*dds)->SetInput(false);
    localizer.Shutdown();
    MAV_LOG(kInfo) << "received " << (*dds)->frames_received() << " stereo frames and "
                   << (*dds)->imu_samples_received() << " IMU samples, published "
                   << (*dds)->poses_published() << " poses";
  });
}
