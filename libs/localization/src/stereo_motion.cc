#include "mav/localization/stereo_motion.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>

#include <Eigen/Cholesky>

#include "mav/common/check.h"

namespace mav::localization {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using geometry::Vector6d;

// StereoReprojectionResidual, inlined into the estimation's loops (the residual and Jacobian
// stay in registers; the same operations, so the same bits).
inline __attribute__((always_inline)) bool Residual(const camera::RectifiedStereo& rig,
                                                    const geometry::SE3& T_cur_prev,
                                                    const Eigen::Vector3d& p_prev,
                                                    const StereoObservation& observation,
                                                    Eigen::Vector4d* residual,
                                                    Matrix46d* jacobian) {
  const Eigen::Vector3d p = T_cur_prev * p_prev;
  if (!(p.z() > 1e-3)) return false;
  const double iz = 1.0 / p.z();
  const double xl = p.x() * iz, xr = (p.x() - rig.baseline) * iz, y = p.y() * iz;
  const double v = rig.fy * y + rig.cy;  // both images share the row
  (*residual)(0) = rig.fx * xl + rig.cx - observation(0);
  (*residual)(1) = v - observation(1);
  (*residual)(2) = rig.fx * xr + rig.cx - observation(2);
  (*residual)(3) = v - observation(3);
  if (jacobian != nullptr) {
    // d(projection)/dp, then dp/d(delta) = [I, -Hat(p)] for p' = Exp(delta) p.
    Eigen::Matrix<double, 4, 3> dproj;
    dproj << rig.fx * iz, 0, -rig.fx * xl * iz,  //
        0, rig.fy * iz, -rig.fy * y * iz,        //
        rig.fx * iz, 0, -rig.fx * xr * iz,       //
        0, rig.fy * iz, -rig.fy * y * iz;
    jacobian->leftCols<3>() = dproj;
    jacobian->rightCols<3>() = -dproj * geometry::Hat(p);
  }
  return true;
}

bool IsFinite(const geometry::SE3& T) {
  return T.Translation().allFinite() && T.Rotation().coeffs().allFinite();
}

// Indices of correspondences whose residual norm is below the threshold.
void CollectInliers(const camera::RectifiedStereo& rig, const std::vector<Eigen::Vector3d>& points,
                    const std::vector<StereoObservation>& obs, const geometry::SE3& T,
                    double threshold, std::vector<int>* inliers, double* mean_error) {
  inliers->clear();
  const double t2 = threshold * threshold;
  double sum = 0;
  Eigen::Vector4d r;
  for (size_t i = 0; i < points.size(); ++i) {
    if (!Residual(rig, T, points[i], obs[i], &r, nullptr)) continue;
    const double e2 = r.squaredNorm();
    if (e2 < t2) {
      inliers->push_back(static_cast<int>(i));
      sum += std::sqrt(e2);
    }
  }
  if (mean_error) *mean_error = inliers->empty() ? 0.0 : sum / inliers->size();
}

// Adds the rotation prior's residual (on the rotation half of the left-multiplied tangent,
// whose Jacobian is the identity to first order) to the normal equations.
void AddRotationPrior(const RotationPrior* prior, const geometry::SE3& T, Matrix6d* H,
                      Vector6d* g) {
  if (prior == nullptr || !(prior->weight_px_per_rad > 0)) return;
  const double w = prior->weight_px_per_rad;
  const Eigen::Vector3d r = w * geometry::LogSO3(T.Rotation() * prior->R_cur_prev.conjugate());
  H->bottomRightCorner<3, 3>().diagonal().array() += w * w;
  g->tail<3>() += w * r;
}

}  // namespace

bool StereoReprojectionResidual(const camera::RectifiedStereo& rig, const geometry::SE3& T_cur_prev,
                                const Eigen::Vector3d& p_prev, const StereoObservation& observation,
                                Eigen::Vector4d* residual, Matrix46d* jacobian) {
  return Residual(rig, T_cur_prev, p_prev, observation, residual, jacobian);
}

