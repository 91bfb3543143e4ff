#include "mav/mapping/octomap_mapper.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <octomap/OcTree.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "mav/common/check.h"
#include "mav/common/time.h"

namespace mav::mapping {
namespace {

// OctoMap addresses 2^16 leaf-sized cells per axis, the key of coordinate c being
// floor(c / resolution) + 2^15.
constexpr int kTreeDepth = 16;
constexpr int64_t kKeyOffset = int64_t{1} << (kTreeDepth - 1);
constexpr int64_t kNumKeys = int64_t{1} << kTreeDepth;

std::string MatTypeName(int type) {
  static const char* kDepths[] = {"8U", "8S", "16U", "16S", "32S", "32F", "64F", "16F"};
  std::ostringstream s;
  s << "CV_" << kDepths[CV_MAT_DEPTH(type)] << "C" << CV_MAT_CN(type);
  return s.str();
}

Status ValidateImage(const cv::Mat& image, const char* name,
                     const camera::RectifiedStereo& stereo) {
  const std::string field(name);
  if (image.empty()) return Status::InvalidArgument(field + ": empty image");
  if (image.type() != CV_8UC1) {
    return Status::InvalidArgument(field + ": expected CV_8UC1 (8-bit grey), got " +
                                   MatTypeName(image.type()));
  }
  if (image.cols != stereo.width || image.rows != stereo.height) {
    return Status::InvalidArgument(field + ": size " + std::to_string(image.cols) + "x" +
                                   std::to_string(image.rows) + " differs from stereo " +
                                   std::to_string(stereo.width) + "x" +
                                   std::to_string(stereo.height));
  }
  return Status::Ok();
}

// An axis-aligned range of leaf keys, [min, max] inclusive per axis.
struct KeyBox {
  Eigen::Matrix<int64_t, 3, 1> min;
  Eigen::Matrix<int64_t, 3, 1> max;
  int64_t Volume() const { return (max - min + decltype(min)::Ones()).prod(); }
};

// Leaf keys whose cells overlap the world box with positive volume (a flat axis takes the layer
// containing it). The epsilon keeps a box edge lying on a cell boundary (up to rounding) from
// reaching into the neighbouring cell.
Result<KeyBox> KeysOverlapping(const Eigen::AlignedBox3d& box, double resolution) {
  if (!box.min().allFinite() || !box.max().allFinite()) {
    return Status::InvalidArgument("box: non-finite corner");
  }
  if ((box.min().array() > box.max().array()).any()) {
    return Status::InvalidArgument("box: min exceeds max (inverted or empty box)");
  }
  constexpr double kEps = 1e-9;
  KeyBox keys;
  for (int a = 0; a < 3; ++a) {
    const double lo = box.min()[a] / resolution;
    const double hi = box.max()[a] / resolution;
    if (std::abs(lo) > kKeyOffset || std::abs(hi) > kKeyOffset) {
      return Status::InvalidArgument("box: outside the octree's addressable range +-" +
                                     std::to_string(kKeyOffset * resolution) + " m");
    }
    int64_t kmin = static_cast<int64_t>(std::floor(lo + kEps));
    int64_t kmax = static_cast<int64_t>(std::ceil(hi - kEps)) - 1;
    if (kmax < kmin) kmin = kmax = static_cast<int64_t>(std::floor(lo));
    keys.min[a] = std::clamp<int64_t>(kmin + kKeyOffset, 0, kNumKeys - 1);
    keys.max[a] = std::clamp<int64_t>(kmax + kKeyOffset, 0, kNumKeys - 1);
  }
  return keys;
}

// Visits the octree nodes overlapping `keys` depth first. `leaf(node, key_min, cells)` is called
// for every leaf overlapping the range (a cube of `cells` leaf cells per edge starting at key_min)
// and returns false to stop the traversal.
template <typename LeafFn>
bool VisitLeaves(const octomap::OcTree& tree, const octomap::OcTreeNode* node,
                 const Eigen::Matrix<int64_t, 3, 1>& key_min, int64_t cells, const KeyBox& keys,
                 LeafFn&& leaf) {
  for (int a = 0; a < 3; ++a) {
    if (key_min[a] > keys.max[a] || key_min[a] + cells - 1 < keys.min[a]) return true;
  }
  if (!tree.nodeHasChildren(node)) return leaf(*node, key_min, cells);
  const int64_t half = cells / 2;
  for (unsigned int i = 0; i < 8; ++i) {
    if (!tree.nodeChildExists(node, i)) continue;
    // OctoMap's child index: bit 0 = upper half in x, bit 1 in y, bit 2 in z.
    const Eigen::Matrix<int64_t, 3, 1> child_min =
        key_min +
        half * Eigen::Matrix<int64_t, 3, 1>((i & 1) ? 1 : 0, (i & 2) ? 1 : 0, (i & 4) ? 1 : 0);
    if (!VisitLeaves(tree, tree.getNodeChild(node, i), child_min, half, keys, leaf)) return false;
  }
  return true;
}

int64_t OverlapVolume(const Eigen::Matrix<int64_t, 3, 1>& key_min, int64_t cells,
                      const KeyBox& keys) {
  int64_t volume = 1;
  for (int a = 0; a < 3; ++a) {
    const int64_t lo = std::max(key_min[a], keys.min[a]);
    const int64_t hi = std::min(key_min[a] + cells - 1, keys.max[a]);
    if (hi < lo) return 0;
    volume *= hi - lo + 1;
  }
  return volume;
}

}  // namespace

bool OctomapMapperOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  auto finite = [](double v) { return std::isfinite(v); };
  if (!finite(resolution) || !(resolution > 0.0) || resolution > 10.0) {
    return fail("resolution: must be in (0, 10] m, got " + std::to_string(resolution));
  }
  if (!finite(min_range_m) || min_range_m < 0.0) {
    return fail("min_range_m: must be finite and >= 0 m, got " + std::to_string(min_range_m));
  }
  if (!finite(max_range_m) || !(max_range_m > min_range_m)) {
    return fail("max_range_m: must be finite and > min_range_m, got " +
                std::to_string(max_range_m));
  }
  if (pixel_stride < 1) {
    return fail("pixel_stride: must be >= 1, got " + std::to_string(pixel_stride));
  }
  if (!finite(prob_hit) || !(prob_hit > 0.5 && prob_hit < 1.0)) {
    return fail("prob_hit: must be in (0.5, 1), got " + std::to_string(prob_hit));
  }
  if (!finite(prob_miss) || !(prob_miss > 0.0 && prob_miss < 0.5)) {
    return fail("prob_miss: must be in (0, 0.5), got " + std::to_string(prob_miss));
  }
  if (!finite(occupancy_threshold) || !(occupancy_threshold > 0.0 && occupancy_threshold < 1.0)) {
    return fail("occupancy_threshold: must be in (0, 1), got " +
                std::to_string(occupancy_threshold));
  }
  if (!finite(clamping_min) || !(clamping_min > 0.0 && clamping_min < occupancy_threshold)) {
    return fail("clamping_min: must be in (0, occupancy_threshold), got " +
                std::to_string(clamping_min));
  }
  if (!finite(clamping_max) || !(clamping_max > occupancy_threshold && clamping_max < 1.0)) {
    return fail("clamping_max: must be in (occupancy_threshold, 1), got " +
                std::to_string(clamping_max));
  }
  if (num_disparities <= 0 || num_disparities % 16 != 0) {
    return fail("num_disparities: must be a positive multiple of 16, got " +
                std::to_string(num_disparities));
  }
  if (block_size % 2 == 0) {
    return fail("block_size: must be odd, got " + std::to_string(block_size));
  }
  if (matcher == StereoMatcherType::kSgbm && (block_size < 1 || block_size > 11)) {
    return fail("block_size: must be in [1, 11] for SGBM, got " + std::to_string(block_size));
  }
  if (matcher == StereoMatcherType::kBm && (block_size < 5 || block_size > 255)) {
    return fail("block_size: must be in [5, 255] for BM, got " + std::to_string(block_size));
  }
  if (uniqueness_ratio < 0 || uniqueness_ratio > 100) {
    return fail("uniqueness_ratio: must be in [0, 100], got " + std::to_string(uniqueness_ratio));
  }
  if (speckle_window_size < 0) {
    return fail("speckle_window_size: must be >= 0, got " + std::to_string(speckle_window_size));
  }
  if (speckle_range < 0) {
    return fail("speckle_range: must be >= 0, got " + std::to_string(speckle_range));
  }
  if (sgbm_p1 < 0 || sgbm_p2 < 0) return fail("sgbm_p1: penalties must be >= 0");
  if ((sgbm_p1 > 0 || sgbm_p2 > 0) && !(sgbm_p2 > sgbm_p1)) {
    return fail("sgbm_p2: must exceed sgbm_p1 when either is set, got p1 " +
                std::to_string(sgbm_p1) + ", p2 " + std::to_string(sgbm_p2));
  }
  if (bm_texture_threshold < 0) {
    return fail("bm_texture_threshold: must be >= 0, got " + std::to_string(bm_texture_threshold));
  }
  return true;
}

