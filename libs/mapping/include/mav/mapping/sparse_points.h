#pragma once
// The sparse front end of the mapping pipeline: about 100 stereo-matched features per keyframe,
// triangulated from the rectified pair at the keyframe's known pose and merged across keyframes
// into one global point cloud that keeps every point's visibility. This is the input of the
// multi-view mesher (delaunay_graph_cut.h), as in Holzmann et al., "Performance Evaluation of
// Vision-Based Algorithms for MAVs" (OAGM 2015), Section 2.2: "From these keyframes we collect
// sparse features (approximately 100) that are extracted and matched using libviso2. Using these
// features, we unproject 3D points and store them in a global point cloud with visibility
// information."
//
// Per keyframe (docs/mapping.md, "Sparse points", has the reasons for each choice):
//  1. Features of both rectified images with the sparse VO's extractor (localization/features.h,
//     StereoScan blob/corner features with 32-byte Sobel descriptors; Geiger et al., IV 2011).
//  2. Stereo matching: every left feature searches the right features of its class on the same
//     row (+- row_tolerance_px) at disparities [fx b / max_depth_m, fx b / min_depth_m]; the best
//     descriptor SAD wins if it is clearly better than the second best on the row (uniqueness
//     ratio), and the match is kept only if the right feature's own best match back in the left
//     image is the same feature (left-right consistency). The right position is then
//     refined to sub-pixel accuracy with the VO's parabola fit (localization::
//     RefineMatchesSubpixel), which sharpens the disparity and so the depth.
//  3. Re-observation (the merge): the points of the cloud seen by one of the last
//     `merge_window_keyframes` keyframes are projected into the new left image with the known
//     pose. A stereo match re-observes a point when it is of the point's feature class, lies within
//     `merge_radius_px` of the projection, its descriptor SAD to the point's last descriptor is at
//     most `merge_max_descriptor_sad`, and its depth agrees with the point's predicted depth within
//     max(merge_min_depth_tolerance_m, merge_relative_depth_tolerance * depth). Pairs are assigned
//     one to one, lowest SAD first.
//  4. Selection of ~target_points_per_keyframe matches spread over the image: the image is cut into
//     bucket_cols x bucket_rows buckets; within a bucket re-observations come first, then lower
//     stereo cost; buckets are visited round-robin (every bucket's best, then every bucket's second
//     best, ...) until the target is reached. Re-observations are preferred because a point seen
//     from several keyframes gives the mesher several lines of sight.
//     With foreground_points_per_keyframe > 0, a second budget takes verified matches at depth
//     discontinuities (thin structures in front of a wall) that the spread missed.
//  5. A selected re-observation adds the keyframe to the point's visibility and moves the point to
//     the inverse-variance weighted mean of its triangulations (stereo depth variance grows as Z^4,
//     so the weight is 1 / Z^4); any other selected match becomes a new point.
//  6. Two-keyframe verification of single-view points (docs/mapping.md, "Outlier rejection"):
//     every stereo match of a keyframe (selected or not) is checked against every stereo match of
//     the `verify_window_keyframes` keyframes before it, with the known poses. A pair supports
//     each other when, transferred into the later keyframe, the earlier match lands within
//     `verify_radius_px` of the later one, at a disparity within `verify_disparity_tolerance_px`,
//     of the same feature class and with a descriptor SAD of at most `verify_max_descriptor_sad`.
//     A point is "checked" by a keyframe of the window (before or after it) in whose image and
//     depth range it projects. Points() leaves out a point seen by one keyframe only that was
//     checked at least once and never supported: a wrong disparity (the aperture problem along
//     horizontal structures, repetitive texture) triangulates to a point that another viewpoint's
//     independent stereo match does not reproduce, whereas a true surface point is re-matched
//     at the transferred position. Selection (step 4) prefers supported matches after
//     re-observations. The rejected points stay in AllPoints(): their depth is doubtful but the
//     space in front of them was seen, so they still give lines of sight for the free space
//     (mesh_to_grid.h rule 4). The matches that a neighbour reproduced but the selection did not
//     take become extra lines of sight too (SightPoints()): the mesh keeps the paper's ~100 points
//     per keyframe, the free space gets every verified observation.
//
// The poses are trusted (ground truth in the evaluation, as the paper's Vicon poses): there is no
// bundle adjustment. Not thread-safe; one thread owns a SparsePointCloud.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"
#include "mav/localization/features.h"
#include "mav/mapping/types.h"

namespace mav::mapping {

struct SparsePointsOptions {
  // The sparse VO's feature detector (same defaults as localization::SparseVo).
  localization::FeatureOptions features;

