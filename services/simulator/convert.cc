#include "services/simulator/convert.h"

#include <cmath>
#include <sstream>

namespace mav::simulator_service {

using service_common::Number;

Result<LoadRequest> FromProto(const v1::LoadScenarioRequest& request) {
  LoadRequest out;
  switch (request.source_case()) {
    case v1::LoadScenarioRequest::kPreset:
      out.is_preset = true;
      out.preset.name = request.preset().name();
      out.preset.frames = request.preset().frames();
      out.preset.seed = request.preset().seed();
      out.preset.rectified = request.preset().rectified();
      return out;
    case v1::LoadScenarioRequest::kEuroc:
      out.is_preset = false;
      out.euroc_directory = request.euroc().directory();
      return out;
    case v1::LoadScenarioRequest::SOURCE_NOT_SET:
      break;
  }
  return Status::InvalidArgument("source: set either preset or euroc");
}

Result<Pacing> FromProto(const v1::SimulatorStartRequest& request) {
  Pacing pacing;
  switch (request.pacing_case()) {
    case v1::SimulatorStartRequest::kRealTimeFactor: {
      const double factor = request.real_time_factor();
      if (!std::isfinite(factor) || factor <= 0.0) {
        return Status::InvalidArgument("real_time_factor: must be > 0 and finite, got " +
                                       Number(factor));
      }
      pacing.real_time_factor = factor;
      pacing.as_fast_as_subscribers = false;
      break;
    }
    case v1::SimulatorStartRequest::kAsFastAsSubscribers:
      if (!request.as_fast_as_subscribers()) {
        return Status::InvalidArgument(
            "as_fast_as_subscribers: false is not a pacing; set real_time_factor instead");
      }
      pacing.real_time_factor = 0.0;
      pacing.as_fast_as_subscribers = true;
      break;
    case v1::SimulatorStartRequest::PACING_NOT_SET:
      return Status::InvalidArgument(
          "real_time_factor: no pacing given; set real_time_factor > 0 or "
          "as_fast_as_subscribers");
  }
  const double timeout = request.wait_timeout_s();
  if (!std::isfinite(timeout) || timeout < 0.0) {
    return Status::InvalidArgument("wait_timeout_s: must be >= 0 and finite, got " +
                                   Number(timeout));
  }
  pacing.wait_timeout_s = timeout == 0.0 ? 5.0 : timeout;
  pacing.wait_for_subscribers = request.wait_for_subscribers();
  pacing.loop = request.loop();
  return pacing;
}

void ToProto(const ScenarioInfo& info, v1::ScenarioSummary* out) {
  out->set_name(info.name);
  out->set_is_preset(info.is_preset);
  out->set_frames(info.frames);
  out->set_imu_samples(info.imu_samples);
  out->set_start_t_ns(info.start_t_ns);
  out->set_end_t_ns(info.end_t_ns);
  out->set_camera_rate_hz(info.camera_rate_hz);
  out->set_imu_rate_hz(info.imu_rate_hz);
  out->set_rectified(info.rectified);
  out->set_seed(info.seed);
  out->set_has_ground_truth(info.has_ground_truth);
  out->set_has_ground_truth_occupancy(info.has_ground_truth_occupancy);
  out->set_image_width(static_cast<uint32_t>(info.width));
  out->set_image_height(static_cast<uint32_t>(info.height));
}

v1::SimulatorState ToProto(PlayerState state) {
  switch (state) {
    case PlayerState::kIdle:
      return v1::SIMULATOR_STATE_IDLE;
    case PlayerState::kLoaded:
      return v1::SIMULATOR_STATE_LOADED;
    case PlayerState::kRunning:
      return v1::SIMULATOR_STATE_RUNNING;
    case PlayerState::kPaused:
      return v1::SIMULATOR_STATE_PAUSED;
    case PlayerState::kFinished:
      return v1::SIMULATOR_STATE_FINISHED;
  }
  return v1::SIMULATOR_STATE_UNSPECIFIED;
}

void ToProto(const PlayerStatus& status, v1::SimulatorStatus* out) {
  out->set_state(ToProto(status.state));
  if (status.scenario.has_value()) ToProto(*status.scenario, out->mutable_scenario());
  out->set_next_frame(status.next_frame);
  out->set_frames_published(status.frames_published);
  out->set_imu_samples_published(status.imu_samples_published);
  out->set_ground_truth_published(status.ground_truth_published);
  out->set_current_t_ns(status.current_t_ns);
  out->set_achieved_rate_hz(status.achieved_rate_hz);
  out->set_real_time_factor(status.pacing.as_fast_as_subscribers ? 0.0
                                                                 : status.pacing.real_time_factor);
  out->set_as_fast_as_subscribers(status.pacing.as_fast_as_subscribers);
  out->set_loop(status.pacing.loop);
  out->set_stereo_subscribers(status.stereo_subscribers);
  out->set_imu_subscribers(status.imu_subscribers);
  ToProto(status.render_ms, out->mutable_render_ms());
  ToProto(status.publish_ms, out->mutable_publish_ms());
  out->set_dds_domain(status.dds_domain);
  out->set_last_error(status.last_error);
}

void ToProto(const camera::StereoCalibration& calibration, double rate_hz, bool rectified,
             v1::StereoCalibration* out) {
  v1::CameraCalibration* left = out->mutable_left();
  left->set_camera_id("cam0");
  ToProto(calibration.cam0, left->mutable_intrinsics());
  ToProto(calibration.T_body_cam0, left->mutable_t_body_cam());
  left->set_rate_hz(rate_hz);
  v1::CameraCalibration* right = out->mutable_right();
  right->set_camera_id("cam1");
  ToProto(calibration.cam1, right->mutable_intrinsics());
  ToProto(calibration.T_body_cam1, right->mutable_t_body_cam());
  right->set_rate_hz(rate_hz);
  out->set_rectified(rectified);
  out->set_baseline_m(calibration.Baseline());
}

void ToProto(const dataset::ImuNoise& noise, double rate_hz, v1::ImuNoise* out) {
  out->set_gyroscope_noise_density(noise.gyroscope_noise_density);
  out->set_gyroscope_random_walk(noise.gyroscope_random_walk);
  out->set_accelerometer_noise_density(noise.accelerometer_noise_density);
  out->set_accelerometer_random_walk(noise.accelerometer_random_walk);
  out->set_rate_hz(rate_hz);
}

}  // namespace mav::simulator_service
