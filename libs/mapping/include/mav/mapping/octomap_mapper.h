#pragma once
// The paper's baseline mapper: dense stereo range images from known camera poses integrated into
// an OctoMap (Holzmann et al., OAGM 2015, Section 2.2, "OctoMap + libELAS"; OctoMap: Hornung,
// Wurm, Bennewitz, Stachniss, Burgard, "OctoMap: an efficient probabilistic 3D mapping framework
// based on octrees", Autonomous Robots 2013).
//
// Per keyframe:
//   1. Dense disparity of the rectified pair. The paper used libELAS (Geiger, Roser, Urtasun,
//      ACCV 2010, ~250 ms per 752x480 pair). We use OpenCV's semi-global matcher (StereoSGBM,
//      Hirschmueller, PAMI 2008) in its role by default: like ELAS it regularises the disparity
//      over the image, so it fills weakly textured regions and produces far fewer holes and
//      speckles than local block matching; that is the quality the baseline's accuracy depends
//      on. StereoBM (local SAD block matching) is available through `matcher` and is several
//      times faster, but leaves holes wherever texture is weak (those regions then stay unknown,
//      i.e. count as occupied in the evaluation). Measured per-pair times are in
//      benchmarks/octomap_mapper_benchmark.cc and docs/benchmarks.md.
//   2. Valid disparities d > 0 on every `pixel_stride`-th pixel of every `pixel_stride`-th row are
//      triangulated in the rectified left frame, Z = fx * baseline / d, and moved to the world
//      with T_world_cam.
//   3. The points are inserted with ray casting from the camera centre
//      (octomap::OcTree::insertPointCloud): cells on each ray get a "miss" update, the end cell a
//      "hit" (hit wins when a cell is both within one scan). Rays longer than `max_range_m` are
//      truncated: free space is cleared up to max_range_m and no endpoint is inserted. With
//      `discretize` the end points are first merged per voxel so each voxel's ray is cast once
//      (OctoMap's discretized insertion, ~10x faster at our point densities; the map differs
//      only in cells grazed by rays of merged points).
//
// Occupancy semantics (OctoMap's): a leaf is occupied if its probability > occupancy_threshold,
// free otherwise; space without a leaf was never observed and is unknown. The paper counts unknown
// space as occupied in collision checks; that is applied by the evaluator (CollisionEvalOptions::
// computed_unknown_is_occupied), not here: Classify and ToGrid report unknown as unknown.
//
// OctoMap and OpenCV stay out of this header (pimpl; cv::Mat and octomap::OcTree are forward
// declared). Not thread-safe: one thread owns a mapper.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"
#include "mav/mapping/types.h"

namespace cv {
class Mat;
}
namespace octomap {
class OcTree;
}

namespace mav::mapping {

enum class StereoMatcherType {
  kSgbm,  // cv::StereoSGBM (semi-global): libELAS-like density and quality. Default.
  kBm,    // cv::StereoBM (local block matching): faster, holes in weak texture.
};

struct OctomapMapperOptions {
  // Octree leaf size [m]; the paper's and our evaluation grids use 5 cm. OctoMap addresses
  // 2^16 leaves per axis centred on the world origin, so the map covers +-2^15 * resolution
  // (+-1638.4 m at 5 cm) on each axis: MaxAbsCoordinateM().
  double resolution = 0.05;

  double MaxAbsCoordinateM() const { return 32768.0 * resolution; }
  // Rays are truncated at this range [m]. Why 5 m: stereo depth noise grows quadratically,
  // sigma_Z = Z^2 sigma_d / (fx b); with EuRoC's fx b ~ 458 px * 0.11 m ~ 50 px m and a quarter-
  // pixel disparity error, sigma_Z is 0.12 m (2.5 voxels) at 5 m and 0.31 m at 8 m, so farther
  // points would smear surfaces over many voxels; 5 m still reaches most walls of the 8 x 8 m
  // Vicon room from its centre part.
  double max_range_m = 5.0;
  // Pixels closer than this depth [m] are dropped (matching artefacts right in front of the
  // lens). The disparity search range already limits the depth from below: see num_disparities.
  double min_range_m = 0.2;
  // Sample every pixel_stride-th pixel of every pixel_stride-th row. The default 4 keeps the
  // sample spacing on a surface at max range, max_range_m * pixel_stride / fx ~ 4.4 cm, below the
  // 5 cm voxel size, so no voxel a full-resolution image would hit is skipped at 5 m, at 1/16 of
  // the rays.
  int pixel_stride = 4;
  // OctoMap's discretized insertion (see the header comment).
  bool discretize = true;

  // Sensor model (OctoMap's defaults, Hornung et al. 2013, Sec. 5): probabilities that a hit /
  // miss cell is occupied, the clamping bounds of the occupancy probability (keep the map
  // updatable), and the threshold above which a leaf counts as occupied.
  double prob_hit = 0.7;
  double prob_miss = 0.4;
  double clamping_min = 0.1192;
  double clamping_max = 0.971;
  double occupancy_threshold = 0.5;

