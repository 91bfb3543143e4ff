#pragma once
// Trajectory files that evaluation tools (evo, the KITTI devkit) read.
//
// TUM (Sturm et al., "A Benchmark for the Evaluation of RGB-D SLAM Systems", IROS 2012):
//   one pose per line, "timestamp tx ty tz qx qy qz qw", timestamp in seconds, fields separated
//   by blanks, lines starting with '#' are comments. We write the timestamp with exactly nine
//   decimals from the integer t_ns, so nanoseconds round-trip exactly; the reader parses the
//   decimal text exactly as well (no detour through a double) when it has at most nine decimals.
//
// KITTI odometry (Geiger et al., CVPR 2012): one pose per line, the 12 numbers of the 3x4 matrix
//   [R | t] row-major, blank-separated, no timestamps. The pose maps the current camera frame into
//   the first camera frame (T_world_cam in our naming).
//
// Numbers are written in their shortest exact decimal form (std::to_chars), so every double in a
// file reads back bit-identically: ReadKittiMatrices(WriteKittiMatrices(m)) == m exactly, and
// rewriting what was read reproduces the file byte for byte. A TUM pose whose quaternion is unit
// to rounding (any normalised quaternion) reads back bit for bit, since geometry::SE3 keeps such a
// quaternion as it is. A KITTI rotation matrix converted to SE3 (a quaternion) and back differs by
// a few units in the last place per entry. Translations and timestamps are always exact.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/dataset/types.h"
#include "mav/geometry/se3.h"

namespace mav::dataset {

Status WriteTumTrajectory(const std::string& path, const std::vector<StampedPose>& poses);
// Errors: NotFound; InvalidArgument "path:line: expected 8 fields, got N" or
// "path:line: field 'qw': ..." for a malformed row, a zero quaternion, or a timestamp that does
// not increase.
Result<std::vector<StampedPose>> ReadTumTrajectory(const std::string& path);

using KittiMatrix = Eigen::Matrix<double, 3, 4>;

Status WriteKittiTrajectory(const std::string& path, const std::vector<geometry::SE3>& poses);
Result<std::vector<geometry::SE3>> ReadKittiTrajectory(const std::string& path);
// The raw matrices, exactly as in the file.
Status WriteKittiMatrices(const std::string& path, const std::vector<KittiMatrix>& matrices);
// Errors: NotFound; InvalidArgument "path:line: expected 12 numbers, got N" or
// "path:line: entry 'r01': ..." for a malformed number.
Result<std::vector<KittiMatrix>> ReadKittiMatrices(const std::string& path);

}  // namespace mav::dataset
