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
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/dataset/read_options.h"
#include "mav/dataset/types.h"
#include "mav/geometry/se3.h"

namespace mav::dataset {

// The readers also have in-memory forms (Parse*: an upload, a fuzzer) where `name` stands for the
// path in messages. Every number must be finite and within +-1e9 (see euroc.h).

Status WriteTumTrajectory(const std::string& path, const std::vector<StampedPose>& poses);
// Errors: NotFound; InvalidArgument "path:line: expected 8 columns, got N" or
// "path:line: column 'qw': ..." for a malformed row, a zero quaternion, a time stamp beyond
// int64 nanoseconds (9.2e9 s) or time going backwards. A repeated time stamp (TUM's own fr2/desk
// ground truth has one) is handled as `options` says: by default the first row is kept and the
// others dropped with a warning naming path:line (read_options.h).
Result<std::vector<StampedPose>> ReadTumTrajectory(const std::string& path,
                                                   const ReadOptions& options = {});
Result<std::vector<StampedPose>> ParseTumTrajectory(std::string_view text, const std::string& name,
                                                    const ReadOptions& options = {});

using KittiMatrix = Eigen::Matrix<double, 3, 4>;

Status WriteKittiTrajectory(const std::string& path, const std::vector<geometry::SE3>& poses);
// ReadKittiMatrices plus "path:line: rotation block is not a rotation" for a matrix whose left
// 3x3 block is not a rotation (|R R^T - I| >= 1e-6 or det <= 0).
Result<std::vector<geometry::SE3>> ReadKittiTrajectory(const std::string& path);
Result<std::vector<geometry::SE3>> ParseKittiTrajectory(std::string_view text,
                                                        const std::string& name);
// The raw matrices, exactly as in the file.
Status WriteKittiMatrices(const std::string& path, const std::vector<KittiMatrix>& matrices);
// Errors: NotFound; InvalidArgument "path:line: expected 12 numbers, got N" or
// "path:line: entry 'r01': ..." for a malformed number.
Result<std::vector<KittiMatrix>> ReadKittiMatrices(const std::string& path);
Result<std::vector<KittiMatrix>> ParseKittiMatrices(std::string_view text, const std::string& name);

}  // namespace mav::dataset