  // Dense stereo (OpenCV calib3d). Disparities searched: [0, num_disparities).
  StereoMatcherType matcher = StereoMatcherType::kSgbm;
  // Multiple of 16. 96 px reaches down to fx b / 96 ~ 0.52 m on EuRoC's rig, below the
  // simulator's 0.6 m minimum clearance; closer surfaces would be matched wrongly. Cost is linear
  // in it.
  int num_disparities = 96;
  // Matching window edge [px]: odd; SGBM 1..11 (typically 3..11), BM 5..255.
  int block_size = 5;
  // Reject a match whose best cost is not better than the second best by this margin [%].
  int uniqueness_ratio = 10;
  // Speckle filter: connected disparity blobs up to this many pixels whose disparity varies by
  // at most speckle_range (in pixels) are invalidated. 0 disables.
  int speckle_window_size = 100;
  int speckle_range = 2;
  // Left-right consistency check tolerance [px]; negative disables.
  int disp12_max_diff = 1;
  // SGBM smoothness penalties; 0 = the usual 8 * block_size^2 and 32 * block_size^2.
  int sgbm_p1 = 0;
  int sgbm_p2 = 0;
  // SGBM in its single-pass 3-way mode (MODE_SGBM_3WAY): faster and multithreaded by OpenCV,
  // with nearly the quality of the 5-direction mode. false = MODE_SGBM (5 directions).
  bool sgbm_three_way = true;
  // BM's texture threshold (pixels with less local texture are invalid).
  int bm_texture_threshold = 10;

  // False with the offending field named in *why (e.g. "num_disparities: must be a positive
  // multiple of 16, got 50").
  bool IsValid(std::string* why) const;
};

// Per-keyframe and total cost of the mapping.
struct OctomapKeyframeTiming {
  double disparity_ms = 0;  // dense stereo matching
  double points_ms = 0;     // disparity -> world points
  double insertion_ms = 0;  // OctoMap ray casting and update
  int64_t points = 0;       // points inserted (after stride, validity and range filtering)
};

struct OctomapMapperStats {
  std::vector<OctomapKeyframeTiming> keyframes;
  double finish_ms = 0;  // Finish(): final pruning

  double TotalDisparityMs() const;
  double TotalPointsMs() const;
  double TotalInsertionMs() const;
  // Sum of every keyframe's cost plus finish_ms: the whole data set's mapping time.
  double TotalMs() const;
  int64_t TotalPoints() const;
};

// Result of a box query.
enum class BoxOccupancy { kFree, kOccupied, kUnknown };
const char* BoxOccupancyName(BoxOccupancy occupancy);

class OctomapMapper {
 public:
  // InvalidArgument "options.<field>: ..." for invalid options.
  static Result<OctomapMapper> Create(const OctomapMapperOptions& options = {});

  OctomapMapper(OctomapMapper&&) noexcept;
  OctomapMapper& operator=(OctomapMapper&&) noexcept;
  ~OctomapMapper();

  // Integrates one keyframe (see the header comment). `left` and `right` are the rectified
  // images as CV_8UC1 of stereo.width x stereo.height; T_world_cam is the pose of the rectified
  // left camera (x right, y down, z along the optical axis). InvalidArgument naming the field
  // ("left: empty image", "right: expected CV_8UC1 (8-bit grey), got CV_16UC1", "left: size
  // 640x480 differs from stereo 752x480", "stereo: ...", "T_world_cam: non-finite") leaves the
  // map unchanged. A keyframe without a single valid disparity is OK (nothing is inserted).
  Status InsertKeyframe(const cv::Mat& left, const cv::Mat& right,
                        const camera::RectifiedStereo& stereo, const geometry::SE3& T_world_cam);

  // Ends a data set: prunes the octree (merges uniform children) and records the time. Further
  // keyframes may still be inserted afterwards. Returns the stats.
  const OctomapMapperStats& Finish();

  const OctomapMapperOptions& options() const;
  const OctomapMapperStats& stats() const;
  int64_t num_keyframes() const;
  // Number of leaves of the octree (pruned leaves count once).
  int64_t NumLeaves() const;
  // The underlying octree, for callers that include <octomap/OcTree.h> themselves.
  const octomap::OcTree& tree() const;

  // Free / occupied / unknown state of an axis-aligned world box [m]: kOccupied if any occupied
  // leaf overlaps it, else kUnknown if any part of it was never observed, else kFree. A leaf
  // overlaps the box when their intersection has positive volume (touching faces do not count;
  // a box that is flat along an axis uses the voxel layer containing it). Cost: one octree
  // lookup per resolution-sized voxel the box covers. InvalidArgument for an empty, inverted or
  // non-finite box ("box: ..."), or one outside OctoMap's addressable +-1638 m (at 5 cm).
  Result<BoxOccupancy> Classify(const Eigen::AlignedBox3d& box_world) const;

  // The map sampled onto a dense grid (layout of OccupancyGrid / mav::dataset::OccupancyGrid, x
  // fastest). Each grid voxel gets the Classify rule applied to its cube, so grids of another
  // resolution or alignment stay conservative. When origin / resolution are multiples of the map
  // resolution each grid voxel is exactly one octree voxel. Cost O(leaves + voxels).
  // InvalidArgument "geometry: ..." for an invalid geometry.
  Result<OccupancyGrid> ToGrid(const GridGeometry& geometry) const;

  // OctoMap binary (.bt, maximum-likelihood occupied/free leaves; octovis reads it). IoError
  // naming the path when writing fails.
  Status WriteBinary(const std::string& path) const;

  // Clears the map and the stats (options unchanged).
  void Reset();

 private:
  struct Impl;
  explicit OctomapMapper(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mav::mapping
