#include "mav/mapping/sparse_points.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <tuple>

#include "mav/common/check.h"
#include "mav/common/parallel.h"
#include "mav/common/time.h"
#include "mav/localization/matcher.h"

namespace mav::mapping {
namespace {

using localization::FeatureSet;
using localization::ImageView;

// Best feature of class `c` (lowest descriptor SAD to `d`) inside [u0, u1] x [v0, v1]
// (inclusive), visiting only the grid cells the window overlaps (features are sorted by cell).
// *second_cost receives the second lowest SAD (uint32 max if there is none).
int FindBest(const FeatureSet& fs, const FeatureSet::Class& c, const localization::Descriptor& d,
             int u0, int u1, int v0, int v1, uint32_t* best_cost, uint32_t* second_cost) {
  int best = -1;
  *best_cost = std::numeric_limits<uint32_t>::max();
  *second_cost = std::numeric_limits<uint32_t>::max();
  fs.ForEachInWindow(c, u0, u1, v0, v1, [&](int i) {
    const uint32_t cost = localization::DescriptorSad(d, c.descriptors[i]);
    if (cost < *best_cost) {
      *second_cost = *best_cost;
      *best_cost = cost;
      best = i;
    } else if (cost < *second_cost) {
      *second_cost = cost;
    }
  });
  return best;
}

Status CheckImage(const ImageView& image, const camera::RectifiedStereo& rig, const char* name) {
  std::ostringstream msg;
  if (image.data == nullptr) {
    msg << name << ": empty image";
  } else if (image.width != rig.width || image.height != rig.height) {
    msg << name << ": size " << image.width << "x" << image.height << " differs from the rig "
        << rig.width << "x" << rig.height;
  } else if (image.stride < image.width) {
    msg << name << ": stride " << image.stride << " is smaller than the width " << image.width;
  } else {
    return Status::Ok();
  }
  return Status::InvalidArgument(msg.str());
}

bool FinitePose(const geometry::SE3& T) {
  return T.Translation().allFinite() && T.Rotation().coeffs().allFinite();
}

// Sum of one field over every keyframe's stats.
template <typename Sum, typename Field>
Sum SumOver(const std::vector<SparseKeyframeStats>& keyframes, Field SparseKeyframeStats::*field) {
  Sum sum = 0;
  for (const SparseKeyframeStats& k : keyframes) sum += k.*field;
  return sum;
}

}  // namespace

bool SparsePointsOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  std::string sub;
  if (!features.IsValid(&sub)) {
    msg << "features." << sub;
  } else if (max_sight_lines < 0) {
    msg << "max_sight_lines: must be >= 0, got " << max_sight_lines;
  } else if (!(min_depth_m > 0) || !std::isfinite(min_depth_m)) {
    msg << "min_depth_m: must be finite and > 0 [m], got " << min_depth_m;
  } else if (!(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    msg << "max_depth_m: must be finite and exceed min_depth_m (" << min_depth_m << "), got "
        << max_depth_m;
  } else if (row_tolerance_px < 0 || row_tolerance_px > 8) {
    msg << "row_tolerance_px: must be in [0, 8], got " << row_tolerance_px;
  } else if (!(stereo_uniqueness_ratio > 0 && stereo_uniqueness_ratio <= 1)) {
    msg << "stereo_uniqueness_ratio: must be in (0, 1], got " << stereo_uniqueness_ratio;
  } else if (refine_half_window_px < 1 || refine_half_window_px > 4) {
    msg << "refine_half_window_px: must be in [1, 4], got " << refine_half_window_px;
  } else if (target_points_per_keyframe < 1) {
    msg << "target_points_per_keyframe: must be >= 1, got " << target_points_per_keyframe;
  } else if (bucket_cols < 1 || bucket_rows < 1) {
    msg << "bucket_cols/bucket_rows: must be >= 1, got " << bucket_cols << "x" << bucket_rows;
  } else if (foreground_points_per_keyframe < 0) {
    msg << "foreground_points_per_keyframe: must be >= 0, got " << foreground_points_per_keyframe;
  } else if (!(foreground_depth_drop > 0 && foreground_depth_drop < 1)) {
    msg << "foreground_depth_drop: must be in (0, 1), got " << foreground_depth_drop;
  } else if (!(foreground_radius_px > 0) || !std::isfinite(foreground_radius_px)) {
    msg << "foreground_radius_px: must be finite and > 0 [px], got " << foreground_radius_px;
  } else if (merge_window_keyframes < 0) {
    msg << "merge_window_keyframes: must be >= 0, got " << merge_window_keyframes;
  } else if (!(merge_radius_px > 0) || !std::isfinite(merge_radius_px)) {
    msg << "merge_radius_px: must be finite and > 0 [px], got " << merge_radius_px;
  } else if (merge_max_descriptor_sad < 0) {
    msg << "merge_max_descriptor_sad: must be >= 0, got " << merge_max_descriptor_sad;
  } else if (!(merge_min_depth_tolerance_m >= 0) || !std::isfinite(merge_min_depth_tolerance_m)) {
    msg << "merge_min_depth_tolerance_m: must be finite and >= 0 [m], got "
        << merge_min_depth_tolerance_m;
  } else if (!(merge_relative_depth_tolerance >= 0) ||
             !std::isfinite(merge_relative_depth_tolerance)) {
    msg << "merge_relative_depth_tolerance: must be finite and >= 0, got "
        << merge_relative_depth_tolerance;
  } else if (verify_window_keyframes < 0) {
    msg << "verify_window_keyframes: must be >= 0, got " << verify_window_keyframes;
  } else if (!(verify_radius_px > 0) || !std::isfinite(verify_radius_px)) {
    msg << "verify_radius_px: must be finite and > 0 [px], got " << verify_radius_px;
  } else if (!(verify_disparity_tolerance_px > 0) ||
             !std::isfinite(verify_disparity_tolerance_px)) {
    msg << "verify_disparity_tolerance_px: must be finite and > 0 [px], got "
        << verify_disparity_tolerance_px;
  } else if (verify_max_descriptor_sad < 0) {
    msg << "verify_max_descriptor_sad: must be >= 0, got " << verify_max_descriptor_sad;
  } else {
    return true;
  }
  if (why) *why = msg.str();
  return false;
}

double SparsePointsStats::TotalMs() const {
  return SumOver<double>(keyframes, &SparseKeyframeStats::total_ms);
}
double SparsePointsStats::TotalExtractionMs() const {
  return SumOver<double>(keyframes, &SparseKeyframeStats::extraction_ms);
}
double SparsePointsStats::TotalMatchingMs() const {
  return SumOver<double>(keyframes, &SparseKeyframeStats::matching_ms);
}
double SparsePointsStats::TotalMergingMs() const {
  return SumOver<double>(keyframes, &SparseKeyframeStats::merging_ms);
}
int64_t SparsePointsStats::TotalSelected() const {
  return SumOver<int64_t>(keyframes, &SparseKeyframeStats::selected);
}
int64_t SparsePointsStats::TotalReobserved() const {
  return SumOver<int64_t>(keyframes, &SparseKeyframeStats::reobserved);
}

struct SparsePointCloud::Extractors {
  explicit Extractors(const localization::FeatureOptions& options)
      : left(options), right(options) {}
  localization::FeatureExtractor left, right;
  FeatureSet left_features, right_features;
};

SparsePointCloud::SparsePointCloud(const camera::RectifiedStereo& rig,
                                   const SparsePointsOptions& options)
    : rig_(rig), options_(options), extractors_(std::make_unique<Extractors>(options.features)) {}

SparsePointCloud::SparsePointCloud(SparsePointCloud&&) noexcept = default;
SparsePointCloud& SparsePointCloud::operator=(SparsePointCloud&&) noexcept = default;
SparsePointCloud::~SparsePointCloud() = default;

Result<SparsePointCloud> SparsePointCloud::Create(const camera::RectifiedStereo& rig,
                                                  const SparsePointsOptions& options) {
  std::string why;
  if (!rig.IsValid(&why)) return Status::InvalidArgument("rig: " + why);
  if (!options.IsValid(&why)) return Status::InvalidArgument("options." + why);
  return SparsePointCloud(rig, options);
}

void SparsePointCloud::Reset() {
  tracks_.clear();
  keyframes_.clear();
  T_world_cams_.clear();
  keyframe_tracks_.clear();
  recent_matches_.clear();
  extra_sight_lines_.clear();
  stats_ = SparsePointsStats();
}

bool SparsePointCloud::Accepted(const Track& t, bool keep_unchecked_points) const {
  if (options_.verify_window_keyframes == 0 || t.keyframes.size() >= 2 || t.supported) {
    return true;
  }
  return t.checks == 0 && keep_unchecked_points;
}

std::vector<MapPoint> SparsePointCloud::Points() const {
  return Points(options_.keep_unchecked_points);
}

std::vector<MapPoint> SparsePointCloud::Points(bool keep_unchecked_points) const {
  std::vector<MapPoint> points;
  points.reserve(tracks_.size());
  for (const Track& t : tracks_) {
    if (Accepted(t, keep_unchecked_points)) points.push_back({t.p_world, t.keyframes});
  }
  return points;
}

std::vector<MapPoint> SparsePointCloud::AllPoints() const {
  std::vector<MapPoint> points;
  points.reserve(tracks_.size());
  for (const Track& t : tracks_) points.push_back({t.p_world, t.keyframes});
  return points;
}

std::vector<MapPoint> SparsePointCloud::SightPoints() const {
  std::vector<MapPoint> points = AllPoints();
  points.reserve(points.size() + extra_sight_lines_.size());
  for (const SightLine& line : extra_sight_lines_)
    points.push_back({line.p_world, {line.keyframe}});
  return points;
}

void SparsePointCloud::AddSightLine(const Eigen::Vector3d& p_world, int keyframe) {
  if (static_cast<int64_t>(extra_sight_lines_.size()) >= options_.max_sight_lines) {
    ++stats_.sight_lines_dropped;
    return;
  }
  extra_sight_lines_.push_back({p_world, keyframe});
}

int64_t SparsePointCloud::num_accepted_points() const {
  int64_t n = 0;
  for (const Track& t : tracks_) n += Accepted(t, options_.keep_unchecked_points) ? 1 : 0;
  return n;
}

Result<std::vector<StereoObservation>> SparsePointCloud::MatchStereo(const ImageView& left,
                                                                     const ImageView& right,
                                                                     SparseKeyframeStats* stats) {
  MAV_RETURN_IF_ERROR(CheckImage(left, rig_, "left"));
  MAV_RETURN_IF_ERROR(CheckImage(right, rig_, "right"));
  SparseKeyframeStats local;
  SparseKeyframeStats& s = stats ? *stats : local;

  int64_t start = MonotonicNowNs();
  Extractors& ex = *extractors_;
  if (options_.parallel_extraction) {
    ParallelFor(2, 2, [&](int part, int64_t, int64_t) {
      if (part == 0) {
        ex.left.Extract(left, &ex.left_features);
      } else {
        ex.right.Extract(right, &ex.right_features);
      }
    });
  } else {
    ex.left.Extract(left, &ex.left_features);
    ex.right.Extract(right, &ex.right_features);
  }
  s.extraction_ms = MsSince(start);
  s.left_features = ex.left_features.TotalFeatures();
  s.right_features = ex.right_features.TotalFeatures();

  start = MonotonicNowNs();
  const double fb = rig_.fx * rig_.baseline;
  const int dmin = std::max(1, static_cast<int>(std::floor(fb / options_.max_depth_m)));
  const int dmax = static_cast<int>(std::ceil(fb / options_.min_depth_m));
  const int tol = options_.row_tolerance_px;
  const FeatureSet& lf = ex.left_features;
  const FeatureSet& rf = ex.right_features;

  std::vector<localization::QuadMatch> quads;
  std::vector<int> classes;
  std::vector<const localization::Descriptor*> descriptors;
  std::vector<int> back;  // per right feature: its best left match (-2 = not computed yet)
  for (int k = 0; k < localization::kNumFeatureClasses; ++k) {
    const FeatureSet::Class& lc = lf.features(k);
    const FeatureSet::Class& rc = rf.features(k);
    back.assign(rc.size(), -2);
    for (int i = 0; i < lc.size(); ++i) {
      const int u = lc.u[i], v = lc.v[i];
      uint32_t cost = 0, second = 0;
      const int j =
          FindBest(rf, rc, lc.descriptors[i], u - dmax, u - dmin, v - tol, v + tol, &cost, &second);
      if (j < 0) continue;
      // Uniqueness: an ambiguous match on the row (weak or repetitive texture) is dropped.
      if (second != std::numeric_limits<uint32_t>::max() &&
          static_cast<double>(cost) > options_.stereo_uniqueness_ratio * second) {
        continue;
      }
      if (back[j] == -2) {
        uint32_t back_cost = 0, back_second = 0;
        back[j] = FindBest(lf, lc, rc.descriptors[j], rc.u[j] + dmin, rc.u[j] + dmax, rc.v[j] - tol,
                           rc.v[j] + tol, &back_cost, &back_second);
      }
      if (back[j] != i) continue;  // left-right consistency
      localization::QuadMatch q;
      q.u_prev_left = q.u_cur_left = static_cast<float>(u);
      q.v_prev_left = q.v_cur_left = static_cast<float>(v);
      q.u_prev_right = q.u_cur_right = static_cast<float>(rc.u[j]);
      q.v_prev_right = q.v_cur_right = static_cast<float>(rc.v[j]);
      q.cost = cost;
      q.feature_class = k;
      quads.push_back(q);
      descriptors.push_back(&lc.descriptors[i]);
    }
  }
  if (options_.subpixel) {
    // The VO's refinement works on a pair of stereo pairs; giving it the same pair twice refines
    // the right position against the left reference (the "current" copies refine identically).
    localization::MatcherOptions refine;
    refine.refine_half_window_px = options_.refine_half_window_px;
    localization::RefineMatchesSubpixel(lf, rf, lf, rf, refine, &quads);
  }
  std::vector<StereoObservation> out;
  out.reserve(quads.size());
  for (size_t m = 0; m < quads.size(); ++m) {
    const localization::QuadMatch& q = quads[m];
    const float disparity = q.u_prev_left - q.u_prev_right;
    if (!(disparity > 0)) continue;
    const double depth = fb / disparity;
    if (depth < options_.min_depth_m || depth > options_.max_depth_m) continue;
    StereoObservation o;
    o.u_left = q.u_prev_left;
    o.v_left = q.v_prev_left;
    o.disparity = disparity;
    o.feature_class = q.feature_class;
    o.descriptor = *descriptors[m];
    o.stereo_cost = q.cost;
    out.push_back(o);
  }
  s.stereo_matches = static_cast<int>(out.size());
  s.matching_ms = MsSince(start);
  return out;
}

Result<int> SparsePointCloud::AddKeyframe(const ImageView& left, const ImageView& right,
                                          const geometry::SE3& T_world_cam) {
  if (!FinitePose(T_world_cam)) return Status::InvalidArgument("T_world_cam: non-finite pose");
  const int64_t start = MonotonicNowNs();
  SparseKeyframeStats stats;
  MAV_ASSIGN_OR_RETURN(std::vector<StereoObservation> observations,
                       MatchStereo(left, right, &stats));
  stats.total_ms = MsSince(start);  // the merge adds its own share
  return AddObservationsTimed(observations, T_world_cam, stats);
}

Result<int> SparsePointCloud::AddKeyframeObservations(
    const std::vector<StereoObservation>& observations, const geometry::SE3& T_world_cam) {
  return AddObservationsTimed(observations, T_world_cam, SparseKeyframeStats());
}

Result<int> SparsePointCloud::AddObservationsTimed(
    const std::vector<StereoObservation>& observations, const geometry::SE3& T_world_cam,
    SparseKeyframeStats stats) {
  if (!FinitePose(T_world_cam)) return Status::InvalidArgument("T_world_cam: non-finite pose");
  const double fb = rig_.fx * rig_.baseline;
  for (size_t i = 0; i < observations.size(); ++i) {
    const StereoObservation& o = observations[i];
    const std::string field = "observations[" + std::to_string(i) + "].";
    if (!std::isfinite(o.u_left) || !std::isfinite(o.v_left)) {
      return Status::InvalidArgument(field + "u_left/v_left: non-finite");
    }
    if (!(o.disparity > 0) || !std::isfinite(o.disparity)) {
      return Status::InvalidArgument(field + "disparity: must be finite and > 0, got " +
                                     std::to_string(o.disparity));
    }
    const double depth = fb / o.disparity;
    if (depth < options_.min_depth_m || depth > options_.max_depth_m) {
      return Status::InvalidArgument(field + "disparity: depth " + std::to_string(depth) +
                                     " m outside [min_depth_m, max_depth_m]");
    }
    if (o.feature_class < 0 || o.feature_class >= localization::kNumFeatureClasses) {
      return Status::InvalidArgument(field + "feature_class: must be in [0, 4), got " +
                                     std::to_string(o.feature_class));
    }
  }
  const int64_t start = MonotonicNowNs();
  const int id = static_cast<int>(keyframes_.size());
  const geometry::SE3 T_cam_world = T_world_cam.Inverse();
  const Eigen::Matrix3d R_cw = T_cam_world.RotationMatrix();
  const Eigen::Vector3d& t_cw = T_cam_world.Translation();
  const int n = static_cast<int>(observations.size());

  // Points of the camera frame.
  std::vector<Eigen::Vector3d> p_cam(n);
  for (int i = 0; i < n; ++i) {
    const StereoObservation& o = observations[i];
    const double z = fb / o.disparity;
    p_cam[i] =
        Eigen::Vector3d((o.u_left - rig_.cx) / rig_.fx * z, (o.v_left - rig_.cy) / rig_.fy * z, z);
  }

  // Observations indexed by a grid of cells of about the gates' size.
  const int cell = std::max(
      4, static_cast<int>(
             std::ceil(2 * std::max(options_.merge_radius_px, options_.verify_radius_px))));
  const int cols = rig_.width / cell + 1, rows = rig_.height / cell + 1;
  std::vector<std::vector<int>> grid(static_cast<size_t>(cols) * rows);
  for (int i = 0; i < n; ++i) {
    const int cu = std::clamp(static_cast<int>(observations[i].u_left) / cell, 0, cols - 1);
    const int cv = std::clamp(static_cast<int>(observations[i].v_left) / cell, 0, rows - 1);
    grid[static_cast<size_t>(cv) * cols + cu].push_back(i);
  }
  // Calls f(i) for every observation in the grid cells overlapping the disc (u, v, r).
  auto for_each_near = [&](double u, double v, double r, auto&& f) {
    const int cu0 = std::max(0, static_cast<int>(std::floor((u - r) / cell)));
    const int cu1 = std::min(cols - 1, static_cast<int>(std::floor((u + r) / cell)));
    const int cv0 = std::max(0, static_cast<int>(std::floor((v - r) / cell)));
    const int cv1 = std::min(rows - 1, static_cast<int>(std::floor((v + r) / cell)));
    for (int cv = cv0; cv <= cv1; ++cv) {
      for (int cu = cu0; cu <= cu1; ++cu) {
        for (int i : grid[static_cast<size_t>(cv) * cols + cu]) f(i);
      }
    }
  };
  const Eigen::Matrix3d R_wc = T_world_cam.RotationMatrix();
  const Eigen::Vector3d& t_wc = T_world_cam.Translation();
  std::vector<Eigen::Vector3d> p_world(n);
  for (int i = 0; i < n; ++i) p_world[i] = R_wc * p_cam[i] + t_wc;

  // Verification (step 6): transfer the matches of the recent keyframes into this one and back.
  std::vector<char> supported(n, 0);
  std::vector<int> checks(n, 0);
  if (options_.verify_window_keyframes > 0) {
    const double r = options_.verify_radius_px;
    const double dmin = fb / options_.max_depth_m, dmax = fb / options_.min_depth_m;
    // Pixel and disparity of a camera-frame point, false if outside the image or depth range.
    auto project = [&](const Eigen::Vector3d& pc, double* u, double* v, double* d) {
      if (!(pc.z() > 0)) return false;
      *d = fb / pc.z();
      if (*d < dmin || *d > dmax) return false;
      *u = rig_.fx * pc.x() / pc.z() + rig_.cx;
      *v = rig_.fy * pc.y() / pc.z() + rig_.cy;
      return *u >= 0 && *v >= 0 && *u < rig_.width && *v < rig_.height;
    };
    for (KeyframeMatches& km : recent_matches_) {
      std::vector<char>& km_in_sight = km.in_sight_lines;
      const Eigen::Matrix3d R = km.T_cam_world.RotationMatrix();
      const Eigen::Vector3d t = km.T_cam_world.Translation();
      double u = 0, v = 0, d = 0;
      for (int i = 0; i < n; ++i) checks[i] += project(R * p_world[i] + t, &u, &v, &d) ? 1 : 0;
      for (size_t j = 0; j < km.p_world.size(); ++j) {
        if (!project(R_cw * km.p_world[j] + t_cw, &u, &v, &d)) continue;
        const int track = km.track[j];
        if (track >= 0) ++tracks_[track].checks;
        for_each_near(u, v, r, [&](int i) {
          const StereoObservation& o = observations[i];
          if (o.feature_class != km.feature_class[j]) return;
          const double du = o.u_left - u, dv = o.v_left - v;
          if (du * du + dv * dv > r * r) return;
          if (std::abs(o.disparity - d) > options_.verify_disparity_tolerance_px) return;
          if (localization::DescriptorSad(o.descriptor, km.descriptors[j]) >
              static_cast<uint32_t>(options_.verify_max_descriptor_sad)) {
            return;
          }
          supported[i] = 1;
          if (track >= 0) {
            tracks_[track].supported = true;
          } else if (!km_in_sight[j]) {
            km_in_sight[j] = 1;
            AddSightLine(km.p_world[j], km.id);
          }
        });
      }
    }
  }
  for (int i = 0; i < n; ++i) stats.supported += supported[i];

  // Re-observation candidates: (SAD, track, observation) triples that pass every gate.
  std::vector<int> match_of_observation(n, -1);
  if (options_.merge_window_keyframes > 0 && n > 0 && !tracks_.empty()) {
    const double r = options_.merge_radius_px;
    std::vector<int> candidates;
    const int first_kf = std::max(0, id - options_.merge_window_keyframes);
    for (int kf = first_kf; kf < id; ++kf) {
      candidates.insert(candidates.end(), keyframe_tracks_[kf].begin(), keyframe_tracks_[kf].end());
    }
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());

    std::vector<std::tuple<uint32_t, int, int>> pairs;
    for (int t : candidates) {
      const Track& track = tracks_[t];
      const Eigen::Vector3d pc = R_cw * track.p_world + t_cw;
      if (pc.z() < 0.5 * options_.min_depth_m) continue;
      const double u = rig_.fx * pc.x() / pc.z() + rig_.cx;
      const double v = rig_.fy * pc.y() / pc.z() + rig_.cy;
      if (u < -r || v < -r || u > rig_.width + r || v > rig_.height + r) continue;
      const double depth_tol = std::max(options_.merge_min_depth_tolerance_m,
                                        options_.merge_relative_depth_tolerance * pc.z());
      for_each_near(u, v, r, [&](int i) {
        const StereoObservation& o = observations[i];
        if (o.feature_class != track.feature_class) return;
        const double du = o.u_left - u, dv = o.v_left - v;
        if (du * du + dv * dv > r * r) return;
        if (std::abs(p_cam[i].z() - pc.z()) > depth_tol) return;
        const uint32_t sad = localization::DescriptorSad(o.descriptor, track.descriptor);
        if (sad > static_cast<uint32_t>(options_.merge_max_descriptor_sad)) return;
        pairs.emplace_back(sad, t, i);
      });
    }
    std::sort(pairs.begin(), pairs.end());
    std::vector<char> track_taken;  // indexed by position in `candidates`
    track_taken.assign(candidates.size(), 0);
    for (const auto& [sad, t, i] : pairs) {
      const size_t ct = static_cast<size_t>(
          std::lower_bound(candidates.begin(), candidates.end(), t) - candidates.begin());
      if (track_taken[ct] || match_of_observation[i] >= 0) continue;
      track_taken[ct] = 1;
      match_of_observation[i] = t;
    }
  }
  for (int i = 0; i < n; ++i) stats.reobservable += match_of_observation[i] >= 0 ? 1 : 0;

