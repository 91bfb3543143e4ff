#include "mav/eval/mapping_eval.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <thread>
#include <utility>

#include <opencv2/core/mat.hpp>

#include "mav/camera/rectifier.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/eval/paper_figures.h"
#include "mav/eval/trajectory_metrics.h"
#include "mav/mapping/observability.h"

namespace mav::eval {
namespace {

using mapping::CollisionOutcomes;
using mapping::MappingMethod;

// The keyframes the pipeline selects on the ground-truth camera poses at the frame times:
// T_world_cam = T_world_body(t) * T_body_rect0, the ground truth interpolated (slerp + linear)
// at each frame's time stamp.
struct Keyframes {
  std::vector<int64_t> frame;
  std::vector<geometry::SE3> T_world_cam;
};

Result<Keyframes> SelectKeyframes(const dataset::EurocReader& reader, int64_t n,
                                  const geometry::SE3& T_body_cam,
                                  mapping::MappingPipeline* pipeline) {
  std::vector<dataset::StampedPose> frames, gt;
  for (int64_t i = 0; i < n; ++i) frames.push_back({reader.frame_times()[i], geometry::SE3()});
  for (const auto& s : reader.ground_truth()) gt.push_back({s.t_ns, s.T_world_body});
  auto assoc = AssociateByTime(frames, gt);
  if (!assoc.ok()) {
    return Status(assoc.status().code(),
                  "ground truth at the frame times: " + assoc.status().message());
  }
  Keyframes out;
  size_t a = 0;
  for (int64_t i = 0; i < n; ++i) {
    if (a >= assoc->t_ns.size() || assoc->t_ns[a] != reader.frame_times()[i]) continue;
    const geometry::SE3 T_world_cam = assoc->ground_truth[a++] * T_body_cam;
    auto is_keyframe = pipeline->ConsiderFrame(T_world_cam);
    if (!is_keyframe.ok()) {
      return Status(is_keyframe.status().code(),
                    "frame " + std::to_string(i) + ": " + is_keyframe.status().message());
    }
    if (*is_keyframe) {
      out.frame.push_back(i);
      out.T_world_cam.push_back(T_world_cam);
    }
  }
  if (out.frame.empty()) {
    return Status::FailedPrecondition("no frame lies inside the ground truth's time span");
  }
  return out;
}

// Reads and rectifies the keyframes (not timed: shared by both methods) two at a time and
// inserts them into the pipeline.
Status InsertKeyframes(const dataset::EurocReader& reader, const camera::StereoRectifier& rectifier,
                       const Keyframes& keyframes, const StepProgress& progress,
                       mapping::MappingPipeline* pipeline) {
  const int64_t total = static_cast<int64_t>(keyframes.frame.size());
  cv::Mat raw[2][2], rect[2][2];
  Status read_status[2];
  for (size_t k = 0; k < keyframes.frame.size(); k += 2) {
    const size_t count = std::min<size_t>(2, keyframes.frame.size() - k);
    auto load = [&](size_t slot) {
      read_status[slot] =
          reader.ReadStereo(keyframes.frame[k + slot], &raw[slot][0], &raw[slot][1]);
      if (read_status[slot].ok()) {
        read_status[slot] =
            rectifier.Rectify(raw[slot][0], raw[slot][1], &rect[slot][0], &rect[slot][1]);
      }
    };
    std::thread second;
    if (count == 2) second = std::thread(load, 1);
    load(0);
    if (second.joinable()) second.join();
    for (size_t slot = 0; slot < count; ++slot) {
      MAV_RETURN_IF_ERROR(read_status[slot]);
      Status s =
          pipeline->InsertKeyframe(rect[slot][0], rect[slot][1], keyframes.T_world_cam[k + slot]);
      if (!s.ok()) {
        return Status(s.code(), "keyframe at frame " + std::to_string(keyframes.frame[k + slot]) +
                                    ": " + s.message());
      }
      if (progress) progress("mapping", static_cast<int64_t>(k + slot + 1), total);
    }
  }
  return Status::Ok();
}

// Both methods' maps scored over the evaluation volume and the observable volume, with the
// protocol's sensitivity.
Status ScoreMaps(const MappingEvalOptions& options, const std::vector<uint8_t>& observable,
                 const mapping::CollisionEvalOptions& eval, MappingSummary* s) {
  mapping::CollisionEvalOptions observable_eval = eval;
  observable_eval.observable = &observable;
  const mapping::MappingOutput& out = s->output;
  for (MappingMethod m : {MappingMethod::kSparseMesh, MappingMethod::kOctomap}) {
    const bool ours = m == MappingMethod::kSparseMesh;
    if (ours ? !out.has_sparse_mesh : !out.has_octomap) continue;
    const mapping::OccupancyGrid& grid = ours ? out.sparse_mesh_grid : out.octomap_grid;
    MappingMethodResult r;
    r.method = m;
    MAV_ASSIGN_OR_RETURN(r.outcomes, mapping::EvaluateCollisions(s->truth, grid, eval));
    MAV_ASSIGN_OR_RETURN(r.observable,
                         mapping::EvaluateCollisions(s->truth, grid, observable_eval));
    r.runtime_s = ours ? out.sparse_mesh_timing.total_s : out.octomap_timing.total_s;
    if (options.error_attribution) {
      MAV_ASSIGN_OR_RETURN(r.attribution, mapping::AttributeErrors(s->truth, grid, eval));
    }
    s->methods.push_back(std::move(r));
  }
  MAV_ASSIGN_OR_RETURN(s->sensitivity, mapping::ProtocolSensitivity(s->truth, observable, eval));
  return Status::Ok();
}

std::string Paper(const std::optional<int>& ds, double v, const char* format) {
  if (!ds) return "-";
  return FormatLine(format, v);
}

std::string DataSetSuffix(const std::optional<int>& ds) {
  return ds ? " (paper: data set " + std::to_string(*ds + 1) + ")" : std::string();
}

void AddTable3(const MappingSummary& s, const std::optional<int>& ds, Report* report) {
  const PaperMappingRow* paper = ds ? &PaperMapping()[*ds] : nullptr;
  ReportTable& data = report->AddTable(
      "Table 3: accuracy (MCC) and runtime for the whole data set" + DataSetSuffix(ds));
  data.header.push_back(
      FormatLine("%-12s %8s %10s   %s", "", "frames", "keyframes", "paper frames / keyframes"));
  data.rows.push_back(FormatLine(
      "%-12s %8lld %10lld   %s", s.preset.empty() ? "data" : s.preset.c_str(),
      static_cast<long long>(s.output.frames), static_cast<long long>(s.output.keyframes),
      paper ? (std::to_string(paper->frames) + " / " + std::to_string(paper->keyframes)).c_str()
            : "-"));
  ReportTable& t = report->AddTable("", /*blank_line_before=*/false);
  t.header.push_back(
      FormatLine("%-12s %8s %8s %11s %9s", "method", "MCC", "paper", "runtime", "paper"));
  for (const MappingMethodResult& r : s.methods) {
    const bool ours = r.method == MappingMethod::kSparseMesh;
    t.rows.push_back(FormatLine(
        "%-12s %8.3f %8s %9.2f s %9s", mapping::MappingMethodName(r.method), r.outcomes.Mcc(),
        Paper(ds, paper ? (ours ? paper->mcc_ours : paper->mcc_octomap) : 0, "%.3f").c_str(),
        r.runtime_s,
        Paper(ds, paper ? (ours ? paper->runtime_ours_s : paper->runtime_octomap_s) : 0, "%.0f s")
            .c_str()));
  }
  if (s.methods.size() == 2) {
    t.notes.push_back(FormatLine(
        "speed-up sparse-mesh over octomap: %.1fx (paper %s); MCC gap %+.3f (paper %s)",
        s.methods[1].runtime_s / std::max(s.methods[0].runtime_s, 1e-9),
        Paper(ds, paper ? paper->runtime_octomap_s / paper->runtime_ours_s : 0, "%.1fx").c_str(),
        s.methods[0].outcomes.Mcc() - s.methods[1].outcomes.Mcc(),
        Paper(ds, paper ? paper->mcc_ours - paper->mcc_octomap : 0, "%+.3f").c_str()));
  }
}

void AddTable4(const MappingSummary& s, const std::optional<int>& ds, Report* report) {
  const PaperMappingRow* paper = ds ? &PaperMapping()[*ds] : nullptr;
  ReportTable& t = report->AddTable("Table 4: collision-check outcomes (% of box positions)" +
                                    DataSetSuffix(ds));
  std::string header = FormatLine("%-18s", "outcome");
  for (const MappingMethodResult& r : s.methods) {
    header += FormatLine(" %12s %8s", mapping::MappingMethodName(r.method), "paper");
  }
  t.header.push_back(header);
  const char* names[4] = {"false-collision", "missed-collision", "correct-collision",
                          "correct-free"};
  for (int o = 0; o < 4; ++o) {
    std::string row = FormatLine("%-18s", names[o]);
    for (const MappingMethodResult& r : s.methods) {
      const CollisionOutcomes& c = r.outcomes;
      const int64_t counts[4] = {c.false_collision, c.missed_collision, c.correct_collision,
                                 c.correct_free};
      const bool ours = r.method == MappingMethod::kSparseMesh;
      const double p =
          paper ? (ours ? paper->outcomes_ours_pct[o] : paper->outcomes_octomap_pct[o]) : 0;
      row += FormatLine(" %12.2f %8s", c.Percent(counts[o]), Paper(ds, p, "%.2f").c_str());
    }
    t.rows.push_back(row);
  }
  if (s.methods.empty()) return;
  t.notes.push_back(FormatLine(
      "(%lld box positions; box %s)", static_cast<long long>(s.methods.front().outcomes.total()),
      "0.6 x 0.6 x 0.2 m = 12 x 12 x 4 voxels, unknown counts as occupied in both"));
  ReportTable& o = report->AddTable(FormatLine(
      "Over the observable volume (%lld box positions whose truth-free voxels some keyframe "
      "could see; information, not a target):",
      static_cast<long long>(s.methods.front().observable.total())));
  o.header.push_back(FormatLine("%-12s %8s %10s %10s %10s %10s", "method", "MCC", "false-coll",
                                "missed", "corr-coll", "corr-free"));
  for (const MappingMethodResult& r : s.methods) {
    const CollisionOutcomes& c = r.observable;
    o.rows.push_back(FormatLine("%-12s %8.3f %10.2f %10.2f %10.2f %10.2f",
                                mapping::MappingMethodName(r.method), c.Mcc(),
                                c.Percent(c.false_collision), c.Percent(c.missed_collision),
                                c.Percent(c.correct_collision), c.Percent(c.correct_free)));
  }
}

void AddSensitivityAndAttribution(const MappingSummary& s, Report* report) {
  ReportTable& t = report->AddTable(
      "Protocol sensitivity: the ground truth scored against itself with its surfaces moved "
      "or its unseen free space unknown (the ceiling of a map that is right to within that "
      "much; information, not a target):");
  t.header.push_back(
      FormatLine("%-42s %8s %10s %10s", "truth changed", "MCC", "false-coll", "missed"));
  for (const mapping::SensitivityRow& r : s.sensitivity) {
    const CollisionOutcomes& c = r.outcomes;
    t.rows.push_back(FormatLine("%-42s %8.3f %10.2f %10.2f", r.what.c_str(), c.Mcc(),
                                c.Percent(c.false_collision), c.Percent(c.missed_collision)));
  }
  for (const MappingMethodResult& m : s.methods) {
    if (m.attribution.empty()) continue;
    ReportTable& a = report->AddTable(FormatLine(
        "Error attribution, %s (MCC %.3f): the map with one class of its wrong voxels set right "
        "(steps with 26 neighbours to the nearest truth-occupied voxel; height within the "
        "evaluation volume):",
        mapping::MappingMethodName(m.method), m.outcomes.Mcc()));
    a.header.push_back(FormatLine("%-56s %9s %8s %10s %10s", "voxels set right", "voxels", "MCC",
                                  "false-coll", "missed"));
    for (const mapping::AttributionRow& r : m.attribution) {
      const CollisionOutcomes& c = r.outcomes;
      a.rows.push_back(FormatLine("%-56s %9lld %8.3f %10.2f %10.2f", r.what.c_str(),
                                  static_cast<long long>(r.voxels), c.Mcc(),
                                  c.Percent(c.false_collision), c.Percent(c.missed_collision)));
    }
  }
}

void AddStages(const mapping::MappingOutput& out, Report* report) {
  if (out.has_sparse_mesh) {
    const mapping::SparseMeshTiming& t = out.sparse_mesh_timing;
    int64_t multi = 0;
    for (const auto& p : out.points) multi += p.keyframes.size() > 1 ? 1 : 0;
    report->AddTable(FormatLine(
        "sparse-mesh stages: features %.2f s, stereo %.2f s, merge %.2f s, occlusion check "
        "%.2f s, meshing %.2f s, to grid %.2f s; %zu points (%lld seen from >1 keyframe), %lld "
        "observations, %zu triangles, %lld lines of sight for the free space; %lld meshing rays "
        "at a support jump; %lld far single-view points checked, %lld seen through a surface",
        t.extraction_s, t.matching_s, t.merging_s, t.occlusion_check_s, t.meshing_s, t.to_grid_s,
        out.points.size(), static_cast<long long>(multi),
        static_cast<long long>(out.sparse_stats.TotalSelected()), out.meshing.mesh.triangles.size(),
        static_cast<long long>(out.lines_of_sight),
        static_cast<long long>(out.meshing.stats.weak_surface_rays),
        static_cast<long long>(out.occlusion_checked_points),
        static_cast<long long>(out.occluded_points)));
  }
  if (out.has_octomap) {
    const mapping::OctomapTiming& t = out.octomap_timing;
    report->AddTable("", /*blank_line_before=*/false)
        .notes.push_back(
            FormatLine("octomap stages: dense stereo %.2f s (%.0f ms per keyframe), points %.2f s, "
                       "insertion %.2f s, prune %.2f s, to grid %.2f s",
                       t.disparity_s, 1e3 * t.disparity_s / static_cast<double>(out.keyframes),
                       t.points_s, t.insertion_s, t.finish_s, t.to_grid_s));
  }
}

// MCC, missed and false collisions of `c` as "<prefix>mcc", "<prefix>missed_collision_pct" and
// "<prefix>false_collision_pct" of `group`.
void SetMccMissedFalse(JsonReport* json, const std::string& group, const std::string& prefix,
                       const CollisionOutcomes& c) {
  json->Set(group, prefix + "mcc", c.Mcc());
  json->Set(group, prefix + "missed_collision_pct", c.Percent(c.missed_collision));
  json->Set(group, prefix + "false_collision_pct", c.Percent(c.false_collision));
}

void SetStageJson(const MappingSummary& s, const std::string& name, bool ours, JsonReport* json) {
  const mapping::MappingOutput& out = s.output;
  if (ours) {
    const mapping::SparseMeshTiming& t = out.sparse_mesh_timing;
    json->Set(name, "extraction_s", t.extraction_s);
    json->Set(name, "stereo_matching_s", t.matching_s);
    json->Set(name, "merging_s", t.merging_s);
    json->Set(name, "occlusion_check_s", t.occlusion_check_s);
    json->Set(name, "meshing_s", t.meshing_s);
    json->Set(name, "to_grid_s", t.to_grid_s);
    json->Set(name, "points", static_cast<double>(out.points.size()));
    json->Set(name, "lines_of_sight", static_cast<double>(out.lines_of_sight));
    json->Set(name, "observations", static_cast<double>(out.sparse_stats.TotalSelected()));
    json->Set(name, "mesh_triangles", static_cast<double>(out.meshing.mesh.triangles.size()));
    json->Set(name, "inside_cells", static_cast<double>(out.meshing.stats.num_inside_cells));
    json->Set(name, "occlusion_checked_points", static_cast<double>(out.occlusion_checked_points));
    json->Set(name, "occluded_points", static_cast<double>(out.occluded_points));
    json->Set(name, "weak_surface_weight", s.options.meshing.weak_surface_weight);
    json->Set(name, "weak_surface_rays", static_cast<double>(out.meshing.stats.weak_surface_rays));
  } else {
    const mapping::OctomapTiming& t = out.octomap_timing;
    json->Set(name, "disparity_s", t.disparity_s);
    json->Set(name, "points_s", t.points_s);
    json->Set(name, "insertion_s", t.insertion_s);
    json->Set(name, "finish_s", t.finish_s);
    json->Set(name, "to_grid_s", t.to_grid_s);
    json->Set(name, "range_points", static_cast<double>(out.octomap_stats.TotalPoints()));
  }
}

void SetMethodJson(const MappingSummary& s, const MappingMethodResult& r, JsonReport* json) {
  const std::string name = mapping::MappingMethodName(r.method);
  for (const mapping::AttributionRow& row : r.attribution) {
    const std::string group = "error_attribution_" + name;
    json->Set(group, row.name + "_voxels", static_cast<double>(row.voxels));
    SetMccMissedFalse(json, group, row.name + "_fixed_", row.outcomes);
  }
  // The paper's figures over the whole volume, then the same over the observable volume.
  for (const auto& [prefix, c] : {std::pair<std::string, const CollisionOutcomes&>{"", r.outcomes},
                                  {"observable_", r.observable}}) {
    json->Set(name, prefix + "mcc", c.Mcc());
    json->Set(name, prefix + "correct_collision_pct", c.Percent(c.correct_collision));
    json->Set(name, prefix + "missed_collision_pct", c.Percent(c.missed_collision));
    json->Set(name, prefix + "correct_free_pct", c.Percent(c.correct_free));
    json->Set(name, prefix + "false_collision_pct", c.Percent(c.false_collision));
    json->Set(name, prefix + "box_positions", static_cast<double>(c.total()));
  }
  const double keyframes = static_cast<double>(s.output.keyframes);
  json->Set(name, "runtime_s", r.runtime_s);
  json->Set(name, "runtime_per_keyframe_ms", 1e3 * r.runtime_s / keyframes);
  json->Set(name, "keyframes", keyframes);
  json->Set(name, "frames", static_cast<double>(s.output.frames));
  SetStageJson(s, name, r.method == MappingMethod::kSparseMesh, json);
}

void SetJson(const MappingSummary& s, JsonReport* json) {
  for (const MappingMethodResult& r : s.methods) SetMethodJson(s, r, json);
  for (const mapping::SensitivityRow& r : s.sensitivity) {
    SetMccMissedFalse(json, "truth_sensitivity", r.name + "_", r.outcomes);
  }
  if (s.methods.size() == 2) {
    json->Set("comparison", "speedup",
              s.methods[1].runtime_s / std::max(s.methods[0].runtime_s, 1e-9));
    json->Set("comparison", "mcc_gap", s.methods[0].outcomes.Mcc() - s.methods[1].outcomes.Mcc());
  }
}

}  // namespace

Result<MappingSummary> EvaluateMapping(const MappingEvalOptions& options,
                                       const StepProgress& progress) {
  MAV_ASSIGN_OR_RETURN(const dataset::EurocReader reader, dataset::EurocReader::Open(options.data));
  MAV_RETURN_IF_ERROR(reader.CheckHasFrames());
  if (!reader.has_ground_truth()) {
    return Status::FailedPrecondition(
        reader.mav0() +
        "/state_groundtruth_estimate0/data.csv: no ground-truth poses (mapping uses them, as the "
        "paper used Vicon poses)");
  }
  MappingSummary s;
  s.data = options.data;
  s.preset = ReadPresetName(options.data);
  s.options = options.pipeline;
  s.occupancy_path = options.data + "/ground_truth/occupancy.mavocc";
  MAV_ASSIGN_OR_RETURN(s.truth, dataset::ReadMavocc(s.occupancy_path));
  MAV_ASSIGN_OR_RETURN(const camera::StereoRectifier rectifier,
                       camera::StereoRectifier::Create(reader.calibration()));
  MAV_ASSIGN_OR_RETURN(mapping::MappingPipeline pipeline,
                       mapping::MappingPipeline::Create(rectifier.rectified(), options.pipeline));
  const int64_t n = options.max_frames > 0 ? std::min(options.max_frames, reader.num_frames())
                                           : reader.num_frames();
  MAV_ASSIGN_OR_RETURN(const Keyframes keyframes,
                       SelectKeyframes(reader, n, rectifier.T_body_rect0(), &pipeline));
  MAV_RETURN_IF_ERROR(InsertKeyframes(reader, rectifier, keyframes, progress, &pipeline));
  MAV_ASSIGN_OR_RETURN(s.output, pipeline.Finish(s.truth.geometry()));

  // The paper's protocol over the evaluation volume (0.6 x 0.6 x 0.2 m box, unknown = occupied),
  // and over the box positions whose free space some keyframe could see.
  mapping::CollisionEvalOptions eval;
  if (!mapping::KnownRegion(s.truth, &eval.region_min, &eval.region_max)) {
    return Status::InvalidArgument(s.occupancy_path + ": the ground truth has no known voxel");
  }
  MAV_ASSIGN_OR_RETURN(
      const std::vector<uint8_t> observable,
      mapping::ObservableVoxels(s.truth, keyframes.T_world_cam, rectifier.rectified()));
  MAV_RETURN_IF_ERROR(ScoreMaps(options, observable, eval, &s));
  s.pipeline = std::make_shared<const mapping::MappingPipeline>(std::move(pipeline));
  return s;
}

Report MappingReport(const MappingSummary& s) {
  Report report;
  const mapping::KeyframeOptions& k = s.options.keyframes;
  report.AddTable(FormatLine(
      "data: %s (%s), %lld frames, %lld keyframes (>= %.2f m or %.1f deg apart)", s.data.c_str(),
      s.preset.empty() ? "not a mav-sim preset" : s.preset.c_str(),
      static_cast<long long>(s.output.frames), static_cast<long long>(s.output.keyframes),
      k.min_translation_m, k.min_rotation_rad * 180.0 / M_PI));
  const std::optional<int> ds = PaperDataSetIndex(s.preset);
  AddTable3(s, ds, &report);
  AddTable4(s, ds, &report);
  AddSensitivityAndAttribution(s, &report);
  AddStages(s.output, &report);
  SetJson(s, &report.json);
  return report;
}

}  // namespace mav::eval
