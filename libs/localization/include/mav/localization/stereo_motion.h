#pragma once
// Egomotion from stereo correspondences, after Geiger, Ziegler, Stiller, "StereoScan" (IV 2011),
// Section III-B: 3D points triangulated from the previous stereo pair are projected into both
// images of the current pair; the motion minimises the reprojection error
//   E(T) = sum_i || pi_left(T X_i) - x_i,left ||^2 + || pi_right(T X_i) - x_i,right ||^2
// with Gauss-Newton, inside RANSAC over minimal sets of 3 correspondences, followed by a final
// refinement on all inliers.
//
// Frames: X_i are in the previous rectified left camera; T = T_cur_prev maps them into the
// current rectified left camera; the right camera sits at +baseline along x
// (camera::RectifiedStereo). Gauss-Newton updates T <- Exp(delta) * T with delta = (rho, phi) as
// geometry::SE3::Exp.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/camera/stereo.h"
#include "mav/geometry/se3.h"

namespace mav::localization {

// Observation of one point in the current pair: (u_left, v_left, u_right, v_right), pixels.
using StereoObservation = Eigen::Vector4d;
using Matrix46d = Eigen::Matrix<double, 4, 6>;

// Residual r = projection - observation (left u, v, right u, v) of point p_prev under T_cur_prev,
// and optionally its Jacobian with respect to the left-multiplied tangent delta at delta = 0.
// Returns false (r, J untouched) if the point is not in front of the current camera (z < 1 mm).
bool StereoReprojectionResidual(const camera::RectifiedStereo& rig, const geometry::SE3& T_cur_prev,
                                const Eigen::Vector3d& p_prev, const StereoObservation& observation,
                                Eigen::Vector4d* residual, Matrix46d* jacobian);

struct StereoMotionOptions {
  // Upper bound on RANSAC hypotheses; fewer are drawn once `confidence` is reached
  // (N = log(1 - confidence) / log(1 - w^3) for the best inlier ratio w so far).
  int ransac_iterations = 200;
  double confidence = 0.999;
  // A correspondence is an inlier when the norm of its 4-vector residual is below this (pixels).
  double inlier_threshold_px = 2.0;
  // Gauss-Newton iterations for a minimal set and for each final refinement round.
  int minimal_iterations = 15;
  int refinement_iterations = 30;
  // Estimation fails with fewer inliers than this.
  int min_inliers = 10;
  // RANSAC's random generator is seeded with seed (the caller may mix in a frame index).
  uint64_t seed = 42;
  // After the motion-only refinement, refine the motion jointly with the inliers' points
  // (RefineStereoMotionAndStructure), so that the noise of the previous pair's matches is
  // modelled instead of being taken as exact depth. Motion-only refinement treats the
  // triangulated points as exact (an errors-in-variables problem); on the simulator's room
  // sequences with integer matches it came out ~5 % short in translation with a consistent yaw
  // error, ~3.5 % with this (and 0.7 % -> 0.4 % with sub-pixel matches). Not a general cure:
  // both estimates carry an O(noise^2) scale bias whose size depends on the scene (on a shallow
  // synthetic scene with sideways motion the joint one is the larger, see stereo_motion_test).
  bool refine_structure = true;
  // Gauss-Newton iterations of that joint refinement (it starts from the motion-only solution
  // and converges in a few).
  int structure_iterations = 3;

  bool IsValid(std::string* why) const;
};

// A prior on the rotation of T_cur_prev (e.g. the gyro's): the residual
//   r = weight_px_per_rad * Log(R_cur_prev_estimate * R_cur_prev^-1)
// joins the reprojection residuals (pixels) in every refinement, so weight_px_per_rad is the
// reprojection noise over the prior's noise (0.5 px / 1e-4 rad = 5000). It weighs little
// against a few hundred well-spread inliers and decides the directions the points leave
// ambiguous (a sideways shift against a turn, over near or few points). RANSAC starts its
// hypotheses at the prior's rotation and drops those farther than gate_rad from it (0 = no
// gate).
struct RotationPrior {
  Eigen::Quaterniond R_cur_prev = Eigen::Quaterniond::Identity();
  double weight_px_per_rad = 0;
  double gate_rad = 0;
};

struct StereoMotionEstimate {
  bool ok = false;
  std::string failure;  // why not ok
  geometry::SE3 T_cur_prev;
  std::vector<int> inliers;  // indices into the input, ascending
  double mean_error_px = 0;  // mean residual norm over inliers
  int hypotheses = 0;        // RANSAC hypotheses drawn
  // The rotation the inliers alone give: T_cur_prev's without a prior; with one, T_cur_prev's
  // after a Gauss-Newton step on the reprojection errors alone (what a prior's source, e.g. a
  // gyro's bias, must be compared with: the estimate itself leans toward the prior).
  Eigen::Quaterniond vision_R_cur_prev = Eigen::Quaterniond::Identity();
};

// Gauss-Newton on the correspondences `indices` starting from *T_cur_prev. Returns false (and
// leaves *T_cur_prev untouched) if the normal equations are singular or the result is not
// finite. Converged when the update norm drops below 1e-10.
bool RefineStereoMotion(const camera::RectifiedStereo& rig,
                        const std::vector<Eigen::Vector3d>& points_prev,
                        const std::vector<StereoObservation>& observations,
                        const std::vector<int>& indices, int max_iterations,
                        geometry::SE3* T_cur_prev, const RotationPrior* prior = nullptr);

// Joint Gauss-Newton over the motion and the points `indices` (two-view bundle adjustment with
// the points eliminated by the Schur complement). Each point is parametrised by its previous
// left pixel and disparity (u, v, d), initialised from points_prev; its residuals are the
// reprojection errors in the previous left and right images (against the projections of
// points_prev, i.e. the previous matches) and in the current ones (observations). Converged
// when the motion update norm drops below 1e-9. Returns false (leaving *T_cur_prev untouched)
// on a singular system, a non-finite result or fewer than 3 usable points.
bool RefineStereoMotionAndStructure(const camera::RectifiedStereo& rig,
                                    const std::vector<Eigen::Vector3d>& points_prev,
                                    const std::vector<StereoObservation>& observations,
                                    const std::vector<int>& indices, int max_iterations,
                                    geometry::SE3* T_cur_prev,
                                    const RotationPrior* prior = nullptr);

// RANSAC + Gauss-Newton. points_prev and observations are parallel. Deterministic for a seed.
// `prior` (may be null): the rotation prior of every refinement and RANSAC's start and gate.
StereoMotionEstimate EstimateStereoMotion(const camera::RectifiedStereo& rig,
                                          const std::vector<Eigen::Vector3d>& points_prev,
                                          const std::vector<StereoObservation>& observations,
                                          const StereoMotionOptions& options,
                                          const RotationPrior* prior = nullptr);

}  // namespace mav::localization