  // Selection: round-robin over buckets; inside a bucket re-observations first, then stereo cost.
  const int bc = options_.bucket_cols, br = options_.bucket_rows;
  std::vector<std::vector<int>> buckets(static_cast<size_t>(bc) * br);
  for (int i = 0; i < n; ++i) {
    const int cu =
        std::clamp(static_cast<int>(observations[i].u_left * bc / rig_.width), 0, bc - 1);
    const int cv =
        std::clamp(static_cast<int>(observations[i].v_left * br / rig_.height), 0, br - 1);
    buckets[static_cast<size_t>(cv) * bc + cu].push_back(i);
  }
  for (auto& b : buckets) {
    std::sort(b.begin(), b.end(), [&](int a, int c) {
      const bool ra = match_of_observation[a] >= 0, rc = match_of_observation[c] >= 0;
      if (ra != rc) return ra;
      if (supported[a] != supported[c]) return supported[a] > supported[c];
      if (observations[a].stereo_cost != observations[c].stereo_cost) {
        return observations[a].stereo_cost < observations[c].stereo_cost;
      }
      return a < c;
    });
  }
  std::vector<int> selected;
  const int target = std::min(n, options_.target_points_per_keyframe);
  for (size_t rank = 0; static_cast<int>(selected.size()) < target; ++rank) {
    for (const auto& b : buckets) {
      if (rank < b.size()) selected.push_back(b[rank]);
      if (static_cast<int>(selected.size()) >= target) break;
    }
  }
  if (options_.foreground_points_per_keyframe > 0) {
    std::vector<char> is_selected(n, 0);
    for (int i : selected) is_selected[i] = 1;
    const double r2 = options_.foreground_radius_px * options_.foreground_radius_px;
    std::vector<std::pair<double, int>> drops;  // (depth / neighbourhood median, match)
    std::vector<double> near;
    for (int i = 0; i < n; ++i) {
      if (is_selected[i] || (match_of_observation[i] < 0 && !supported[i])) continue;
      near.clear();
      for (int j = 0; j < n; ++j) {
        const double du = observations[j].u_left - observations[i].u_left;
        const double dv = observations[j].v_left - observations[i].v_left;
        if (j != i && du * du + dv * dv <= r2) near.push_back(p_cam[j].z());
      }
      if (near.size() < 4) continue;
      std::nth_element(near.begin(), near.begin() + near.size() / 2, near.end());
      const double ratio = p_cam[i].z() / near[near.size() / 2];
      if (ratio <= 1.0 - options_.foreground_depth_drop) drops.emplace_back(ratio, i);
    }
    std::sort(drops.begin(), drops.end());
    const size_t extra =
        std::min(drops.size(), static_cast<size_t>(options_.foreground_points_per_keyframe));
    for (size_t k = 0; k < extra; ++k) selected.push_back(drops[k].second);
    stats.foreground += static_cast<int>(extra);
  }
  if (options_.apply_all_reobservations) {
    std::vector<char> is_selected(n, 0);
    for (int i : selected) is_selected[i] = 1;
    for (int i = 0; i < n; ++i) {
      if (!is_selected[i] && match_of_observation[i] >= 0) selected.push_back(i);
    }
  }

