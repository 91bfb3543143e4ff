// mav-sim generate: renders a scenario into an EuRoC ASL directory plus ground truth.
//
// Frames are rendered by a pool of threads that take frame indices from an atomic counter; since
// Scenario::RenderStereo is a pure function of (preset, seed, frame) and EurocWriter sorts the
// frame list on Close(), the output does not depend on the number of threads or on scheduling.

#include <charconv>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>

#include "commands.h"
#include "common.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/common/progress.h"
#include "mav/common/time.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/scenario.h"
#include "mav/sim/scenario_source.h"
#include "mav/sim/world.h"

namespace mav::sim_cli {
namespace {

constexpr const char* kCommand = "generate";
// Grids above this many voxels are refused (one byte per voxel plus OctoMap's tree).
constexpr double kMaxVoxels = 4e8;
// Used for large worlds (the plant) when --occupancy-resolution is not given.
constexpr double kCoarseResolution = 0.2;

struct GenerateFlags {
  std::string preset;
  std::string out;
  int64_t frames = 0;
  uint64_t seed = 1;
  bool rectified = false;
  bool exact_cylinder_angles = false;
  bool force = false;
  double occupancy_resolution = 0.05;
  int64_t threads = std::max(1u, std::thread::hardware_concurrency());
};

std::string Join(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

Status CheckOutputDirectory(const std::string& out, bool force) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(out, ec)) return Status::Ok();
  if (!fs::is_directory(out, ec)) {
    return Status::InvalidArgument("--out: '" + out + "' exists and is not a directory");
  }
  if (fs::directory_iterator(out, ec) == fs::directory_iterator()) return Status::Ok();
  if (!force) {
    return Status::InvalidArgument("--out: directory '" + out +
                                   "' is not empty (use --force to replace its data set)");
  }
  // Only what we write ourselves is removed; other files in the directory stay.
  for (const char* sub : {"/mav0", "/ground_truth"}) {
    fs::remove_all(out + sub, ec);
    if (ec) return Status::IoError(out + sub + ": cannot remove: " + ec.message());
  }
  return Status::Ok();
}

// The shortest text that reads back as the same double ("0.05", not "0.050000000000000003").
std::string Shortest(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

std::string ScenarioYaml(const GenerateFlags& flags, const sim::Scenario& scenario,
                         double occupancy_resolution) {
  char buffer[2048];
  const camera::StereoCalibration& calib = scenario.calibration();
  std::snprintf(buffer, sizeof(buffer),
                "# Written by mav-sim generate; describes how this data set was made.\n"
                "generator: mav-sim %s\n"
                "preset: %s\n"
                "seed: %llu\n"
                "frames: %lld\n"
                "rectified: %s\n"
                "exact_cylinder_angles: %s\n"
                "camera_rate_hz: %.17g\n"
                "imu_rate_hz: %.17g\n"
                "first_frame_t_ns: %lld\n"
                "baseline_m: %.17g\n"
                "occupancy_resolution_m: %s\n"
                "occupancy_files: [occupancy.bt, occupancy.mavocc]\n",
                MAV_VERSION, flags.preset.c_str(), static_cast<unsigned long long>(flags.seed),
                static_cast<long long>(scenario.num_frames()), flags.rectified ? "true" : "false",
                flags.exact_cylinder_angles ? "true" : "false", scenario.camera_rate_hz(),
                scenario.imu_rate_hz(), static_cast<long long>(scenario.FrameTimeNs(0)),
                calib.Baseline(), Shortest(occupancy_resolution).c_str());
  return buffer;
}

// Renders and writes every frame on `threads` threads of a sim::FramePrefetcher (the simulator
// service's render-ahead pool); the PNGs are written on the rendering threads too. Returns the
// first error.
Status RenderFrames(const sim::Scenario& scenario, dataset::EurocWriter* writer, int threads) {
  const int64_t n = scenario.num_frames();
  sim::FramePrefetcher::Frames frames{n, [&scenario](int64_t k) { return scenario.FrameTimeNs(k); },
                                      [&scenario](int64_t k, cv::Mat* left, cv::Mat* right) {
                                        scenario.RenderStereo(k, left, right);
                                        return Status::Ok();
                                      }};
  sim::FramePrefetcher prefetcher(std::move(frames), threads, /*depth=*/2 * threads,
                                  [writer](const sim::RenderedFrame& f) {
                                    return writer->WriteStereo(f.t_ns, f.left, f.right);
                                  });
  ProgressBar progress("rendering", n);
  for (int64_t k = 0; k < n; ++k) {
    Result<sim::RenderedFrame> frame = prefetcher.Get(k);
    if (!frame.ok()) return frame.status().WithContext("frame " + std::to_string(k));
    progress.Update(k + 1);
  }
  progress.Finish();
  return Status::Ok();
}

// The ground-truth voxel size: --occupancy-resolution, unless the grid would be too large for
// memory; then a coarser default when the flag was not given, an error when it was.
Result<double> OccupancyResolution(const sim::Scenario& scenario, double resolution,
                                   bool resolution_given) {
  const Eigen::Vector3d extent = scenario.world().bounds().sizes();
  const auto voxels = [&](double r) {
    return std::ceil(extent.x() / r + 1) * std::ceil(extent.y() / r + 1) *
           std::ceil(extent.z() / r + 1);
  };
  if (voxels(resolution) > kMaxVoxels) {
    if (resolution_given) {
      return Status::InvalidArgument("--occupancy-resolution: " + std::to_string(resolution) +
                                     " m gives " +
                                     std::to_string(static_cast<int64_t>(voxels(resolution))) +
                                     " voxels for this world; " + "choose a coarser resolution");
    }
    return kCoarseResolution;
  }
  return resolution;
}

int Fail(const Status& status) {
  PrintError(kCommand, status.ToString());
  return status.code() == StatusCode::kInvalidArgument ? kExitUsage : kExitFailure;
}

}  // namespace

int RunGenerate(const std::vector<std::string>& args) {
  GenerateFlags flags;
  FlagParser parser(
      "mav-sim generate --preset P --out DIR [flags]\n\n"
      "Renders a simulated stereo + IMU data set in the EuRoC ASL layout\n"
      "(DIR/mav0/...) with exact ground truth (DIR/ground_truth/: occupancy.bt,\n"
      "occupancy.mavocc, scenario.yaml).\n"
      "presets: " +
      Join(sim::PresetNames()));
  parser.AddString("preset", &flags.preset, "scenario preset (required)");
  parser.AddString("out", &flags.out, "output directory (required)");
  parser.AddInt64("frames", &flags.frames, "number of stereo frames; 0 = the preset's full length",
                  0, std::numeric_limits<int64_t>::max());
  parser.AddUint64("seed", &flags.seed, "random seed (same seed, same data set)");
  parser.AddBool("rectified", &flags.rectified,
                 "ideal rectified pinhole pair instead of EuRoC's raw distorted calibration");
  parser.AddBool("exact-cylinder-angles", &flags.exact_cylinder_angles,
                 "cylinders' texture angle with std::atan2 per pixel: the images of builds before "
                 "the renderer's own atan2, bit for bit (slower; at most 1 DN apart)");
  parser.AddDouble("occupancy-resolution", &flags.occupancy_resolution,
                   "ground-truth voxel size in metres (large worlds default to 0.2)", 0.005);
  parser.AddInt64("threads", &flags.threads,
                  "render threads (default here: this machine's hardware concurrency)", 1, 256);
  parser.AddBool("force", &flags.force, "replace the data set in a non-empty --out directory");

  std::vector<std::string> positional;
  if (std::optional<int> done = ParseCommandFlags(kCommand, &parser, args, &positional)) {
    return *done;
  }
  if (!positional.empty()) {
    return Fail(Status::InvalidArgument("unexpected argument '" + positional[0] + "'"));
  }
  if (flags.preset.empty()) return Fail(Status::InvalidArgument("--preset: required"));
  if (flags.out.empty()) return Fail(Status::InvalidArgument("--out: required"));

  sim::ScenarioOptions options;
  options.preset = flags.preset;
  options.frames = flags.frames;
  options.seed = flags.seed;
  options.rectified = flags.rectified;
  options.exact_cylinder_angles = flags.exact_cylinder_angles;
  std::string why;
  if (!options.IsValid(&why)) return Fail(Status::InvalidArgument(why));
  auto scenario = sim::Scenario::Create(options);
  if (!scenario.ok()) return Fail(scenario.status());

  // Size the ground-truth grid before anything is written.
  const Result<double> chosen = OccupancyResolution(*scenario, flags.occupancy_resolution,
                                                    parser.WasSet("occupancy-resolution"));
  if (!chosen.ok()) return Fail(chosen.status());
  const double resolution = *chosen;

  if (Status s = CheckOutputDirectory(flags.out, flags.force); !s.ok()) return Fail(s);
  const std::string gt_dir = flags.out + "/ground_truth";
  if (Status s = MakeDirectories(gt_dir); !s.ok()) return Fail(s);

  const int64_t start_ns = MonotonicNowNs();
  auto writer =
      dataset::EurocWriter::Create(flags.out, scenario->calibration(), scenario->imu_noise(),
                                   scenario->camera_rate_hz(), scenario->imu_rate_hz());
  if (!writer.ok()) return Fail(writer.status());
  std::fprintf(stderr,
               "mav-sim generate: preset %s, seed %llu, %lld frames, %s, %lld threads -> %s\n",
               flags.preset.c_str(), static_cast<unsigned long long>(flags.seed),
               static_cast<long long>(scenario->num_frames()),
               flags.rectified ? "rectified" : "raw EuRoC calibration",
               static_cast<long long>(flags.threads), flags.out.c_str());
  if (Status s = RenderFrames(*scenario, writer->get(), static_cast<int>(flags.threads)); !s.ok()) {
    return Fail(s);
  }
  const int64_t render_ns = MonotonicNowNs() - start_ns;
  if (Status s = (*writer)->WriteImu(scenario->ImuSamples()); !s.ok()) return Fail(s);
  if (Status s = (*writer)->WriteGroundTruth(scenario->GroundTruth()); !s.ok()) return Fail(s);
  if (Status s = (*writer)->Close(); !s.ok()) return Fail(s);

  const int64_t occupancy_start_ns = MonotonicNowNs();
  const dataset::OccupancyGrid grid = scenario->ComputeOccupancy(resolution);
  if (Status s = dataset::WriteOctomapBt(grid, gt_dir + "/occupancy.bt"); !s.ok()) return Fail(s);
  if (Status s = dataset::WriteMavocc(grid, gt_dir + "/occupancy.mavocc"); !s.ok()) return Fail(s);
  const int64_t occupancy_ns = MonotonicNowNs() - occupancy_start_ns;
  if (Status s = WriteStringToFileAtomic(gt_dir + "/scenario.yaml",
                                         ScenarioYaml(flags, *scenario, resolution));
      !s.ok()) {
    return Fail(s);
  }

  const double render_s = NsToSeconds(render_ns);
  std::printf(
      "wrote %s: %lld stereo frames in %.1f s (%.1f ms/frame), ground-truth occupancy "
      "%dx%dx%d at %.3g m in %.1f s\n",
      flags.out.c_str(), static_cast<long long>(scenario->num_frames()), render_s,
      1e3 * render_s / static_cast<double>(std::max<int64_t>(1, scenario->num_frames())),
      grid.size().x(), grid.size().y(), grid.size().z(), resolution, NsToSeconds(occupancy_ns));
  return kExitOk;
}

}  // namespace mav::sim_cli