bool StereoMotionOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (ransac_iterations < 1) {
    msg << "ransac_iterations: must be >= 1, got " << ransac_iterations;
  } else if (!(confidence > 0 && confidence < 1)) {
    msg << "confidence: must be in (0, 1), got " << confidence;
  } else if (!(inlier_threshold_px > 0)) {
    msg << "inlier_threshold_px: must be > 0, got " << inlier_threshold_px;
  } else if (minimal_iterations < 1 || refinement_iterations < 1) {
    msg << "minimal_iterations/refinement_iterations: must be >= 1, got " << minimal_iterations
        << "/" << refinement_iterations;
  } else if (structure_iterations < 1) {
    msg << "structure_iterations: must be >= 1, got " << structure_iterations;
  } else if (min_inliers < 3) {
    msg << "min_inliers: must be >= 3, got " << min_inliers;
  } else {
    return true;
  }
  if (why) *why = msg.str();
  return false;
}

bool RefineStereoMotion(const camera::RectifiedStereo& rig,
                        const std::vector<Eigen::Vector3d>& points_prev,
                        const std::vector<StereoObservation>& observations,
                        const std::vector<int>& indices, int max_iterations,
                        geometry::SE3* T_cur_prev, const RotationPrior* prior) {
  geometry::SE3 T = *T_cur_prev;
  Eigen::Vector4d r;
  Matrix46d J;
  for (int it = 0; it < max_iterations; ++it) {
    Matrix6d H = Matrix6d::Zero();
    Vector6d g = Vector6d::Zero();
    int used = 0;
    for (int i : indices) {
      if (!Residual(rig, T, points_prev[i], observations[i], &r, &J)) continue;
      H.noalias() += J.transpose() * J;
      g.noalias() += J.transpose() * r;
      ++used;
    }
    if (used < 3) return false;
    AddRotationPrior(prior, T, &H, &g);
    const Eigen::LDLT<Matrix6d> ldlt(H);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12)) return false;
    const Vector6d delta = -ldlt.solve(g);
    if (!delta.allFinite()) return false;
    T = geometry::SE3::Exp(delta) * T;
    if (delta.norm() < 1e-10) break;
  }
  if (!IsFinite(T)) return false;
  *T_cur_prev = T;
  return true;
}

