// mav-sim preview: one picture of a data set frame - the left and right images side by side over a
// top view of the ground-truth occupancy sliced at the camera's height (occupied dark, free light,
// unknown grey), with the trajectory and the camera's position and viewing direction.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "commands.h"
#include "common.h"
#include "mav/common/flags.h"
#include "mav/common/time.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/png.h"
#include "mav/dataset/stereo_pair.h"
#include "mav/sim/occupancy.h"

namespace mav::sim_cli {
namespace {

constexpr const char* kCommand = "preview";
constexpr int kMaxSliceHeight = 720;

// Ground-truth body pose at t_ns, interpolated between the two neighbouring states.
geometry::SE3 BodyPoseAt(const std::vector<dataset::GroundTruthState>& gt, int64_t t_ns) {
  const auto it =
      std::lower_bound(gt.begin(), gt.end(), t_ns,
                       [](const dataset::GroundTruthState& s, int64_t t) { return s.t_ns < t; });
  if (it == gt.begin()) return gt.front().T_world_body;
  if (it == gt.end()) return gt.back().T_world_body;
  const dataset::GroundTruthState& b = *it;
  const dataset::GroundTruthState& a = *(it - 1);
  const double alpha = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  return geometry::InterpolatePose(a.T_world_body, b.T_world_body, alpha);
}

// Maps world (x, y) to slice pixels: x to the right, y up.
struct TopView {
  double x0 = 0, y1 = 0, scale = 1;  // pixels per metre
  cv::Point2d ToPixel(const Eigen::Vector3d& p) const {
    return {(p.x() - x0) * scale, (y1 - p.y()) * scale};
  }
  Eigen::Vector2d ToWorld(int u, int v) const {
    return {x0 + (u + 0.5) / scale, y1 - (v + 0.5) / scale};
  }
};

struct PreviewFlags {
  std::string dir;
  int64_t frame = 0;
  std::string out;
  std::optional<double> slice_z;  // the camera's height when not given
};

// Parses the command line into *flags; returns the exit code when the command is finished.
std::optional<int> ParsePreviewFlags(const std::vector<std::string>& args, PreviewFlags* flags) {
  double slice_z = 0.0;
  FlagParser parser(
      "mav-sim preview DIR --frame K --out x.png [--slice-z Z]\n\n"
      "Draws frame K's left and right images side by side above a top view of the ground-truth\n"
      "occupancy (DIR/ground_truth/occupancy.mavocc) sliced at the camera height: occupied dark,\n"
      "free light, unknown grey; the trajectory in blue, the camera in red.");
  parser.AddInt64("frame", &flags->frame, "frame index", 0, std::numeric_limits<int64_t>::max());
  parser.AddString("out", &flags->out, "output PNG (required)");
  parser.AddDouble("slice-z", &slice_z,
                   "height of the occupancy slice in metres (default: the camera's)");
  if (std::optional<int> done = ParseDataSetCommand(kCommand, &parser, args, &flags->dir)) {
    return done;
  }
  if (flags->out.empty()) {
    PrintError(kCommand, "--out: required");
    return kExitUsage;
  }
  if (parser.WasSet("slice-z")) flags->slice_z = slice_z;
  return std::nullopt;
}

// The box the top view shows: the occupancy grid and the trajectory, or 2 x 2 x 1 m around the
// origin when there is neither.
Eigen::AlignedBox3d SceneExtent(const std::optional<dataset::OccupancyGrid>& grid,
                                const std::vector<dataset::GroundTruthState>& gt) {
  Eigen::AlignedBox3d extent;
  if (grid) {
    extent.extend(grid->origin());
    extent.extend(grid->origin() + grid->size().cast<double>() * grid->resolution());
  }
  for (const dataset::GroundTruthState& s : gt) extent.extend(s.T_world_body.Translation());
  if (extent.isEmpty()) {
    extent = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, 0), Eigen::Vector3d(1, 1, 1));
  }
  return extent;
}

// Fits `extent` into a slice `width` pixels wide and at most kMaxSliceHeight high, centred
// horizontally; *height is the slice's height in pixels.
TopView FitTopView(const Eigen::AlignedBox3d& extent, int width, int* height) {
  const Eigen::Vector3d size = extent.sizes().cwiseMax(1e-3);
  TopView view;
  view.scale = std::min(width / size.x(), kMaxSliceHeight / size.y());
  view.x0 = extent.min().x() - (width / view.scale - size.x()) / 2;  // centre horizontally
  view.y1 = extent.max().y();
  *height = std::max(1, static_cast<int>(std::lround(size.y() * view.scale)));
  return view;
}

void DrawOccupancy(const dataset::OccupancyGrid& grid, const TopView& view, double slice_z,
                   cv::Mat* slice) {
  for (int v = 0; v < slice->rows; ++v) {
    for (int u = 0; u < slice->cols; ++u) {
      const Eigen::Vector2d xy = view.ToWorld(u, v);
      const dataset::VoxelState s = grid.StateAt(Eigen::Vector3d(xy.x(), xy.y(), slice_z));
      const uint8_t grey =
          s == dataset::VoxelState::kOccupied ? 40 : (s == dataset::VoxelState::kFree ? 235 : 128);
      slice->at<cv::Vec3b>(v, u) = cv::Vec3b(grey, grey, grey);
    }
  }
}