  // Stereo matching. Depth range [m] of accepted matches, converted to a disparity range with the
  // rig: 6 m keeps the depth noise of a quarter-pixel disparity error on EuRoC's rig
  // (fx b ~ 50 px m) at 0.18 m, the walls of the 8 x 8 m room are all seen closer than that from
  // somewhere; 0.3 m is below the simulator's minimum clearance.
  double min_depth_m = 0.3;
  double max_depth_m = 6.0;
  // |v_left - v_right| allowed [px] (rectified images: 0 in theory, 1 for detection jitter).
  int row_tolerance_px = 1;
  // Uniqueness test: a match is kept only if its descriptor SAD is at most this fraction of the
  // second-best SAD among the candidates on the row (1 disables). Repetitive or weak texture
  // (a plain ceiling) otherwise yields confident-looking wrong disparities, and a point
  // triangulated behind a surface makes its line of sight carve through it.
  double stereo_uniqueness_ratio = 0.9;
  // Refine the right position to sub-pixel accuracy (localization::RefineMatchesSubpixel).
  bool subpixel = true;
  // Half window [px] of the sub-pixel refinement (1..4).
  int refine_half_window_px = 3;

  // Selection: about this many matches per keyframe (the paper: ~100), spread over the image.
  int target_points_per_keyframe = 100;
  int bucket_cols = 10;
  int bucket_rows = 6;
  // Thin-structure budget (0 = off, the paper's selection): up to this many more matches per
  // keyframe at depth discontinuities, i.e. verified matches (re-observed or supported, step 6)
  // whose depth is at most (1 - foreground_depth_drop) times the median depth of the matches within
  // foreground_radius_px: a pipe, a rung or a table edge in front of the wall behind it, which the
  // even spread of step 4 rarely picks. Largest relative drop first.
  int foreground_points_per_keyframe = 0;
  double foreground_depth_drop = 0.2;
  double foreground_radius_px = 40.0;

  // Merging (re-observation) of points across keyframes, see the header comment.
  int merge_window_keyframes = 10;      // 0 disables merging
  double merge_radius_px = 3.0;         // reprojection gate
  int merge_max_descriptor_sad = 2500;  // of 8160 (32 bytes x 255)
  double merge_min_depth_tolerance_m = 0.05;
  double merge_relative_depth_tolerance = 0.05;

  // Also apply every re-observation beyond the target (they add lines of sight to existing
  // points, not new points); the target then bounds the new points plus the preferred
  // re-observations only.
  bool apply_all_reobservations = false;

  // Two-keyframe verification of single-view points (step 6 of the header comment).
  // 0 disables it (Points() then returns every point).
  int verify_window_keyframes = 2;
  double verify_radius_px = 3.0;
  double verify_disparity_tolerance_px = 1.0;
  int verify_max_descriptor_sad = 2500;  // of 8160
  // Keep single-view points that no keyframe of the window could check (outside every
  // neighbour's image or depth range: the first and last views of a surface).
  bool keep_unchecked_points = true;

  // Extract the left and right features on two threads (the images are independent).
  bool parallel_extraction = true;

  // Cap on the extra lines of sight kept for the free space (SightPoints(): 32 bytes each); the
  // ones beyond are dropped and counted (SparsePointsStats::sight_lines_dropped). A full room
  // preset keeps 0.35-0.65 M; 4 M bound them to 128 MiB whatever a session streams. 0 = keep
  // none.
  int64_t max_sight_lines = 4'000'000;

  // False with the offending field named in *why ("max_depth_m: must exceed min_depth_m ...",
  // "features.nms_radius: ...").
  bool IsValid(std::string* why) const;
};

// One stereo-matched feature of a keyframe: the input of the merge step, exposed so tests (and
// front ends with their own matcher) can feed observations directly.
struct StereoObservation {
  float u_left = 0, v_left = 0;  // rectified left pixel
  float disparity = 0;           // u_left - u_right [px], > 0
  int feature_class = 0;         // localization::FeatureClass; only equal classes merge
  localization::Descriptor descriptor;
  uint32_t stereo_cost = 0;  // descriptor SAD of the stereo match (lower = more reliable)
};

struct SparseKeyframeStats {
  int id = -1;
  int left_features = 0;
  int right_features = 0;
  int stereo_matches = 0;    // left-right consistent matches within the depth range
  int reobservable = 0;      // matches that passed the re-observation gates
  int selected = 0;          // matches kept (~target_points_per_keyframe)
  int reobserved = 0;        // of the selected: merged into existing points
  int new_points = 0;        // of the selected: new points
  int supported = 0;         // matches supported by a match of an earlier keyframe (step 6)
  int foreground = 0;        // of the selected: taken by the thin-structure budget
  double extraction_ms = 0;  // feature extraction, both images
  double matching_ms = 0;    // stereo matching and sub-pixel refinement
  double merging_ms = 0;     // projection, gating, selection, triangulation, update
  double total_ms = 0;
};

struct SparsePointsStats {
  std::vector<SparseKeyframeStats> keyframes;
  int64_t sight_lines_dropped = 0;  // beyond SparsePointsOptions::max_sight_lines
  double TotalMs() const;
  double TotalExtractionMs() const;
  double TotalMatchingMs() const;
  double TotalMergingMs() const;
  int64_t TotalSelected() const;
  int64_t TotalReobserved() const;
};

class SparsePointCloud {
 public:
  // InvalidArgument naming the field for an invalid rig ("rig: ...") or options ("options.<f>").
  static Result<SparsePointCloud> Create(const camera::RectifiedStereo& rig,
                                         const SparsePointsOptions& options = {});

