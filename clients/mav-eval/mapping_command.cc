// mav-eval mapping: runs the sparse multi-view mesher and the OctoMap + dense-stereo baseline on
// the same keyframes of an EuRoC directory with ground-truth poses and occupancy, scores both
// with the paper's collision-check protocol and prints its Tables 3 and 4 (Holzmann et al. 2015)
// with the paper's figures beside ours.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "commands.h"
#include "json.h"
#include "mav/camera/rectifier.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/common/progress.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/eval/trajectory_metrics.h"
#include "mav/mapping/collision_eval.h"
#include "mav/mapping/grid_morphology.h"
#include "mav/mapping/mesh.h"
#include "mav/mapping/observability.h"
#include "mav/mapping/pipeline.h"
#include "mav/sim/occupancy.h"
#include "paper.h"

namespace mav::eval_cli {
namespace {

using dataset::OccupancyGrid;
using dataset::VoxelState;
using mapping::CollisionOutcomes;
using mapping::MappingMethod;

constexpr const char* kCommand = "mav-eval mapping";

int Fail(const std::string& message, int code = 1) {
  std::cerr << kCommand << ": " << message << "\n";
  return code;
}

// Preset name from <data>/ground_truth/scenario.yaml (written by mav-sim), empty if absent.
std::string ReadPreset(const std::string& data) {
  std::ifstream in(data + "/ground_truth/scenario.yaml");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("preset:", 0) == 0) {
      std::string value = line.substr(7);
      value.erase(0, value.find_first_not_of(" \"'"));
      value.erase(value.find_last_not_of(" \"'\r") + 1);
      return value;
    }
  }
  return "";
}

// The evaluation volume: the bounding box (voxel indices, [min, max)) of the ground truth's known
// voxels, i.e. the world's bounds (room interior plus walls, floor and ceiling).
bool KnownRegion(const OccupancyGrid& truth, Eigen::Vector3i* lo, Eigen::Vector3i* hi) {
  *lo = truth.size();
  *hi = Eigen::Vector3i::Zero();
  const Eigen::Vector3i& n = truth.size();
  for (int k = 0; k < n.z(); ++k) {
    for (int j = 0; j < n.y(); ++j) {
      for (int i = 0; i < n.x(); ++i) {
        if (truth[truth.Linear(i, j, k)] == VoxelState::kUnknown) continue;
        *lo = lo->cwiseMin(Eigen::Vector3i(i, j, k));
        *hi = hi->cwiseMax(Eigen::Vector3i(i + 1, j + 1, k + 1));
      }
    }
  }
  return (hi->array() > lo->array()).all();
}

// ---- Figure 2: point cloud + keyframes, mesh, height-coloured occupancy --------------------

// A perspective view of the scene from above and the side, looking at its centre.
struct View3d {
  Eigen::Matrix3d R_cam_world;
  Eigen::Vector3d t_cam_world;
  double f = 0, cx = 0, cy = 0;

  std::optional<cv::Point2f> Project(const Eigen::Vector3d& p, double* depth = nullptr) const {
    const Eigen::Vector3d c = R_cam_world * p + t_cam_world;
    if (c.z() < 0.1) return std::nullopt;
    if (depth) *depth = c.z();
    return cv::Point2f(static_cast<float>(f * c.x() / c.z() + cx),
                       static_cast<float>(f * c.y() / c.z() + cy));
  }
};