  // Apply: new points and merged observations.
  keyframes_.push_back({id, T_world_cam.Translation()});
  T_world_cams_.push_back(T_world_cam);
  keyframe_tracks_.emplace_back();
  std::vector<int>& seen = keyframe_tracks_.back();
  std::vector<int> track_of_observation(n, -1);
  for (int i : selected) {
    const StereoObservation& o = observations[i];
    const double z = p_cam[i].z();
    const double w = 1.0 / (z * z * z * z);
    const int t = match_of_observation[i];
    if (t >= 0) {
      Track& track = tracks_[t];
      track.p_world = (track.p_world * track.weight + p_world[i] * w) / (track.weight + w);
      track.weight += w;
      track.keyframes.push_back(id);
      track.descriptor = o.descriptor;
      seen.push_back(t);
      track_of_observation[i] = t;
      ++stats.reobserved;
    } else {
      Track track;
      track.p_world = p_world[i];
      track.weight = w;
      track.checks = checks[i];
      track.supported = supported[i] != 0;
      track.keyframes = {id};
      track.descriptor = o.descriptor;
      track.feature_class = o.feature_class;
      seen.push_back(static_cast<int>(tracks_.size()));
      track_of_observation[i] = static_cast<int>(tracks_.size());
      tracks_.push_back(std::move(track));
      ++stats.new_points;
    }
  }
  if (options_.verify_window_keyframes > 0) {
    if (static_cast<int>(recent_matches_.size()) >= options_.verify_window_keyframes) {
      recent_matches_.erase(recent_matches_.begin());
    }
    for (int i = 0; i < n; ++i) {
      if (supported[i] && track_of_observation[i] < 0) {
        AddSightLine(p_world[i], id);
      }
    }
    KeyframeMatches km;
    km.id = id;
    km.T_cam_world = T_cam_world;
    km.p_world = std::move(p_world);
    km.feature_class.reserve(n);
    km.descriptors.reserve(n);
    for (const StereoObservation& o : observations) {
      km.feature_class.push_back(o.feature_class);
      km.descriptors.push_back(o.descriptor);
    }
    km.in_sight_lines.assign(n, 0);
    for (int i = 0; i < n; ++i) km.in_sight_lines[i] = supported[i] && track_of_observation[i] < 0;
    km.track = std::move(track_of_observation);
    recent_matches_.push_back(std::move(km));
  }
  stats.id = id;
  stats.selected = static_cast<int>(selected.size());
  stats.merging_ms = MsSince(start);
  stats.total_ms += stats.merging_ms;
  stats_.keyframes.push_back(stats);
  return id;
}

}  // namespace mav::mapping