double OctomapMapperStats::TotalDisparityMs() const {
  double sum = 0;
  for (const auto& k : keyframes) sum += k.disparity_ms;
  return sum;
}
double OctomapMapperStats::TotalPointsMs() const {
  double sum = 0;
  for (const auto& k : keyframes) sum += k.points_ms;
  return sum;
}
double OctomapMapperStats::TotalInsertionMs() const {
  double sum = 0;
  for (const auto& k : keyframes) sum += k.insertion_ms;
  return sum;
}
double OctomapMapperStats::TotalMs() const {
  return TotalDisparityMs() + TotalPointsMs() + TotalInsertionMs() + finish_ms;
}
int64_t OctomapMapperStats::TotalPoints() const {
  int64_t sum = 0;
  for (const auto& k : keyframes) sum += k.points;
  return sum;
}

const char* BoxOccupancyName(BoxOccupancy occupancy) {
  switch (occupancy) {
    case BoxOccupancy::kFree:
      return "free";
    case BoxOccupancy::kOccupied:
      return "occupied";
    case BoxOccupancy::kUnknown:
      return "unknown";
  }
  return "?";
}

struct OctomapMapper::Impl {
  OctomapMapperOptions options;
  std::unique_ptr<octomap::OcTree> tree;
  cv::Ptr<cv::StereoMatcher> matcher;
  OctomapMapperStats stats;
  cv::Mat disparity;  // CV_16S, 4 fractional bits; reused between keyframes