bool RefineStereoMotionAndStructure(const camera::RectifiedStereo& rig,
                                    const std::vector<Eigen::Vector3d>& points_prev,
                                    const std::vector<StereoObservation>& observations,
                                    const std::vector<int>& indices, int max_iterations,
                                    geometry::SE3* T_cur_prev, const RotationPrior* prior) {
  const double fx = rig.fx, fy = rig.fy, cx = rig.cx, cy = rig.cy, b = rig.baseline;
  // Per point: the previous observation (u0, v0, d0) (projection of points_prev) and the
  // current estimate q = (u, v, d).
  struct PointState {
    int index;
    Eigen::Vector3d q0, q;
  };
  std::vector<PointState> pts;
  pts.reserve(indices.size());
  for (int i : indices) {
    const Eigen::Vector3d& p = points_prev[i];
    if (!(p.z() > 1e-3)) continue;
    const Eigen::Vector3d q(fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy, fx * b / p.z());
    pts.push_back({i, q, q});
  }
  if (pts.size() < 3) return false;
  auto point_of = [&](const Eigen::Vector3d& q) {
    const double z = fx * b / q.z();
    return Eigen::Vector3d((q.x() - cx) / fx * z, (q.y() - cy) / fy * z, z);
  };
  // Residuals in the previous pair are linear in q: (u - u0, v - v0, (u - d) - (u0 - d0), v - v0).
  Eigen::Matrix<double, 4, 3> Jprev;
  Jprev << 1, 0, 0, 0, 1, 0, 1, 0, -1, 0, 1, 0;
  const Eigen::Matrix3d JprevTJprev = Jprev.transpose() * Jprev;

  geometry::SE3 T = *T_cur_prev;
  std::vector<Eigen::Matrix3d> c_inv(pts.size());
  std::vector<Eigen::Matrix<double, 6, 3>> bmat(pts.size());
  std::vector<Eigen::Vector3d> gq(pts.size());
  std::vector<char> used(pts.size());
  Eigen::Vector4d r;
  Matrix46d J;
  for (int it = 0; it < max_iterations; ++it) {
    Matrix6d S = Matrix6d::Zero();
    Vector6d s = Vector6d::Zero();
    const Eigen::Matrix3d R = T.RotationMatrix();
    int n_used = 0;
    for (size_t k = 0; k < pts.size(); ++k) {
      PointState& ps = pts[k];
      used[k] = 0;
      if (!(ps.q.z() > 1e-3)) continue;
      const Eigen::Vector3d P = point_of(ps.q);
      if (!Residual(rig, T, P, observations[ps.index], &r, &J)) continue;
      Eigen::Matrix3d dP_dq;
      dP_dq << P.z() / fx, 0, -P.x() / ps.q.z(),  //
          0, P.z() / fy, -P.y() / ps.q.z(),       //
          0, 0, -P.z() / ps.q.z();
      const Eigen::Matrix<double, 4, 3> Jq = J.leftCols<3>() * R * dP_dq;
      const Eigen::Vector3d d = ps.q - ps.q0;
      const Eigen::Vector4d r_prev(d.x(), d.y(), d.x() - d.z(), d.y());
      const Eigen::Matrix3d C = JprevTJprev + Jq.transpose() * Jq;
      const Eigen::Matrix3d Ci = C.inverse();
      if (!Ci.allFinite()) continue;
      c_inv[k] = Ci;
      bmat[k] = J.transpose() * Jq;
      gq[k] = Jprev.transpose() * r_prev + Jq.transpose() * r;
      S.noalias() += J.transpose() * J - bmat[k] * Ci * bmat[k].transpose();
      s.noalias() += J.transpose() * r - bmat[k] * (Ci * gq[k]);
      used[k] = 1;
      ++n_used;
    }
    if (n_used < 3) return false;
    AddRotationPrior(prior, T, &S, &s);
    const Eigen::LDLT<Matrix6d> ldlt(S);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12)) return false;
    const Vector6d delta = -ldlt.solve(s);
    if (!delta.allFinite()) return false;
    for (size_t k = 0; k < pts.size(); ++k) {
      if (used[k]) pts[k].q -= c_inv[k] * (gq[k] + bmat[k].transpose() * delta);
    }
    T = geometry::SE3::Exp(delta) * T;
    if (delta.norm() < 1e-9) break;
  }
  if (!IsFinite(T)) return false;
  *T_cur_prev = T;
  return true;
}

