// mav-sim info: a summary of an EuRoC-format data set (ours or a real recording).

#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "commands.h"
#include "common.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/common/time.h"
#include "mav/dataset/euroc.h"
#include "mav/sim/occupancy.h"

namespace mav::sim_cli {
namespace {

constexpr const char* kCommand = "info";

double MeasuredRate(const std::vector<int64_t>& times) {
  if (times.size() < 2) return 0;
  return static_cast<double>(times.size() - 1) / NsToSeconds(times.back() - times.front());
}

// Decoding images catches a corrupt or truncated set early: the first and last stereo pair, or
// every pair with `all`. Returns the first failure.
Status DecodeImages(const dataset::EurocReader& r, bool all) {
  std::vector<int64_t> check = {0, r.num_frames() - 1};
  if (all) {
    check.clear();
    for (int64_t i = 0; i < r.num_frames(); ++i) check.push_back(i);
  }
  for (int64_t i : check) {
    cv::Mat left, right;
    if (Status s = r.ReadStereo(i, &left, &right); !s.ok()) return s;
  }
  return Status::Ok();
}

// Frames, timing, rates, calibration and IMU noise: what every EuRoC set has.
void PrintRecording(const dataset::EurocReader& r, bool verified) {
  const std::vector<int64_t>& t = r.frame_times();
  const camera::StereoCalibration& calib = r.calibration();
  std::printf("data set        %s\n", r.mav0().c_str());
  std::printf("frames          %lld stereo pairs (%lld unpaired skipped)%s\n",
              static_cast<long long>(r.num_frames()), static_cast<long long>(r.skipped_frames()),
              verified ? ", all images decoded" : "");
  std::printf("duration        %.3f s (%lld .. %lld ns)\n", NsToSeconds(t.back() - t.front()),
              static_cast<long long>(t.front()), static_cast<long long>(t.back()));
  std::vector<int64_t> imu_times;
  for (const dataset::ImuSample& s : r.imu()) imu_times.push_back(s.t_ns);
  std::printf("camera rate     %.2f Hz nominal, %.2f Hz measured\n", r.camera_rate_hz(),
              MeasuredRate(t));
  std::printf("imu             %zu samples, %.2f Hz nominal, %.2f Hz measured\n", r.imu().size(),
              r.imu_rate_hz(), MeasuredRate(imu_times));
  std::printf("cameras         %dx%d, cam0 fx %.3f fy %.3f cx %.3f cy %.3f, %s\n", calib.cam0.width,
              calib.cam0.height, calib.cam0.fx, calib.cam0.fy, calib.cam0.cx, calib.cam0.cy,
              calib.cam0.HasDistortion() || calib.cam1.HasDistortion() ? "radial-tangential"
                                                                       : "no distortion");
  const double angle_deg = geometry::LogSO3(calib.T_cam0_cam1().Rotation()).norm() * 180.0 / M_PI;
  std::printf("stereo          baseline %.4f m, cam0->cam1 rotation %.3f deg\n", calib.Baseline(),
              angle_deg);
  const dataset::ImuNoise& n = r.imu_noise();
  std::printf(
      "imu noise       gyro %.4g rad/s/sqrt(Hz) (walk %.4g), accel %.4g m/s^2/sqrt(Hz) "
      "(walk %.4g)\n",
      n.gyroscope_noise_density, n.gyroscope_random_walk, n.accelerometer_noise_density,
      n.accelerometer_random_walk);
}

void PrintGroundTruth(const dataset::EurocReader& r) {
  if (!r.has_ground_truth()) {
    std::printf("ground truth    none\n");
    return;
  }
  const std::vector<dataset::GroundTruthState>& gt = r.ground_truth();
  double length = 0;
  for (size_t i = 1; i < gt.size(); ++i) {
    length += (gt[i].T_world_body.Translation() - gt[i - 1].T_world_body.Translation()).norm();
  }
  const double span = NsToSeconds(gt.back().t_ns - gt.front().t_ns);
  std::printf("ground truth    %zu states over %.3f s, trajectory %.2f m, mean speed %.3f m/s\n",
              gt.size(), span, length, span > 0 ? length / span : 0.0);
}

void PrintOccupancy(const dataset::OccupancyGrid& grid) {
  const Eigen::Vector3i& size = grid.size();
  const double total = static_cast<double>(grid.num_voxels());
  const auto pct = [&](dataset::VoxelState s) {
    return 100.0 * static_cast<double>(grid.Count(s)) / total;
  };
  std::printf(
      "occupancy       %dx%dx%d voxels at %.3g m (%.1f x %.1f x %.1f m from (%.2f, %.2f, "
      "%.2f)): %.2f %% occupied, %.2f %% free, %.2f %% unknown\n",
      size.x(), size.y(), size.z(), grid.resolution(), size.x() * grid.resolution(),
      size.y() * grid.resolution(), size.z() * grid.resolution(), grid.origin().x(),
      grid.origin().y(), grid.origin().z(), pct(dataset::VoxelState::kOccupied),
      pct(dataset::VoxelState::kFree), pct(dataset::VoxelState::kUnknown));
}

// The lines of DIR/ground_truth/scenario.yaml (written by mav-sim generate) that say how the set
// was made; nothing for sets without one.
void PrintScenario(const std::string& dir) {
  const std::string scenario_path = dir + "/ground_truth/scenario.yaml";
  auto text = ReadFileToString(scenario_path);
  if (!text.ok()) return;
  std::istringstream lines(*text);
  std::string line;
  std::string summary;
  while (std::getline(lines, line)) {
    for (const char* key :
         {"generator:", "preset:", "seed:", "rectified:", "exact_cylinder_angles: true"}) {
      if (line.rfind(key, 0) == 0) summary += (summary.empty() ? "" : ", ") + line;
    }
  }
  std::printf("scenario        %s\n", summary.c_str());
}

}  // namespace

int RunInfo(const std::vector<std::string>& args) {
  bool verify = false;
  FlagParser parser(
      "mav-sim info DIR [--verify]\n\n"
      "Summarises an EuRoC ASL data set: frames, duration, rates, calibration, IMU noise, ground\n"
      "truth and, for generated sets, the ground-truth occupancy grid. Reads the first and last\n"
      "stereo pair (all of them with --verify).");
  parser.AddBool("verify", &verify, "decode every image");
  std::string dir;
  if (std::optional<int> done = ParseDataSetCommand(kCommand, &parser, args, &dir)) return *done;
  auto reader = dataset::EurocReader::Open(dir);
  if (!reader.ok()) {
    PrintError(kCommand, reader.status().ToString());
    return kExitFailure;
  }
  const dataset::EurocReader& r = *reader;
  if (Status s = r.CheckHasFrames(); !s.ok()) {
    PrintError(kCommand, s.ToString());
    return kExitFailure;
  }
  if (Status s = DecodeImages(r, verify); !s.ok()) {
    PrintError(kCommand, s.ToString());
    return kExitFailure;
  }

  PrintRecording(r, verify);
  PrintGroundTruth(r);
  auto grid = ReadGroundTruthOccupancy(dir);
  if (!grid.ok()) {
    PrintError(kCommand, grid.status().ToString());
    return kExitFailure;
  }
  if (grid->has_value()) PrintOccupancy(**grid);
  PrintScenario(dir);
  return kExitOk;
}

}  // namespace mav::sim_cli