  // Adds a keyframe from its rectified 8-bit grey pair (rig.width x rig.height, `stride` bytes per
  // row) and the pose of the rectified left camera (x right, y down, z forward). Returns the
  // keyframe id (0, 1, 2, ... in call order). InvalidArgument naming "left"/"right" (null data,
  // size differing from the rig, stride < width) or "T_world_cam" (non-finite) leaves the cloud
  // unchanged.
  Result<int> AddKeyframe(const localization::ImageView& left, const localization::ImageView& right,
                          const geometry::SE3& T_world_cam);

  // Steps 3-5 only, for observations matched elsewhere. InvalidArgument naming the offending
  // "observations[i].<field>" (non-finite, disparity <= 0 or out of the depth range, class out
  // of range) or "T_world_cam".
  Result<int> AddKeyframeObservations(const std::vector<StereoObservation>& observations,
                                      const geometry::SE3& T_world_cam);

  // Stereo matching of one pair (steps 1-2), without touching the cloud. Same errors as
  // AddKeyframe. `stats` (optional) receives feature counts and times.
  Result<std::vector<StereoObservation>> MatchStereo(const localization::ImageView& left,
                                                     const localization::ImageView& right,
                                                     SparseKeyframeStats* stats = nullptr);

  // The cloud for the mesher: every point with the ids of the keyframes that saw it (ascending),
  // and every keyframe's optical centre. With verification on (verify_window_keyframes > 0) the
  // single-view points rejected by step 6 are left out; num_points() still counts them.
  std::vector<MapPoint> Points() const;
  // The same with SparsePointsOptions::keep_unchecked_points given for this call (a map
  // preference decides it per build).
  std::vector<MapPoint> Points(bool keep_unchecked_points) const;
  // Every point, the rejected single-view ones included: the lines of sight that observed free
  // space (a rejected point's depth is doubtful, the space in front of it was still seen).
  std::vector<MapPoint> AllPoints() const;
  // AllPoints() plus the stereo matches that were not selected but that the verification
  // reproduced in a neighbouring keyframe (each with the one keyframe that matched it): many more
  // lines of sight, each to a reliable point, for the free space.
  std::vector<MapPoint> SightPoints() const;
  // Points() would return this many (= num_points() - rejected single-view points).
  int64_t num_accepted_points() const;
  const std::vector<KeyframeView>& keyframes() const { return keyframes_; }
  const std::vector<geometry::SE3>& keyframe_poses() const { return T_world_cams_; }
  int64_t num_points() const { return static_cast<int64_t>(tracks_.size()); }
  const SparsePointsStats& stats() const { return stats_; }
  const SparsePointsOptions& options() const { return options_; }
  const camera::RectifiedStereo& rig() const { return rig_; }

  void Reset();  // forgets points, keyframes and stats

  SparsePointCloud(SparsePointCloud&&) noexcept;
  SparsePointCloud& operator=(SparsePointCloud&&) noexcept;
  ~SparsePointCloud();

 private:
  struct Track {
    Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
    double weight = 0;  // sum of 1 / Z^4
    std::vector<int> keyframes;
    localization::Descriptor descriptor;  // of the latest observation
    int feature_class = 0;
    int checks = 0;          // keyframes of the verification window it projects into (step 6)
    bool supported = false;  // a match of another keyframe reproduced it (step 6)
  };
  // Every stereo match of a recent keyframe, for the verification (step 6).
  struct KeyframeMatches {
    int id = 0;  // keyframe id
    geometry::SE3 T_cam_world;
    std::vector<Eigen::Vector3d> p_world;
    std::vector<int> feature_class;
    std::vector<localization::Descriptor> descriptors;
    std::vector<int> track;  // the track the match became or re-observed, -1 if not selected
    std::vector<char> in_sight_lines;  // already added to extra_sight_lines_
  };
  struct Extractors;
  bool Accepted(const Track& t, bool keep_unchecked_points) const;

  SparsePointCloud(const camera::RectifiedStereo& rig, const SparsePointsOptions& options);
  Result<int> AddObservationsTimed(const std::vector<StereoObservation>& observations,
                                   const geometry::SE3& T_world_cam, SparseKeyframeStats stats);

  camera::RectifiedStereo rig_;
  SparsePointsOptions options_;
  std::vector<Track> tracks_;
  std::vector<KeyframeView> keyframes_;
  std::vector<geometry::SE3> T_world_cams_;
  std::vector<std::vector<int>> keyframe_tracks_;  // tracks observed by each keyframe
  std::vector<KeyframeMatches> recent_matches_;    // the last verify_window_keyframes keyframes
  // A supported match that became no point: a line of sight from keyframe `keyframe`, stored
  // compactly (a MapPoint's visibility vector would cost a heap allocation per line).
  struct SightLine {
    Eigen::Vector3d p_world;
    int keyframe = 0;
  };
  void AddSightLine(const Eigen::Vector3d& p_world, int keyframe);
  std::vector<SightLine> extra_sight_lines_;  // at most options_.max_sight_lines
  SparsePointsStats stats_;
  std::unique_ptr<Extractors> extractors_;
};

}  // namespace mav::mapping