View3d MakeView(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int width, int height) {
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double radius = 0.5 * (hi - lo).norm();
  const Eigen::Vector3d dir = Eigen::Vector3d(-0.55, -1.0, 1.25).normalized();
  const Eigen::Vector3d eye = centre + dir * radius * 2.1;
  const Eigen::Vector3d z = (centre - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  View3d v;
  v.R_cam_world.row(0) = x.transpose();
  v.R_cam_world.row(1) = y.transpose();
  v.R_cam_world.row(2) = z.transpose();
  v.t_cam_world = -v.R_cam_world * eye;
  v.f = 0.95 * std::min(width, height) * 2.1 / 2.0 / 1.05;
  v.cx = width / 2.0;
  v.cy = height / 2.0 + 0.04 * height;
  return v;
}

// Blue (low) to red (high), like the paper's occupancy picture.
cv::Scalar HeightColour(double z, double z_lo, double z_hi) {
  const double t = std::clamp((z - z_lo) / std::max(z_hi - z_lo, 1e-6), 0.0, 1.0);
  cv::Mat1b in(1, 1, static_cast<uint8_t>(std::lround(t * 255)));
  cv::Mat3b out;
  cv::applyColorMap(in, out, cv::COLORMAP_JET);
  const cv::Vec3b c = out(0, 0);
  return cv::Scalar(c[0], c[1], c[2]);
}

Status WriteMappingFigure(const std::string& path, const std::string& title,
                          const mapping::MappingOutput& out, const OccupancyGrid& truth) {
  const int w = 640, h = 520;
  cv::Mat canvas(h, 3 * w, CV_8UC3, cv::Scalar(255, 255, 255));
  const Eigen::Vector3d& lo = truth.origin();
  const Eigen::Vector3d hi = lo + truth.size().cast<double>() * truth.resolution();
  double z_cut = lo.z();
  for (const auto& T : out.keyframe_poses) z_cut = std::max(z_cut, T.Translation().z());
  z_cut += 0.3;  // cut away the ceiling so the inside can be seen
  const View3d view = MakeView(lo, hi, w, h);
  cv::Mat panels[3] = {canvas(cv::Rect(0, 0, w, h)), canvas(cv::Rect(w, 0, w, h)),
                       canvas(cv::Rect(2 * w, 0, w, h))};

  // Left: points (height-coloured) and keyframe poses (camera centre + optical axis).
  for (const mapping::MapPoint& p : out.points) {
    if (p.p_world.z() > z_cut) continue;
    if (auto px = view.Project(p.p_world)) {
      cv::circle(panels[0], *px, 1, HeightColour(p.p_world.z(), lo.z(), z_cut), cv::FILLED);
    }
  }
  for (const auto& T : out.keyframe_poses) {
    const Eigen::Vector3d& c = T.Translation();
    const Eigen::Vector3d axis = T * Eigen::Vector3d(0, 0, 0.25);
    auto pc = view.Project(c), pa = view.Project(axis);
    if (pc && pa) cv::line(panels[0], *pc, *pa, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    if (pc) cv::circle(panels[0], *pc, 2, cv::Scalar(0, 0, 200), cv::FILLED, cv::LINE_AA);
  }

  // Middle: the mesh, flat-shaded, far triangles first.
  {
    const mapping::TriangleMesh& mesh = out.meshing.mesh;
    struct Tri {
      double depth;
      std::array<cv::Point, 3> px;
      cv::Scalar colour;
    };
    std::vector<Tri> tris;
    const Eigen::Vector3d light = Eigen::Vector3d(0.3, -0.5, 1.0).normalized();
    for (const Eigen::Vector3i& t : mesh.triangles) {
      const Eigen::Vector3d& a = mesh.vertices[t[0]];
      const Eigen::Vector3d& b = mesh.vertices[t[1]];
      const Eigen::Vector3d& c = mesh.vertices[t[2]];
      if (std::max({a.z(), b.z(), c.z()}) > z_cut) continue;
      Tri tri;
      double da = 0, db = 0, dc = 0;
      auto pa = view.Project(a, &da), pb = view.Project(b, &db), pc = view.Project(c, &dc);
      if (!pa || !pb || !pc) continue;
      tri.depth = (da + db + dc) / 3;
      tri.px = {cv::Point(*pa), cv::Point(*pb), cv::Point(*pc)};
      const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
      const double shade = 0.35 + 0.65 * std::abs(n.dot(light));
      tri.colour = cv::Scalar(190 * shade, 200 * shade, 210 * shade);
      tris.push_back(tri);
    }
    std::sort(tris.begin(), tris.end(),
              [](const Tri& x, const Tri& y) { return x.depth > y.depth; });
    for (const Tri& t : tris) {
      cv::fillConvexPoly(panels[1], t.px.data(), 3, t.colour, cv::LINE_AA);
    }
  }

  // Right: our occupancy grid, occupied voxels with a free or unknown 6-neighbour (the visible
  // shell), height-coloured, far voxels first.
  {
    const OccupancyGrid& g = out.has_sparse_mesh ? out.sparse_mesh_grid : out.octomap_grid;
    const Eigen::Vector3i n = g.size();
    struct Vox {
      double depth;
      cv::Point2f px;
      double z;
    };
    std::vector<Vox> voxels;
    auto occupied = [&](int i, int j, int k) {
      return g.InBounds({i, j, k}) && g[g.Linear(i, j, k)] == VoxelState::kOccupied;
    };
    for (int k = 0; k < n.z(); ++k) {
      for (int j = 0; j < n.y(); ++j) {
        for (int i = 0; i < n.x(); ++i) {
          if (!occupied(i, j, k)) continue;
          const Eigen::Vector3d c = g.CenterOf({i, j, k});
          if (c.z() > z_cut) continue;
          if (occupied(i - 1, j, k) && occupied(i + 1, j, k) && occupied(i, j - 1, k) &&
              occupied(i, j + 1, k) && occupied(i, j, k - 1) && occupied(i, j, k + 1)) {
            continue;
          }
          double depth = 0;
          if (auto px = view.Project(c, &depth)) voxels.push_back({depth, *px, c.z()});
        }
      }
    }
    std::sort(voxels.begin(), voxels.end(),
              [](const Vox& x, const Vox& y) { return x.depth > y.depth; });
    for (const Vox& v : voxels) {
      const float half = static_cast<float>(0.5 * view.f * g.resolution() / v.depth) + 0.5f;
      const cv::Scalar colour = HeightColour(v.z, lo.z(), z_cut);
      cv::rectangle(panels[2], cv::Point2f(v.px.x - half, v.px.y - half),
                    cv::Point2f(v.px.x + half, v.px.y + half), colour, cv::FILLED);
    }
  }

  const char* captions[3] = {"3D points and keyframe poses", "mesh (Delaunay + graph cut)",
                             "occupancy grid (height: blue low, red high)"};
  for (int p = 0; p < 3; ++p) {
    cv::putText(panels[p], captions[p], cv::Point(12, 24), cv::FONT_HERSHEY_SIMPLEX, 0.55,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    if (p > 0)
      cv::line(canvas, cv::Point(p * w, 0), cv::Point(p * w, h), cv::Scalar(200, 200, 200));
  }
  cv::putText(canvas, title, cv::Point(12, h - 12), cv::FONT_HERSHEY_SIMPLEX, 0.5,
              cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
  if (!cv::imwrite(path, canvas)) return Status::IoError(path + ": cannot write PNG");
  return Status::Ok();
}

// ---- Tables ----------------------------------------------------------------------------------

// Where a map's errors are: its wrong voxels in classes (distance to the true surface, height in
// the evaluation volume), and the map's outcomes with one class set right (the truth's state),
// the rest as it was. A voxel is blocked when it is occupied or unknown (both collide).
struct AttributionRow {
  std::string name;  // the JSON key's prefix
  std::string what;
  int64_t voxels = 0;
  CollisionOutcomes outcomes;
};

struct MethodResult {
  MappingMethod method;
  CollisionOutcomes outcomes;
  double runtime_s = 0;
  CollisionOutcomes observable;             // over the observable volume only
  std::vector<AttributionRow> attribution;  // with --error-attribution
};

// MCC, missed and false collisions of `c` as "<prefix>mcc", "<prefix>missed_collision_pct" and
// "<prefix>false_collision_pct" of `group`.
void SetMccMissedFalse(JsonReport* json, const std::string& group, const std::string& prefix,
                       const CollisionOutcomes& c) {
  json->Set(group, prefix + "mcc", c.Mcc());
  json->Set(group, prefix + "missed_collision_pct", c.Percent(c.missed_collision));
  json->Set(group, prefix + "false_collision_pct", c.Percent(c.false_collision));
}

std::string Paper(const std::optional<int>& ds, double v, const char* format) {
  if (!ds) return "-";
  char buf[32];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

void PrintTables(const std::vector<MethodResult>& results, const mapping::MappingOutput& out,
                 const std::string& preset) {
  const std::optional<int> ds = PaperDataSetIndex(preset);
  const PaperMappingRow* paper = ds ? &PaperMapping()[*ds] : nullptr;
  std::printf("\nTable 3: accuracy (MCC) and runtime for the whole data set%s\n",
              ds ? (" (paper: data set " + std::to_string(*ds + 1) + ")").c_str() : "");
  std::printf("%-12s %8s %10s   %s\n", "", "frames", "keyframes", "paper frames / keyframes");
  std::printf(
      "%-12s %8lld %10lld   %s\n", preset.empty() ? "data" : preset.c_str(),
      static_cast<long long>(out.frames), static_cast<long long>(out.keyframes),
      paper ? (std::to_string(paper->frames) + " / " + std::to_string(paper->keyframes)).c_str()
            : "-");
  std::printf("%-12s %8s %8s %11s %9s\n", "method", "MCC", "paper", "runtime", "paper");
  for (const MethodResult& r : results) {
    const bool ours = r.method == MappingMethod::kSparseMesh;
    std::printf(
        "%-12s %8.3f %8s %9.2f s %9s\n", mapping::MappingMethodName(r.method), r.outcomes.Mcc(),
        Paper(ds, paper ? (ours ? paper->mcc_ours : paper->mcc_octomap) : 0, "%.3f").c_str(),
        r.runtime_s,
        Paper(ds, paper ? (ours ? paper->runtime_ours_s : paper->runtime_octomap_s) : 0, "%.0f s")
            .c_str());
  }
  if (results.size() == 2) {
    std::printf(
        "speed-up sparse-mesh over octomap: %.1fx (paper %s); MCC gap %+.3f (paper %s)\n",
        results[1].runtime_s / std::max(results[0].runtime_s, 1e-9),
        Paper(ds, paper ? paper->runtime_octomap_s / paper->runtime_ours_s : 0, "%.1fx").c_str(),
        results[0].outcomes.Mcc() - results[1].outcomes.Mcc(),
        Paper(ds, paper ? paper->mcc_ours - paper->mcc_octomap : 0, "%+.3f").c_str());
  }

  std::printf("\nTable 4: collision-check outcomes (%% of box positions)%s\n",
              ds ? (" (paper: data set " + std::to_string(*ds + 1) + ")").c_str() : "");
  std::printf("%-18s", "outcome");
  for (const MethodResult& r : results) {
    std::printf(" %12s %8s", mapping::MappingMethodName(r.method), "paper");
  }
  std::printf("\n");
  const char* names[4] = {"false-collision", "missed-collision", "correct-collision",
                          "correct-free"};
  for (int o = 0; o < 4; ++o) {
    std::printf("%-18s", names[o]);
    for (const MethodResult& r : results) {
      const CollisionOutcomes& c = r.outcomes;
      const int64_t counts[4] = {c.false_collision, c.missed_collision, c.correct_collision,
                                 c.correct_free};
      const bool ours = r.method == MappingMethod::kSparseMesh;
      const double p =
          paper ? (ours ? paper->outcomes_ours_pct[o] : paper->outcomes_octomap_pct[o]) : 0;
      std::printf(" %12.2f %8s", c.Percent(counts[o]), Paper(ds, p, "%.2f").c_str());
    }
    std::printf("\n");
  }
  if (!results.empty()) {
    std::printf("(%lld box positions; box %s)\n",
                static_cast<long long>(results.front().outcomes.total()),
                "0.6 x 0.6 x 0.2 m = 12 x 12 x 4 voxels, unknown counts as occupied in both");
    std::printf(
        "\nOver the observable volume (%lld box positions whose truth-free voxels some keyframe "
        "could see; information, not a target):\n",
        static_cast<long long>(results.front().observable.total()));
    std::printf("%-12s %8s %10s %10s %10s %10s\n", "method", "MCC", "false-coll", "missed",
                "corr-coll", "corr-free");
    for (const MethodResult& r : results) {
      const CollisionOutcomes& c = r.observable;
      std::printf("%-12s %8.3f %10.2f %10.2f %10.2f %10.2f\n", mapping::MappingMethodName(r.method),
                  c.Mcc(), c.Percent(c.false_collision), c.Percent(c.missed_collision),
                  c.Percent(c.correct_collision), c.Percent(c.correct_free));
    }
  }
}

// The protocol's sensitivity: the ground truth scored against itself with every surface moved by
// one voxel, or with the free space no keyframe could observe made unknown (docs/mapping.md,
// "Protocol sensitivity"). It bounds what a map whose surfaces are right to within one voxel, or
// a map perfect wherever the cameras looked, can score on this data set.
struct SensitivityRow {
  enum class Change { kDilate, kErode, kHideUnobservable };
  const char* name;  // the JSON key's prefix
  const char* what;
  Change change;
  mapping::MorphologyOptions morphology;  // for kDilate and kErode
  CollisionOutcomes outcomes;
};

// One row: the truth dilated (steps > 0) or eroded (steps < 0) by |steps| voxels along `axes`
// ("xyz", "xy", "z").
SensitivityRow Row(const char* name, const char* what, int steps, bool full,
                   const std::string& axes) {
  using Change = SensitivityRow::Change;
  SensitivityRow r{name, what, steps > 0 ? Change::kDilate : Change::kErode, {}, {}};
  r.morphology.steps = std::abs(steps);
  r.morphology.full_neighbourhood = full;
  r.morphology.along_x = axes.find('x') != std::string::npos;
  r.morphology.along_y = axes.find('y') != std::string::npos;
  r.morphology.along_z = axes.find('z') != std::string::npos;
  return r;
}

std::vector<SensitivityRow> SensitivityRows() {
  return {Row("dilated_1", "1 voxel thicker (6 face neighbours)", 1, false, "xyz"),
          Row("dilated_1_full", "1 voxel thicker (26 neighbours)", 1, true, "xyz"),
          Row("dilated_1_xy", "1 voxel thicker in x and y only", 1, false, "xy"),
          Row("dilated_1_z", "1 voxel thicker in z only", 1, false, "z"),
          Row("dilated_2", "2 voxels thicker (6 face neighbours)", 2, false, "xyz"),
          Row("eroded_1", "1 voxel thinner (6 face neighbours)", -1, false, "xyz"),
          {"unobservable_unknown",
           "free space no keyframe could see unknown",
           SensitivityRow::Change::kHideUnobservable,
           {},
           {}}};
}

// The truth as `row` changes it; `observable` is the ObservableVoxels mask of the truth.
Result<OccupancyGrid> ChangedTruth(const OccupancyGrid& truth, const SensitivityRow& row,
                                   const std::vector<uint8_t>& observable) {
  switch (row.change) {
    case SensitivityRow::Change::kDilate:
      return mapping::DilateOccupied(truth, row.morphology);
    case SensitivityRow::Change::kErode:
      return mapping::ErodeOccupied(truth, row.morphology);
    case SensitivityRow::Change::kHideUnobservable:
      break;
  }
  OccupancyGrid hidden = truth;
  for (int64_t v = 0; v < hidden.num_voxels(); ++v) {
    if (hidden[v] == VoxelState::kFree && !observable[static_cast<size_t>(v)]) {
      hidden[v] = VoxelState::kUnknown;
    }
  }
  return hidden;
}

void PrintSensitivity(const std::vector<SensitivityRow>& rows) {
  std::printf(
      "\nProtocol sensitivity: the ground truth scored against itself with its surfaces moved "
      "or its unseen free space unknown (the ceiling of a map that is right to within that "
      "much; information, not a target):\n");
  std::printf("%-42s %8s %10s %10s\n", "truth changed", "MCC", "false-coll", "missed");
  for (const SensitivityRow& r : rows) {
    const CollisionOutcomes& c = r.outcomes;
    std::printf("%-42s %8.3f %10.2f %10.2f\n", r.what, c.Mcc(), c.Percent(c.false_collision),
                c.Percent(c.missed_collision));
  }
}

Result<std::vector<AttributionRow>> AttributeErrors(const OccupancyGrid& truth,
                                                    const OccupancyGrid& map,
                                                    const mapping::CollisionEvalOptions& eval) {
  constexpr int kFar = 3;  // steps; farther wrong voxels form one class
  mapping::MorphologyOptions steps_options;
  steps_options.steps = kFar;
  steps_options.full_neighbourhood = true;
  auto steps = mapping::StepsToOccupied(truth, steps_options);
  if (!steps.ok()) return steps.status();
  // Every wrong voxel once, with its distance class (1..kFar + 1), height quarter (0..3) and kind.
  struct Wrong {
    int64_t v;
    int distance;
    int quarter;
    bool false_block;  // blocked in the map, free in the truth (else: a miss)
  };
  auto blocked = [](VoxelState v) { return v != VoxelState::kFree; };
  const int z_lo = eval.region_min.z(), height = std::max(1, eval.region_max.z() - z_lo);
  const int64_t nxy = static_cast<int64_t>(truth.size().x()) * truth.size().y();
  std::vector<Wrong> wrong;
  for (int64_t v = 0; v < map.num_voxels(); ++v) {
    if (blocked(map[v]) == blocked(truth[v])) continue;
    const int k = static_cast<int>(v / nxy);
    wrong.push_back({v, (*steps)[static_cast<size_t>(v)], std::clamp(4 * (k - z_lo) / height, 0, 3),
                     blocked(map[v])});
  }
  // The classes: a name, a description, and a test of one wrong voxel.
  enum class By { kDistance, kQuarter, kAllBlocked, kAllMissed };
  struct Class {
    std::string name, what;
    By by;
    int value;
  };
  std::vector<Class> classes;
  for (int d = 1; d <= kFar + 1; ++d) {
    classes.push_back(
        {d <= kFar ? "blocked_at_" + std::to_string(d) : "blocked_beyond_" + std::to_string(kFar),
         d <= kFar
             ? "map blocked, truth free: " + std::to_string(d) + (d == 1 ? " step" : " steps") +
                   " from the surface"
             : "map blocked, truth free: > " + std::to_string(kFar) + " steps from the surface",
         By::kDistance, d});
  }
  const char* quarter_names[4] = {"bottom", "second", "third", "top"};
  for (int q = 0; q < 4; ++q) {
    classes.push_back(
        {std::string("blocked_") + quarter_names[q] + "_quarter",
         std::string("map blocked, truth free: ") + quarter_names[q] + " quarter of the height",
         By::kQuarter, q});
  }
  classes.push_back({"blocked_all", "map blocked, truth free: all", By::kAllBlocked, 0});
  classes.push_back({"free_all", "map free, truth blocked (the misses): all", By::kAllMissed, 0});
  auto member = [](const Class& c, const Wrong& w) {
    switch (c.by) {
      case By::kDistance:
        return w.false_block && w.distance == c.value;
      case By::kQuarter:
        return w.false_block && w.quarter == c.value;
      case By::kAllBlocked:
        return w.false_block;
      case By::kAllMissed:
        return !w.false_block;
    }
    return false;
  };

  std::vector<AttributionRow> rows;
  for (const Class& c : classes) {
    OccupancyGrid fixed = map;
    AttributionRow row{c.name, c.what, 0, {}};
    for (const Wrong& w : wrong) {
      if (!member(c, w)) continue;
      fixed[w.v] = truth[w.v];
      ++row.voxels;
    }
    auto outcomes = mapping::EvaluateCollisions(truth, fixed, eval);
    if (!outcomes.ok()) return outcomes.status();
    row.outcomes = *outcomes;
    rows.push_back(std::move(row));
  }
  return rows;
}

void PrintAttribution(const MethodResult& result) {
  std::printf(
      "\nError attribution, %s (MCC %.3f): the map with one class of its wrong voxels set right "
      "(steps with 26 neighbours to the nearest truth-occupied voxel; height within the "
      "evaluation volume):\n",
      mapping::MappingMethodName(result.method), result.outcomes.Mcc());
  std::printf("%-56s %9s %8s %10s %10s\n", "voxels set right", "voxels", "MCC", "false-coll",
              "missed");
  for (const AttributionRow& r : result.attribution) {
    const CollisionOutcomes& c = r.outcomes;
    std::printf("%-56s %9lld %8.3f %10.2f %10.2f\n", r.what.c_str(),
                static_cast<long long>(r.voxels), c.Mcc(), c.Percent(c.false_collision),
                c.Percent(c.missed_collision));
  }
}

}  // namespace

int RunMapping(const std::vector<std::string>& args) {
  std::string data, method_name = "all", out_dir, json_path;
  int64_t max_frames = 0;
  double keyframe_translation_m = mapping::KeyframeOptions().min_translation_m;
  double keyframe_rotation_deg = mapping::KeyframeOptions().min_rotation_rad * 180.0 / M_PI;
  bool no_figure = false;
  mapping::MappingPipelineOptions options;
  FlagParser flags(
      "mav-eval mapping --data DIR [--method sparse-mesh|octomap|all] [--out DIR] [--json FILE] "
      "[--frames N]");
  flags.AddString("data", &data,
                  "EuRoC directory with ground-truth poses and DIR/ground_truth/occupancy.mavocc "
                  "(e.g. from mav-sim generate)");
  flags.AddString("method", &method_name, "sparse-mesh, octomap or all");
  flags.AddString("out", &out_dir,
                  "directory for mesh.ply, the occupancy grids (.bt) and mapping.png "
                  "(default DIR/eval)");
  flags.AddString("json", &json_path, "write every figure as {method: {metric: value}}");
  flags.AddInt64("frames", &max_frames, "use only the first N frames (0 = all)", 0,
                 std::numeric_limits<int64_t>::max());
  flags.AddDouble("keyframe-translation", &keyframe_translation_m,
                  "camera-centre distance to the last keyframe that makes a keyframe [m]");
  flags.AddDouble("keyframe-rotation-deg", &keyframe_rotation_deg,
                  "rotation to the last keyframe that makes a keyframe [deg]");
  flags.AddBool("no-figure", &no_figure, "do not draw mapping.png");
  bool error_attribution = false;
  flags.AddBool("error-attribution", &error_attribution,
                "also print where each map's wrong voxels are and what setting each class right "
                "would score");
  int64_t points_per_keyframe = options.sparse.target_points_per_keyframe;
  flags.AddInt64("points-per-keyframe", &points_per_keyframe,
                 "sparse-mesh: stereo points kept per keyframe (the paper: ~100)", 1, 100000);
  flags.AddDouble("stereo-uniqueness", &options.sparse.stereo_uniqueness_ratio,
                  "sparse-mesh: a stereo match's SAD must be at most this x the second best on "
                  "its row");
  flags.AddDouble("max-depth", &options.sparse.max_depth_m,
                  "sparse-mesh: deepest stereo point [m]");
  int64_t foreground_points = options.sparse.foreground_points_per_keyframe;
  flags.AddInt64("foreground-points", &foreground_points,
                 "sparse-mesh: extra points per keyframe at depth discontinuities (thin "
                 "structures; 0 = the paper's selection)",
                 0, 100000);
  flags.AddDouble("foreground-drop", &options.sparse.foreground_depth_drop,
                  "sparse-mesh: relative depth drop below the neighbourhood median for those");
  flags.AddDouble("mesh-sigma", &options.meshing.sigma,
                  "sparse-mesh: distance behind a point of its inside (sink) cell [m]");
  flags.AddBool("free-requires-traversal", &options.mesh_to_grid.free_requires_traversal,
                "sparse-mesh: outside cells are free only where a line of sight crossed them");
  int64_t carve_radius = options.mesh_to_grid.carve_radius_voxels;
  flags.AddInt64("carve-radius", &carve_radius,
                 "sparse-mesh: radius of the free-space lines of sight [voxels]", 0, 8);
  flags.AddDouble(
      "carve-thick-stop", &options.mesh_to_grid.thick_stop_m,
      "sparse-mesh: the thick part of a line of sight ends this far before its point [m]");
  int64_t safety_margin = options.mesh_to_grid.occupied_margin_voxels;
  flags.AddInt64("safety-margin", &safety_margin,
                 "sparse-mesh: free voxels this close to an occupied one become occupied [voxels]",
                 0, 8);
  int64_t free_near_ray = options.mesh_to_grid.free_near_ray_voxels;
  flags.AddInt64("free-near-ray", &free_near_ray,
                 "sparse-mesh: outside cells are free only this close to a line of sight [voxels; "
                 "-1 = everywhere]",
                 -1, 8);
  flags.AddBool("extra-sight", &options.extra_lines_of_sight,
                "sparse-mesh: free space also from the verified stereo matches not selected as "
                "points");
  int64_t verify_window = options.sparse.verify_window_keyframes;
  flags.AddInt64("verify-window", &verify_window,
                 "sparse-mesh: keyframes that check a single-view point (0 = no verification)", 0,
                 16);
  flags.AddBool("keep-unchecked", &options.sparse.keep_unchecked_points,
                "sparse-mesh: mesh single-view points that no other keyframe could check "
                "(default: from --prefer)");
  flags.AddDouble("mesh-lambda", &options.meshing.lambda_quality,
                  "sparse-mesh: weight of the surface-quality term");
  std::string prefer = "safety";
  flags.AddString(
      "prefer", &prefer,
      "sparse-mesh: safety (fewer missed collisions: weakly supported surfaces, "
      "voxels touching the mesh occupied, only checked points meshed, far single-view points "
      "seen through a surface dropped; the default) "
      "or mcc (the paper's weights: the best MCC)");
  double weak_surface_weight = -1.0;
  flags.AddDouble("weak-surface-weight", &weak_surface_weight,
                  "sparse-mesh: extra weight of a line of sight at a free-space-support jump "
                  "(Jancosek and Pajdla 2011; 0 = off; default: from --prefer)");
  flags.AddDouble("weak-surface-ratio", &options.meshing.weak_surface_ratio,
                  "sparse-mesh: a jump: support behind the point <= this x the support in front");
  flags.AddDouble("weak-surface-depth", &options.meshing.weak_surface_depth,
                  "sparse-mesh: distance behind the point searched for the least support [m]");
  flags.AddDouble("weak-surface-min-support", &options.meshing.weak_surface_min_support,
                  "sparse-mesh: least support in front of the point for a jump [lines of sight]");
  int64_t weak_surface_min_views = options.meshing.weak_surface_min_views;
  flags.AddInt64("weak-surface-min-views", &weak_surface_min_views,
                 "sparse-mesh: least number of observing keyframes of a point for the extra weight",
                 1, 100000);
  flags.AddBool("all-reobservations", &options.sparse.apply_all_reobservations,
                "sparse-mesh: apply every re-observation of an existing point, beyond the target");
  flags.AddBool("occupy-surface-voxels", &options.mesh_to_grid.occupy_surface_voxels,
                "sparse-mesh: voxels touching the mesh are occupied (default: from --prefer)");
  double occlusion_range = -1.0;
  flags.AddDouble("occlusion-check-range", &occlusion_range,
                  "sparse-mesh: single-view points farther than this from their keyframe are "
                  "dropped if seen through a surface of the other points' mesh [m] (0 = off; "
                  "default: from --prefer, 2.5 for safety)");
  flags.AddDouble("occlusion-check-margin", &options.occlusion_check.margin_m,
                  "sparse-mesh: the last part of such a line of sight that is not checked [m]");
  std::vector<std::string> positional;
  bool help = false;
  if (Status s = flags.Parse(args, &positional, &help); !s.ok()) return Fail(s.message(), 2);
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (data.empty() || !positional.empty()) {
    std::cerr << kCommand << ": --data DIR is required\n" << flags.Help();
    return 2;
  }
  std::optional<mapping::MapPreference> preference;
  for (const mapping::MapPreference p :
       {mapping::MapPreference::kSafety, mapping::MapPreference::kMcc}) {
    if (prefer == mapping::MapPreferenceName(p)) preference = p;
  }
  if (!preference) return Fail("--prefer: '" + prefer + "' is not safety or mcc", 2);
  options.meshing.weak_surface_weight = mapping::MeshingOptionsFor(*preference).weak_surface_weight;
  // The preference's grid rule and point choice, unless given.
  if (!flags.WasSet("occupy-surface-voxels")) {
    options.mesh_to_grid.occupy_surface_voxels =
        mapping::MeshToGridOptionsFor(*preference).occupy_surface_voxels;
  }
  if (!flags.WasSet("keep-unchecked")) {
    options.sparse.keep_unchecked_points = mapping::KeepUncheckedPointsFor(*preference);
  }
  options.occlusion_check.enabled = mapping::OcclusionCheckFor(*preference).enabled;
  if (occlusion_range == 0.0) {
    options.occlusion_check.enabled = false;
  } else if (occlusion_range != -1.0) {
    // Any other non-positive value is rejected by OcclusionCheckOptions::IsValid.
    options.occlusion_check.enabled = true;
    options.occlusion_check.min_range_m = occlusion_range;
  }
  // -1 = not given; any other negative value is rejected by MeshingOptions::IsValid.
  if (weak_surface_weight != -1.0) options.meshing.weak_surface_weight = weak_surface_weight;
  options.sparse.target_points_per_keyframe = static_cast<int>(points_per_keyframe);
  options.sparse.foreground_points_per_keyframe = static_cast<int>(foreground_points);
  options.meshing.weak_surface_min_views = static_cast<int>(weak_surface_min_views);
  options.mesh_to_grid.carve_radius_voxels = static_cast<int>(carve_radius);
  options.mesh_to_grid.occupied_margin_voxels = static_cast<int>(safety_margin);
  options.mesh_to_grid.free_near_ray_voxels = static_cast<int>(free_near_ray);
  options.sparse.verify_window_keyframes = static_cast<int>(verify_window);
  if (method_name == "sparse-mesh") {
    options.run_octomap = false;
  } else if (method_name == "octomap") {
    options.run_sparse_mesh = false;
  } else if (method_name != "all") {
    return Fail("--method: unknown method '" + method_name + "' (known: sparse-mesh, octomap, all)",
                2);
  }
  options.keyframes.min_translation_m = keyframe_translation_m;
  options.keyframes.min_rotation_rad = keyframe_rotation_deg * M_PI / 180.0;
  if (std::string why; !options.IsValid(&why)) {
    return Fail("invalid flag value: " + why, 2);
  }
  if (out_dir.empty()) out_dir = data + "/eval";

  auto reader = dataset::EurocReader::Open(data);
  if (!reader.ok()) return Fail(reader.status().message());
  if (Status s = reader->CheckHasFrames(); !s.ok()) return Fail(s.message());
  if (!reader->has_ground_truth()) {
    return Fail(reader->mav0() +
                "/state_groundtruth_estimate0/data.csv: no ground-truth poses (mapping uses "
                "them, as the paper used Vicon poses)");
  }
  const std::string occupancy_path = data + "/ground_truth/occupancy.mavocc";
  Result<OccupancyGrid> truth_read = dataset::ReadMavocc(occupancy_path);
  if (!truth_read.ok()) return Fail(truth_read.status().message());
  const OccupancyGrid truth = std::move(*truth_read);
  auto rectifier = camera::StereoRectifier::Create(reader->calibration());
  if (!rectifier.ok()) return Fail(rectifier.status().message());
  auto pipeline = mapping::MappingPipeline::Create(rectifier->rectified(), options);
  if (!pipeline.ok()) return Fail(pipeline.status().message());

  // Camera poses at the frame times: T_world_cam = T_world_body(t) * T_body_rect0, the ground
  // truth interpolated (slerp + linear) at each frame's time stamp.
  const int64_t n =
      max_frames > 0 ? std::min(max_frames, reader->num_frames()) : reader->num_frames();
  std::vector<dataset::StampedPose> frames, gt;
  for (int64_t i = 0; i < n; ++i) frames.push_back({reader->frame_times()[i], geometry::SE3()});
  for (const auto& s : reader->ground_truth()) gt.push_back({s.t_ns, s.T_world_body});
  auto assoc = eval::AssociateByTime(frames, gt);
  if (!assoc.ok()) return Fail("ground truth at the frame times: " + assoc.status().message());
  const geometry::SE3 T_body_cam = rectifier->T_body_rect0();
  std::vector<int64_t> keyframe_index;
  std::vector<geometry::SE3> keyframe_pose;
  {
    size_t a = 0;
    for (int64_t i = 0; i < n; ++i) {
      if (a >= assoc->t_ns.size() || assoc->t_ns[a] != reader->frame_times()[i]) continue;
      const geometry::SE3 T_world_cam = assoc->ground_truth[a++] * T_body_cam;
      auto is_keyframe = pipeline->ConsiderFrame(T_world_cam);
      if (!is_keyframe.ok())
        return Fail("frame " + std::to_string(i) + ": " + is_keyframe.status().message());
      if (*is_keyframe) {
        keyframe_index.push_back(i);
        keyframe_pose.push_back(T_world_cam);
      }
    }
  }
  if (keyframe_index.empty()) return Fail("no frame lies inside the ground truth's time span");

  // Read and rectify the keyframes (not timed: shared by both methods) two at a time, then map.
  ProgressBar progress("mapping", static_cast<int64_t>(keyframe_index.size()));
  cv::Mat raw[2][2], rect[2][2];
  Status read_status[2];
  for (size_t k = 0; k < keyframe_index.size(); k += 2) {
    const size_t count = std::min<size_t>(2, keyframe_index.size() - k);
    auto load = [&](size_t slot) {
      read_status[slot] =
          reader->ReadStereo(keyframe_index[k + slot], &raw[slot][0], &raw[slot][1]);
      if (read_status[slot].ok()) {
        read_status[slot] =
            rectifier->Rectify(raw[slot][0], raw[slot][1], &rect[slot][0], &rect[slot][1]);
      }
    };
    std::thread second;
    if (count == 2) second = std::thread(load, 1);
    load(0);
    if (second.joinable()) second.join();
    for (size_t slot = 0; slot < count; ++slot) {
      if (!read_status[slot].ok()) return Fail(read_status[slot].message());
      Status s = pipeline->InsertKeyframe(rect[slot][0], rect[slot][1], keyframe_pose[k + slot]);
      if (!s.ok()) {
        return Fail("keyframe at frame " + std::to_string(keyframe_index[k + slot]) + ": " +
                    s.message());
      }
      progress.Update(static_cast<int64_t>(k + slot + 1));
    }
  }
  progress.Finish();
  auto out = pipeline->Finish(truth.geometry());
  if (!out.ok()) return Fail(out.status().message());

  // The paper's protocol over the evaluation volume.
  mapping::CollisionEvalOptions eval_options;  // 0.6 x 0.6 x 0.2 m box, unknown = occupied
  if (!KnownRegion(truth, &eval_options.region_min, &eval_options.region_max)) {
    return Fail(occupancy_path + ": the ground truth has no known voxel");
  }
  // The second evaluation: only the box positions whose free space some keyframe could see.
  auto observable = mapping::ObservableVoxels(truth, keyframe_pose, rectifier->rectified());
  if (!observable.ok()) return Fail(observable.status().message());
  mapping::CollisionEvalOptions observable_options = eval_options;
  observable_options.observable = &*observable;
  std::vector<MethodResult> results;
  JsonReport json;
  for (MappingMethod m : {MappingMethod::kSparseMesh, MappingMethod::kOctomap}) {
    const bool ours = m == MappingMethod::kSparseMesh;
    if (ours ? !out->has_sparse_mesh : !out->has_octomap) continue;
    const OccupancyGrid& grid = ours ? out->sparse_mesh_grid : out->octomap_grid;
    auto outcomes = mapping::EvaluateCollisions(truth, grid, eval_options);
    if (!outcomes.ok()) return Fail(outcomes.status().message());
    auto seen = mapping::EvaluateCollisions(truth, grid, observable_options);
    if (!seen.ok()) return Fail(seen.status().message());
    MethodResult r{m,
                   *outcomes,
                   ours ? out->sparse_mesh_timing.total_s : out->octomap_timing.total_s,
                   *seen,
                   {}};
    const std::string name = mapping::MappingMethodName(m);
    if (error_attribution) {
      auto rows = AttributeErrors(truth, grid, eval_options);
      if (!rows.ok()) return Fail(rows.status().message());
      for (const AttributionRow& row : *rows) {
        const std::string group = "error_attribution_" + name;
        json.Set(group, row.name + "_voxels", static_cast<double>(row.voxels));
        SetMccMissedFalse(&json, group, row.name + "_fixed_", row.outcomes);
      }
      r.attribution = std::move(*rows);
    }
    results.push_back(r);
    // The paper's figures over the whole volume, then the same over the observable volume.
    for (const auto& [prefix, c] :
         {std::pair<std::string, const CollisionOutcomes&>{"", r.outcomes},
          {"observable_", r.observable}}) {
      json.Set(name, prefix + "mcc", c.Mcc());
      json.Set(name, prefix + "correct_collision_pct", c.Percent(c.correct_collision));
      json.Set(name, prefix + "missed_collision_pct", c.Percent(c.missed_collision));
      json.Set(name, prefix + "correct_free_pct", c.Percent(c.correct_free));
      json.Set(name, prefix + "false_collision_pct", c.Percent(c.false_collision));
      json.Set(name, prefix + "box_positions", static_cast<double>(c.total()));
    }
    json.Set(name, "runtime_s", r.runtime_s);
    json.Set(name, "runtime_per_keyframe_ms",
             1e3 * r.runtime_s / static_cast<double>(out->keyframes));
    json.Set(name, "keyframes", static_cast<double>(out->keyframes));
    json.Set(name, "frames", static_cast<double>(out->frames));
    if (ours) {
      const mapping::SparseMeshTiming& t = out->sparse_mesh_timing;
      json.Set(name, "extraction_s", t.extraction_s);
      json.Set(name, "stereo_matching_s", t.matching_s);
      json.Set(name, "merging_s", t.merging_s);
      json.Set(name, "occlusion_check_s", t.occlusion_check_s);
      json.Set(name, "meshing_s", t.meshing_s);
      json.Set(name, "to_grid_s", t.to_grid_s);
      json.Set(name, "points", static_cast<double>(out->points.size()));
      json.Set(name, "lines_of_sight", static_cast<double>(out->lines_of_sight));
      json.Set(name, "observations", static_cast<double>(out->sparse_stats.TotalSelected()));
      json.Set(name, "mesh_triangles", static_cast<double>(out->meshing.mesh.triangles.size()));
      json.Set(name, "inside_cells", static_cast<double>(out->meshing.stats.num_inside_cells));
      json.Set(name, "occlusion_checked_points",
               static_cast<double>(out->occlusion_checked_points));
      json.Set(name, "occluded_points", static_cast<double>(out->occluded_points));
      json.Set(name, "weak_surface_weight", options.meshing.weak_surface_weight);
      json.Set(name, "weak_surface_rays",
               static_cast<double>(out->meshing.stats.weak_surface_rays));
    } else {
      const mapping::OctomapTiming& t = out->octomap_timing;
      json.Set(name, "disparity_s", t.disparity_s);
      json.Set(name, "points_s", t.points_s);
      json.Set(name, "insertion_s", t.insertion_s);
      json.Set(name, "finish_s", t.finish_s);
      json.Set(name, "to_grid_s", t.to_grid_s);
      json.Set(name, "range_points", static_cast<double>(out->octomap_stats.TotalPoints()));
    }
  }
  std::vector<SensitivityRow> sensitivity = SensitivityRows();
  for (SensitivityRow& r : sensitivity) {
    auto changed = ChangedTruth(truth, r, *observable);
    if (!changed.ok()) return Fail(changed.status().message());
    auto outcomes = mapping::EvaluateCollisions(truth, *changed, eval_options);
    if (!outcomes.ok()) return Fail(outcomes.status().message());
    r.outcomes = *outcomes;
    SetMccMissedFalse(&json, "truth_sensitivity", std::string(r.name) + "_", r.outcomes);
  }
  if (results.size() == 2) {
    json.Set("comparison", "speedup", results[1].runtime_s / std::max(results[0].runtime_s, 1e-9));
    json.Set("comparison", "mcc_gap", results[0].outcomes.Mcc() - results[1].outcomes.Mcc());
  }

  const std::string preset = ReadPreset(data);
  std::printf("\ndata: %s (%s), %lld frames, %lld keyframes (>= %.2f m or %.1f deg apart)\n",
              data.c_str(), preset.empty() ? "not a mav-sim preset" : preset.c_str(),
              static_cast<long long>(out->frames), static_cast<long long>(out->keyframes),
              keyframe_translation_m, keyframe_rotation_deg);
  PrintTables(results, *out, preset);
  PrintSensitivity(sensitivity);
  for (const MethodResult& r : results) {
    if (!r.attribution.empty()) PrintAttribution(r);
  }
  if (out->has_sparse_mesh) {
    const mapping::SparseMeshTiming& t = out->sparse_mesh_timing;
    int64_t multi = 0;
    for (const auto& p : out->points) multi += p.keyframes.size() > 1 ? 1 : 0;
    std::printf(
        "\nsparse-mesh stages: features %.2f s, stereo %.2f s, merge %.2f s, occlusion check "
        "%.2f s, meshing %.2f s, to grid %.2f s; %zu points (%lld seen from >1 keyframe), %lld "
        "observations, %zu triangles, %lld lines of sight for the free space; %lld meshing rays "
        "at a support jump; %lld far single-view points checked, %lld seen through a surface\n",
        t.extraction_s, t.matching_s, t.merging_s, t.occlusion_check_s, t.meshing_s, t.to_grid_s,
        out->points.size(), static_cast<long long>(multi),
        static_cast<long long>(out->sparse_stats.TotalSelected()),
        out->meshing.mesh.triangles.size(), static_cast<long long>(out->lines_of_sight),
        static_cast<long long>(out->meshing.stats.weak_surface_rays),
        static_cast<long long>(out->occlusion_checked_points),
        static_cast<long long>(out->occluded_points));
  }
  if (out->has_octomap) {
    const mapping::OctomapTiming& t = out->octomap_timing;
    std::printf(
        "octomap stages: dense stereo %.2f s (%.0f ms per keyframe), points %.2f s, insertion "
        "%.2f s, prune %.2f s, to grid %.2f s\n",
        t.disparity_s, 1e3 * t.disparity_s / static_cast<double>(out->keyframes), t.points_s,
        t.insertion_s, t.finish_s, t.to_grid_s);
  }

  if (Status s = MakeDirectories(out_dir); !s.ok()) return Fail(s.message());
  std::vector<std::string> written;
  auto write = [&](Status s, const std::string& file) {
    if (s.ok()) written.push_back(file);
    return s;
  };
  Status s;
  if (out->has_sparse_mesh) {
    s = write(mapping::WritePly(out_dir + "/mesh.ply", out->meshing.mesh), "mesh.ply");
    if (s.ok()) {
      mapping::TriangleMesh cloud;
      for (const auto& p : out->points) cloud.vertices.push_back(p.p_world);
      s = write(mapping::WritePly(out_dir + "/points.ply", cloud), "points.ply");
    }
    if (s.ok()) {
      s = write(dataset::WriteOctomapBt(out->sparse_mesh_grid, out_dir + "/sparse_mesh.bt"),
                "sparse_mesh.bt");
    }
    if (s.ok()) {
      // The stack's own grid format as well: lossless, same geometry as the ground truth.
      s = write(dataset::WriteMavocc(out->sparse_mesh_grid, out_dir + "/sparse_mesh.mavocc"),
                "sparse_mesh.mavocc");
    }
  }
  if (s.ok() && out->has_octomap) {
    s = write(pipeline->octomap_mapper()->WriteBinary(out_dir + "/octomap.bt"), "octomap.bt");
  }
  if (s.ok() && !no_figure) {
    s = write(WriteMappingFigure(out_dir + "/mapping.png",
                                 "mapping: " + (preset.empty() ? data : preset) + ", " +
                                     std::to_string(out->keyframes) + " keyframes, " +
                                     std::to_string(out->points.size()) + " points",
                                 *out, truth),
              "mapping.png");
  }
  if (s.ok() && !json_path.empty()) s = json.WriteFile(json_path);
  if (!s.ok()) return Fail(s.message());
  std::printf("wrote %s/{", out_dir.c_str());
  for (size_t i = 0; i < written.size(); ++i)
    std::printf("%s%s", i ? ", " : "", written[i].c_str());
  std::printf("}%s\n", json_path.empty() ? "" : (" and " + json_path).c_str());
  return 0;
}

}  // namespace mav::eval_cli