  void MakeTree() {
    tree = std::make_unique<octomap::OcTree>(options.resolution);
    tree->setProbHit(options.prob_hit);
    tree->setProbMiss(options.prob_miss);
    tree->setClampingThresMin(options.clamping_min);
    tree->setClampingThresMax(options.clamping_max);
    tree->setOccupancyThres(options.occupancy_threshold);
  }

  void MakeMatcher() {
    const OctomapMapperOptions& o = options;
    if (o.matcher == StereoMatcherType::kSgbm) {
      const int area = o.block_size * o.block_size;
      const int p1 = o.sgbm_p1 > 0 ? o.sgbm_p1 : 8 * area;
      const int p2 = o.sgbm_p2 > 0 ? o.sgbm_p2 : 32 * area;
      matcher = cv::StereoSGBM::create(
          /*minDisparity=*/0, o.num_disparities, o.block_size, p1, p2, o.disp12_max_diff,
          /*preFilterCap=*/63, o.uniqueness_ratio, o.speckle_window_size, o.speckle_range,
          o.sgbm_three_way ? cv::StereoSGBM::MODE_SGBM_3WAY : cv::StereoSGBM::MODE_SGBM);
    } else {
      cv::Ptr<cv::StereoBM> bm = cv::StereoBM::create(o.num_disparities, o.block_size);
      bm->setUniquenessRatio(o.uniqueness_ratio);
      bm->setSpeckleWindowSize(o.speckle_window_size);
      bm->setSpeckleRange(o.speckle_range);
      bm->setDisp12MaxDiff(o.disp12_max_diff);
      bm->setTextureThreshold(o.bm_texture_threshold);
      matcher = bm;
    }
  }
};