// The trajectory (every fifth state) and the camera with its viewing direction.
void DrawTrajectory(const std::vector<dataset::GroundTruthState>& gt,
                    const geometry::SE3& T_world_cam0, const TopView& view, cv::Mat* slice) {
  std::vector<cv::Point> path;
  for (size_t i = 0; i < gt.size(); i += 5) {
    const cv::Point2d p = view.ToPixel(gt[i].T_world_body.Translation());
    path.emplace_back(static_cast<int>(std::lround(p.x)), static_cast<int>(std::lround(p.y)));
  }
  cv::polylines(*slice, path, false, cv::Scalar(200, 90, 20), 2, cv::LINE_AA);
  const cv::Point2d c = view.ToPixel(T_world_cam0.Translation());
  // The optical axis (camera z) projected onto the ground plane, 0.6 m long.
  Eigen::Vector3d axis = T_world_cam0.Rotation() * Eigen::Vector3d::UnitZ();
  axis.z() = 0;
  if (axis.norm() > 1e-6) {
    const cv::Point2d tip = view.ToPixel(T_world_cam0.Translation() + 0.6 * axis.normalized());
    cv::arrowedLine(*slice, c, tip, cv::Scalar(0, 0, 230), 3, cv::LINE_AA, 0, 0.3);
  }
  cv::circle(*slice, c, 8, cv::Scalar(0, 0, 230), cv::FILLED, cv::LINE_AA);
}

// White text with a black outline, readable on both free and occupied voxels.
void DrawCaption(const std::string& caption, cv::Mat* slice) {
  cv::putText(*slice, caption, cv::Point(12, 30), cv::FONT_HERSHEY_SIMPLEX, 0.8,
              cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(*slice, caption, cv::Point(12, 30), cv::FONT_HERSHEY_SIMPLEX, 0.8,
              cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
}

// The top view of frame `frame` of the set, `width` pixels wide (the stereo pair's width).
cv::Mat DrawSlice(const dataset::EurocReader& reader, int64_t frame,
                  const std::optional<dataset::OccupancyGrid>& grid,
                  std::optional<double> slice_z_flag, int width) {
  const std::vector<dataset::GroundTruthState>& gt = reader.ground_truth();
  const Eigen::AlignedBox3d extent = SceneExtent(grid, gt);
  int height = 0;
  const TopView view = FitTopView(extent, width, &height);

  const int64_t t_ns = reader.frame_times()[frame];
  geometry::SE3 T_world_cam0;
  if (!gt.empty()) {
    T_world_cam0 = BodyPoseAt(gt, t_ns) * reader.calibration().T_body_cam0;
  } else {
    T_world_cam0 = geometry::SE3(Eigen::Quaterniond::Identity(), extent.center());
  }
  const double slice_z = slice_z_flag ? *slice_z_flag : T_world_cam0.Translation().z();

  cv::Mat slice(height, width, CV_8UC3, cv::Scalar(128, 128, 128));
  if (grid) DrawOccupancy(*grid, view, slice_z, &slice);
  if (!gt.empty()) DrawTrajectory(gt, T_world_cam0, view, &slice);
  char caption[256];
  std::snprintf(caption, sizeof(caption), "frame %lld  t = %.2f s  slice z = %.2f m%s",
                static_cast<long long>(frame), NsToSeconds(t_ns - reader.frame_times().front()),
                slice_z, grid ? "" : "  (no ground-truth occupancy)");
  DrawCaption(caption, &slice);
  return slice;
}

int WritePicture(const std::string& out, const cv::Mat& picture) {
  const Status written = dataset::WritePngFile(out, picture);
  if (!written.ok()) {
    PrintError(kCommand, "--out: cannot write '" + out + "': " + written.message());
    return kExitFailure;
  }
  std::printf("wrote %s (%dx%d)\n", out.c_str(), picture.cols, picture.rows);
  return kExitOk;
}

}  // namespace

int RunPreview(const std::vector<std::string>& args) {
  PreviewFlags flags;
  if (std::optional<int> done = ParsePreviewFlags(args, &flags)) return *done;
  auto reader = dataset::EurocReader::Open(flags.dir);
  if (!reader.ok()) {
    PrintError(kCommand, reader.status().ToString());
    return kExitFailure;
  }
  if (flags.frame < 0 || flags.frame >= reader->num_frames()) {
    PrintError(kCommand, "--frame: " + std::to_string(flags.frame) + " is outside [0, " +
                             std::to_string(reader->num_frames()) + ")");
    return kExitUsage;
  }
  auto pair = reader->ReadStereo(flags.frame);
  if (!pair.ok()) {
    PrintError(kCommand, pair.status().ToString());
    return kExitFailure;
  }

  // Top row: the stereo pair; below it the slice.
  cv::Mat stereo;
  cv::hconcat(pair->left, pair->right, stereo);
  cv::cvtColor(stereo, stereo, cv::COLOR_GRAY2BGR);
  auto grid = ReadGroundTruthOccupancy(flags.dir);
  if (!grid.ok()) {
    PrintError(kCommand, grid.status().ToString());
    return kExitFailure;
  }
  const cv::Mat slice = DrawSlice(*reader, flags.frame, *grid, flags.slice_z, stereo.cols);
  cv::Mat picture;
  cv::vconcat(stereo, slice, picture);
  return WritePicture(flags.out, picture);
}

}  // namespace mav::sim_cli
