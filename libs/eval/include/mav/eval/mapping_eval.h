#pragma once
// The mapping evaluation of mav-eval (the paper's Tables 3 and 4, Holzmann et al. 2015): the
// sparse multi-view mesher and the OctoMap + dense-stereo baseline (mapping::MappingPipeline, the
// code the mapping service runs) on the same keyframes of an EuRoC directory with ground-truth
// poses and occupancy, scored with the paper's collision-check protocol over the evaluation
// volume and over the observable volume, with the protocol's sensitivity and, optionally, each
// map's error attribution (mav/mapping/collision_analysis.h).

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/eval/report.h"
#include "mav/mapping/collision_analysis.h"
#include "mav/mapping/collision_eval.h"
#include "mav/mapping/pipeline.h"

namespace mav::eval {

struct MappingEvalOptions {
  std::string data;  // EuRoC directory with ground-truth poses and ground_truth/occupancy.mavocc
  int64_t max_frames = 0;                    // the first N frames; 0 = all
  mapping::MappingPipelineOptions pipeline;  // which methods run, keyframes, every stage
  bool error_attribution = false;            // AttributeErrors of every map
};

struct MappingMethodResult {
  mapping::MappingMethod method = mapping::MappingMethod::kSparseMesh;
  mapping::CollisionOutcomes outcomes;               // over the evaluation volume (KnownRegion)
  mapping::CollisionOutcomes observable;             // over the observable volume only
  double runtime_s = 0;                              // the method over the whole data set
  std::vector<mapping::AttributionRow> attribution;  // with error_attribution
};

struct MappingSummary {
  std::string data;
  std::string preset;  // ReadPresetName; empty: not a mav-sim preset
  mapping::MappingPipelineOptions options;
  std::string occupancy_path;  // the ground truth's file
  mapping::OccupancyGrid truth;
  // The pipeline after Finish (its octree for octomap.bt) and its output on the truth's grid.
  std::shared_ptr<const mapping::MappingPipeline> pipeline;
  mapping::MappingOutput output;
  std::vector<MappingMethodResult> methods;  // sparse-mesh first
  std::vector<mapping::SensitivityRow> sensitivity;
};

// Selects keyframes on the ground-truth camera poses at the frame times, reads and rectifies
// them (two at a time), maps them with every method and scores the maps. Errors name the file,
// the frame or the keyframe ("keyframe at frame 12: ..."); a data set without ground-truth poses
// is FailedPrecondition. `options.pipeline` must be valid (MappingPipelineOptions::IsValid).
Result<MappingSummary> EvaluateMapping(const MappingEvalOptions& options,
                                       const StepProgress& progress = {});

// Tables 3 and 4 with the paper's figures beside ours, the observable volume, the protocol
// sensitivity, the error attribution, the stages of both methods; the JSON {method: {metric:
// value}}, "truth_sensitivity", "error_attribution_<method>" and "comparison".
Report MappingReport(const MappingSummary& summary);

}  // namespace mav::eval