OctomapMapper::OctomapMapper(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
OctomapMapper::OctomapMapper(OctomapMapper&&) noexcept = default;
OctomapMapper& OctomapMapper::operator=(OctomapMapper&&) noexcept = default;
OctomapMapper::~OctomapMapper() = default;

Result<OctomapMapper> OctomapMapper::Create(const OctomapMapperOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("options." + why);
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->MakeTree();
  impl->MakeMatcher();
  return OctomapMapper(std::move(impl));
}

Status OctomapMapper::InsertKeyframe(const cv::Mat& left, const cv::Mat& right,
                                     const camera::RectifiedStereo& stereo,
                                     const geometry::SE3& T_world_cam) {
  std::string why;
  if (!stereo.IsValid(&why)) return Status::InvalidArgument("stereo: " + why);
  MAV_RETURN_IF_ERROR(ValidateImage(left, "left", stereo));
  MAV_RETURN_IF_ERROR(ValidateImage(right, "right", stereo));
  if (!T_world_cam.Translation().allFinite() || !T_world_cam.Rotation().coeffs().allFinite()) {
    return Status::InvalidArgument("T_world_cam: non-finite pose");
  }
  Impl& s = *impl_;
  const OctomapMapperOptions& o = s.options;
  OctomapKeyframeTiming timing;

  int64_t start = MonotonicNowNs();
  try {
    s.matcher->compute(left, right, s.disparity);
  } catch (const cv::Exception& e) {
    return Status::InvalidArgument(std::string("left/right: stereo matching failed: ") + e.what());
  }
  timing.disparity_ms = MsSince(start);
  MAV_CHECK(s.disparity.type() == CV_16SC1) << "unexpected disparity type";

  start = MonotonicNowNs();
  const Eigen::Matrix3d R_world_cam = T_world_cam.RotationMatrix();
  const Eigen::Vector3d& t_world_cam = T_world_cam.Translation();
  const double fx_b = stereo.fx * stereo.baseline;
  // Disparities are fixed point with 4 fractional bits; skip those giving depths below
  // min_range_m (d > fx b / min_range).
  const double max_disparity =
      o.min_range_m > 0 ? fx_b / o.min_range_m : std::numeric_limits<double>::infinity();
  octomap::Pointcloud cloud;
  cloud.reserve(static_cast<size_t>(left.rows / o.pixel_stride + 1) *
                static_cast<size_t>(left.cols / o.pixel_stride + 1));
  for (int v = 0; v < s.disparity.rows; v += o.pixel_stride) {
    const int16_t* row = s.disparity.ptr<int16_t>(v);
    for (int u = 0; u < s.disparity.cols; u += o.pixel_stride) {
      if (row[u] <= 0) continue;  // invalid (negative) or zero disparity
      const double d = row[u] / 16.0;
      if (d > max_disparity) continue;
      const double z = fx_b / d;
      const Eigen::Vector3d p_cam((u - stereo.cx) * z / stereo.fx, (v - stereo.cy) * z / stereo.fy,
                                  z);
      const Eigen::Vector3d p_world = R_world_cam * p_cam + t_world_cam;
      cloud.push_back(static_cast<float>(p_world.x()), static_cast<float>(p_world.y()),
                      static_cast<float>(p_world.z()));
    }
  }
  timing.points = static_cast<int64_t>(cloud.size());
  timing.points_ms = MsSince(start);

  start = MonotonicNowNs();
  if (cloud.size() > 0) {
    const octomap::point3d origin(static_cast<float>(t_world_cam.x()),
                                  static_cast<float>(t_world_cam.y()),
                                  static_cast<float>(t_world_cam.z()));
    s.tree->insertPointCloud(cloud, origin, o.max_range_m, /*lazy_eval=*/false, o.discretize);
  }
  timing.insertion_ms = MsSince(start);
  s.stats.keyframes.push_back(timing);
  return Status::Ok();
}

const OctomapMapperStats& OctomapMapper::Finish() {
  const int64_t start = MonotonicNowNs();
  impl_->tree->prune();
  impl_->stats.finish_ms += MsSince(start);
  return impl_->stats;
}

const OctomapMapperOptions& OctomapMapper::options() const { return impl_->options; }
const OctomapMapperStats& OctomapMapper::stats() const { return impl_->stats; }
int64_t OctomapMapper::num_keyframes() const {
  return static_cast<int64_t>(impl_->stats.keyframes.size());
}
int64_t OctomapMapper::NumLeaves() const {
  return static_cast<int64_t>(impl_->tree->getNumLeafNodes());
}
const octomap::OcTree& OctomapMapper::tree() const { return *impl_->tree; }

Result<BoxOccupancy> OctomapMapper::Classify(const Eigen::AlignedBox3d& box_world) const {
  const octomap::OcTree& tree = *impl_->tree;
  MAV_ASSIGN_OR_RETURN(const KeyBox keys, KeysOverlapping(box_world, tree.getResolution()));
  const octomap::OcTreeNode* root = tree.getRoot();
  if (root == nullptr) return BoxOccupancy::kUnknown;
  bool occupied = false;
  int64_t known = 0;
  VisitLeaves(tree, root, Eigen::Matrix<int64_t, 3, 1>::Zero(), kNumKeys, keys,
              [&](const octomap::OcTreeNode& leaf, const Eigen::Matrix<int64_t, 3, 1>& key_min,
                  int64_t cells) {
                if (tree.isNodeOccupied(leaf)) {
                  occupied = true;
                  return false;
                }
                known += OverlapVolume(key_min, cells, keys);
                return true;
              });
  if (occupied) return BoxOccupancy::kOccupied;
  return known < keys.Volume() ? BoxOccupancy::kUnknown : BoxOccupancy::kFree;
}

Result<OccupancyGrid> OctomapMapper::ToGrid(const GridGeometry& geometry) const {
  std::string why;
  if (!geometry.IsValid(&why)) return Status::InvalidArgument("geometry: " + why);
  const octomap::OcTree& tree = *impl_->tree;
  const double res = tree.getResolution();
  const Eigen::Vector3d grid_max =
      geometry.origin + geometry.size.cast<double>() * geometry.resolution;
  MAV_ASSIGN_OR_RETURN(const KeyBox keys,
                       KeysOverlapping(Eigen::AlignedBox3d(geometry.origin, grid_max), res));

  // Paint every leaf onto the grid voxels it overlaps: occupied leaves mark voxels occupied,
  // free leaves add the overlapped fraction of the voxel's volume. A voxel is free when free
  // leaves cover all of it, unknown otherwise.
  const int64_t n = geometry.num_voxels();
  std::vector<uint8_t> occupied(n, 0);
  std::vector<double> covered(n, 0.0);
  const double g = geometry.resolution;
  const Eigen::Vector3i& size = geometry.size;
  auto linear = [&](int i, int j, int k) {
    return (static_cast<int64_t>(k) * size.y() + j) * size.x() + i;
  };
  const octomap::OcTreeNode* root = tree.getRoot();
  if (root != nullptr) {
    VisitLeaves(tree, root, Eigen::Matrix<int64_t, 3, 1>::Zero(), kNumKeys, keys,
                [&](const octomap::OcTreeNode& leaf, const Eigen::Matrix<int64_t, 3, 1>& key_min,
                    int64_t cells) {
                  const bool is_occupied = tree.isNodeOccupied(leaf);
                  Eigen::Vector3d lo, hi;
                  Eigen::Vector3i first, last;
                  for (int a = 0; a < 3; ++a) {
                    lo[a] = static_cast<double>(key_min[a] - kKeyOffset) * res;
                    hi[a] = static_cast<double>(key_min[a] + cells - kKeyOffset) * res;
                    constexpr double kEps = 1e-9;
                    first[a] = std::max(
                        0, static_cast<int>(std::floor((lo[a] - geometry.origin[a]) / g + kEps)));
                    last[a] = std::min(
                        size[a] - 1,
                        static_cast<int>(std::ceil((hi[a] - geometry.origin[a]) / g - kEps)) - 1);
                  }
                  for (int k = first.z(); k <= last.z(); ++k) {
                    for (int j = first.y(); j <= last.y(); ++j) {
                      for (int i = first.x(); i <= last.x(); ++i) {
                        const int64_t idx = linear(i, j, k);
                        if (is_occupied) {
                          occupied[idx] = 1;
                          continue;
                        }
                        double fraction = 1.0;
                        const Eigen::Vector3i ijk(i, j, k);
                        for (int a = 0; a < 3; ++a) {
                          const double vlo = geometry.origin[a] + ijk[a] * g;
                          const double overlap = std::min(hi[a], vlo + g) - std::max(lo[a], vlo);
                          fraction *= std::clamp(overlap / g, 0.0, 1.0);
                        }
                        covered[idx] += fraction;
                      }
                    }
                  }
                  return true;
                });
  }
  std::vector<VoxelState> states(n, VoxelState::kUnknown);
  for (int64_t idx = 0; idx < n; ++idx) {
    if (occupied[idx]) {
      states[idx] = VoxelState::kOccupied;
    } else if (covered[idx] >= 1.0 - 1e-6) {
      states[idx] = VoxelState::kFree;
    }
  }
  return OccupancyGrid(geometry, std::move(states));
}

Status OctomapMapper::WriteBinary(const std::string& path) const {
  if (!impl_->tree->writeBinaryConst(path)) {
    return Status::IoError(path + ": cannot write the OctoMap binary file");
  }
  return Status::Ok();
}

void OctomapMapper::Reset() {
  impl_->MakeTree();
  impl_->stats = OctomapMapperStats();
}

}  // namespace mav::mapping
