#pragma once
// Circular ("quad") matching of sparse features across two rectified stereo pairs, bucketing and
// sub-pixel refinement, after Geiger, Ziegler, Stiller, "StereoScan" (IV 2011), Section III-A.
//
// For every feature of the previous left image, the best match (lowest descriptor SAD, same
// feature class) is searched along the loop
//   previous left -> previous right -> current right -> current left -> previous left;
// the match is kept only if the loop closes, i.e. the last search returns to the start feature.
// Stereo searches run along the same row (+- row tolerance) at positive disparity; temporal
// searches run in a window around a predicted position: the stereo point moved by the predicted
// motion (constant velocity) or, without a prediction, the position in the other frame.
// All searches visit only the cells of the features' grid index that the window overlaps, so the
// cost grows with the number of features times the features per window, not quadratically.

#include <cstdint>
#include <string>
#include <vector>

#include "mav/camera/stereo.h"
#include "mav/geometry/se3.h"
#include "mav/localization/features.h"

namespace mav::localization {

// One feature seen in all four images. Positions in pixels of the rectified images; integer
// valued unless refined.
struct QuadMatch {
  float u_prev_left = 0, v_prev_left = 0;
  float u_prev_right = 0, v_prev_right = 0;
  float u_cur_left = 0, v_cur_left = 0;
  float u_cur_right = 0, v_cur_right = 0;
  uint32_t cost = 0;  // sum of the four descriptor SADs of the loop
  int feature_class = 0;
};

struct MatcherOptions {
  // Stereo matches: |v_left - v_right| <= stereo_row_tolerance_px and
  // min_disparity_px <= u_left - u_right <= max_disparity_px.
  int stereo_row_tolerance_px = 1;
  int min_disparity_px = 1;
  int max_disparity_px = 200;
  // Half side of the square window of the temporal searches, around the predicted position:
  // search_radius_px with a motion prediction, search_radius_no_prior_px without one (first
  // frame, after a lost frame, or options.use_motion_prior = false).
  int search_radius_px = 24;
  int search_radius_no_prior_px = 64;
  // The loop closes when it ends within this distance (pixels, max-norm) of where it started.
  int loop_tolerance_px = 1;
  // Predict temporal positions from the previous frame's motion (constant velocity). Without a
  // prediction the window is centred at the same pixel.
  bool use_motion_prior = true;

  // Start features: the loop is only started from the max_starts_per_bucket strongest features
  // (largest |filter response|, any class) of each bucket of the previous left image (0: from all
  // features). Bucketing keeps only a few matches per bucket anyway, so trying a few times that
  // many starts yields nearly the same matches at a fraction of the cost.
  int max_starts_per_bucket = 24;

  // Bucketing: at most bucket_max_matches matches (lowest loop cost first) per
  // bucket_width_px x bucket_height_px cell of the current left image.
  int bucket_width_px = 50;
  int bucket_height_px = 50;
  int bucket_max_matches = 6;

  // Sub-pixel refinement: half side of the window of Sobel responses compared (SSD) around each
  // match, see RefineMatchesSubpixel.
  int refine_half_window_px = 3;

  // Search the temporal (square) windows eight features at a time with AVX-512 when the CPU has
  // it (F, BW, VL, DQ): the same matches (matcher_test compares).
  bool use_avx512 = true;

  bool IsValid(std::string* why) const;
};

// Whether MatchCircular searches its square windows with AVX-512 under `options`.
bool MatcherUsesAvx512(const MatcherOptions& options);

// Circular matching. With a prediction (`T_cur_prev_predicted` non-null and
// options.use_motion_prior), the stereo points of the previous pair moved by the predicted motion
// (which maps previous-left-camera points into the current left camera) centre the temporal
// windows of radius search_radius_px; otherwise windows of radius search_radius_no_prior_px are
// centred at the same pixel. Output order is deterministic.
void MatchCircular(const FeatureSet& prev_left, const FeatureSet& prev_right,
                   const FeatureSet& cur_left, const FeatureSet& cur_right,
                   const camera::RectifiedStereo& rig, const geometry::SE3* T_cur_prev_predicted,
                   const MatcherOptions& options, std::vector<QuadMatch>* matches);

// Keeps at most options.bucket_max_matches per bucket of the current left image, preferring the
// lowest loop cost (ties by position, so the result is deterministic).
void BucketMatches(const MatcherOptions& options, int image_width, int image_height,
                   std::vector<QuadMatch>* matches);

// Sub-pixel refinement (the StereoScan "subpixel" mode): the previous-left position stays at its
// integer feature position and is the reference. For each of the other three images the cost
// C(du, dv) = sum of squared differences of both Sobel images over a (2r+1)^2 window between the
// reference and the target shifted by (du, dv) is evaluated on the 3x3 integer neighbourhood,
// the centre moved to the minimum (at most twice), and a parabola through C(-1), C(0), C(+1) is
// fitted along u and along v; its vertex (clamped to +-0.5 px) is the sub-pixel offset.
// The SSD is used instead of the SAD because it is quadratic in a small shift, so the parabola
// vertex is unbiased, while the V-shaped SAD pulls vertices towards integers.
void RefineMatchesSubpixel(const FeatureSet& prev_left, const FeatureSet& prev_right,
                           const FeatureSet& cur_left, const FeatureSet& cur_right,
                           const MatcherOptions& options, std::vector<QuadMatch>* matches);

// Pixel refinement (the StereoScan / libviso2 "pixel" mode): as RefineMatchesSubpixel without
// the parabola, i.e. each of the three other positions moves to the integer position of minimal
// SSD against the previous-left reference (searched on the 3x3 neighbourhood, at most two
// moves). Positions stay integers, but they are placed relative to the reference rather than
// where each image's own detector happened to peak.
void RefineMatchesPixel(const FeatureSet& prev_left, const FeatureSet& prev_right,
                        const FeatureSet& cur_left, const FeatureSet& cur_right,
                        const MatcherOptions& options, std::vector<QuadMatch>* matches);

}  // namespace mav::localization