StereoMotionEstimate EstimateStereoMotion(const camera::RectifiedStereo& rig,
                                          const std::vector<Eigen::Vector3d>& points_prev,
                                          const std::vector<StereoObservation>& observations,
                                          const StereoMotionOptions& options,
                                          const RotationPrior* prior) {
  MAV_CHECK(points_prev.size() == observations.size())
      << points_prev.size() << " points vs " << observations.size() << " observations";
  StereoMotionEstimate est;
  const int n = static_cast<int>(points_prev.size());
  if (n < std::max(3, options.min_inliers)) {
    est.failure = "too few correspondences: " + std::to_string(n) + " (min " +
                  std::to_string(std::max(3, options.min_inliers)) + ")";
    return est;
  }

  std::mt19937_64 rng(options.seed);
  std::vector<int> sample(3), inliers, best_inliers;
  geometry::SE3 best_T;
  int max_hypotheses = options.ransac_iterations;
  for (int h = 0; h < max_hypotheses; ++h) {
    ++est.hypotheses;
    // Three distinct indices; modulo bias is negligible for n << 2^64.
    sample[0] = static_cast<int>(rng() % n);
    do sample[1] = static_cast<int>(rng() % n);
    while (sample[1] == sample[0]);
    do sample[2] = static_cast<int>(rng() % n);
    while (sample[2] == sample[0] || sample[2] == sample[1]);

    // StereoScan starts every hypothesis from the identity; with a prior, from its rotation.
    geometry::SE3 T;
    if (prior != nullptr) T = geometry::SE3(prior->R_cur_prev, Eigen::Vector3d::Zero());
    if (!RefineStereoMotion(rig, points_prev, observations, sample, options.minimal_iterations, &T,
                            prior)) {
      continue;
    }
    if (prior != nullptr && prior->gate_rad > 0 &&
        geometry::AngleBetween(T.Rotation(), prior->R_cur_prev) > prior->gate_rad) {
      continue;
    }
    CollectInliers(rig, points_prev, observations, T, options.inlier_threshold_px, &inliers,
                   nullptr);
    if (inliers.size() > best_inliers.size()) {
      best_inliers.swap(inliers);
      best_T = T;
      const double w = static_cast<double>(best_inliers.size()) / n;
      const double miss = 1.0 - w * w * w;
      if (miss <= 1e-12) {
        max_hypotheses = h + 1;
      } else {
        const double need = std::log(1.0 - options.confidence) / std::log(miss);
        if (need < max_hypotheses)
          max_hypotheses = std::max(h + 1, static_cast<int>(std::ceil(need)));
      }
    }
  }
  if (static_cast<int>(best_inliers.size()) < options.min_inliers) {
    est.failure = "RANSAC failed: best hypothesis has " + std::to_string(best_inliers.size()) +
                  " inliers of " + std::to_string(n) + " (min " +
                  std::to_string(options.min_inliers) + ")";
    return est;
  }

  // Final refinement on all inliers; re-select inliers with the refined motion and repeat once.
  geometry::SE3 T = best_T;
  for (int round = 0; round < 2; ++round) {
    geometry::SE3 refined = T;
    if (!RefineStereoMotion(rig, points_prev, observations, best_inliers,
                            options.refinement_iterations, &refined, prior)) {
      break;
    }
    CollectInliers(rig, points_prev, observations, refined, options.inlier_threshold_px, &inliers,
                   nullptr);
    if (inliers.size() < best_inliers.size() * 9 / 10) break;  // refinement drifted; keep T
    T = refined;
    best_inliers.swap(inliers);
  }
  if (options.refine_structure && static_cast<int>(best_inliers.size()) >= options.min_inliers) {
    geometry::SE3 joint = T;
    if (RefineStereoMotionAndStructure(rig, points_prev, observations, best_inliers,
                                       options.structure_iterations, &joint, prior)) {
      T = joint;
    }
  }
  if (static_cast<int>(best_inliers.size()) < options.min_inliers || !IsFinite(T)) {
    est.failure = "RANSAC failed: refinement left " + std::to_string(best_inliers.size()) +
                  " inliers (min " + std::to_string(options.min_inliers) + ")";
    return est;
  }
  CollectInliers(rig, points_prev, observations, T, options.inlier_threshold_px, &est.inliers,
                 &est.mean_error_px);
  est.T_cur_prev = T;
  est.vision_R_cur_prev = T.Rotation();
  if (prior != nullptr && prior->weight_px_per_rad > 0) {
    geometry::SE3 vision = T;
    if (RefineStereoMotion(rig, points_prev, observations, est.inliers, 1, &vision)) {
      est.vision_R_cur_prev = vision.Rotation();
    }
  }
  est.ok = static_cast<int>(est.inliers.size()) >= options.min_inliers;
  if (!est.ok) est.failure = "RANSAC failed: too few inliers after refinement";
  return est;
}

}  // namespace mav::localization
