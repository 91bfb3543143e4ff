// mav-eval localization: runs the stereo odometry methods over an EuRoC directory and prints the
// paper's Tables 1 and 2 (Holzmann et al. 2015) with its figures beside ours.

#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "clients/plot/plot.h"
#include "commands.h"
#include "json.h"
#include "mav/camera/rectifier.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/common/progress.h"
#include "mav/common/stats.h"
#include "mav/common/time.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/trajectory_io.h"
#include "mav/eval/trajectory_metrics.h"
#include "mav/localization/odometry.h"
#include "mav/localization/rig_odometry.h"
#include "paper.h"

namespace mav::eval_cli {
namespace {

using localization::Method;

struct MethodRun {
  Method method;
  std::unique_ptr<localization::RigOdometry> odometry;  // the localization service's code path
  std::vector<dataset::StampedPose> T_world_body;  // estimate in the ground truth's world frame
  std::vector<double> runtime_ms;                  // wall time of Process()
  std::ostringstream frames_csv;                   // one line per frame (<method>_frames.csv)
  int lost_frames = 0;
  int degraded_frames = 0;
  std::string first_lost_reason;
  std::string first_degraded_reason;
};

struct MethodMetrics {
  eval::RelativeError relative;
  double ate_rmse_m = 0;
  double end_point_error_m = 0;
  double path_length_m = 0;
  RuntimeStats runtime;
};

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

std::string Fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

void PrintTables(const std::vector<MethodRun>& runs, const std::vector<MethodMetrics>& metrics,
                 const std::string& preset) {
  const std::optional<int> ds = PaperDataSetIndex(preset);
  const auto paper_row = [](Method m) -> const PaperLocalizationRow* {
    for (const auto& row : PaperLocalization()) {
      if (std::string(row.method) == localization::MethodName(m)) return &row;
    }
    return nullptr;
  };
  std::printf("\nTable 1: runtime per frame and average relative translational error%s\n",
              ds ? (" (paper: data set " + std::to_string(*ds + 1) + ")").c_str() : "");
  std::printf("%-16s %10s %10s %10s %10s %9s %9s %9s %6s\n", "method", "runtime", "p95", "paper",
              "error", "paper", "ATE", "end-pt", "lost");
  for (size_t i = 0; i < runs.size(); ++i) {
    const MethodMetrics& m = metrics[i];
    const PaperLocalizationRow* p = paper_row(runs[i].method);
    std::printf("%-16s %8.1fms %8.1fms %10s %10s %9s %8.3fm %8.3fm %6d\n",
                localization::MethodName(runs[i].method), m.runtime.mean_ms, m.runtime.p95_ms,
                ds && p ? Fmt("%.0fms", p->runtime_ms[*ds]).c_str() : "-",
                m.relative.average_pct ? Fmt("%.2f%%", *m.relative.average_pct).c_str() : "n/a",
                ds && p ? Fmt("%.1f%%", p->error_pct[*ds]).c_str() : "-", m.ate_rmse_m,
                m.end_point_error_m, runs[i].lost_frames);
  }
  std::printf("\nTable 2: relative translational error (%%) per segment length%s\n",
              ds == 2 ? " (paper: data set 3)" : "");
  std::printf("%-22s", "method");
  for (double l : eval::PaperSegmentLengths()) std::printf(" %6.0fm", l);
  std::printf("\n");
  for (size_t i = 0; i < runs.size(); ++i) {
    std::printf("%-22s", localization::MethodName(runs[i].method));
    for (const auto& e : metrics[i].relative.per_length) {
      if (e.segments > 0) {
        std::printf(" %7.2f", e.translation_error_pct);
      } else {
        std::printf(" %7s", "-");
      }
    }
    std::printf("\n");
    const PaperLocalizationRow* p = paper_row(runs[i].method);
    if (ds == 2 && p) {
      std::printf("%-22s", (std::string("  paper ") + p->method).c_str());
      for (double v : p->ds3_error_per_length_pct) std::printf(" %7.1f", v);
      std::printf("\n");
    }
  }
  std::printf(
      "(segments start every 10 frames; '-' = the trajectory is shorter than that length)\n");
}

}  // namespace

int RunLocalization(const std::vector<std::string>& args) {
  std::string data, method_name = "all", out_dir, json_path;
  int64_t max_frames = 0, step = 10;
  bool use_gyro = true, consistency_check = true;
  double gyro_bias_gain = localization::RigOdometryOptions().gyro_bias_gain;
  FlagParser flags(
      "mav-eval localization --data DIR [--method sparse-pixel|sparse-subpixel|dense|all] "
      "[--out DIR] [--json FILE]");
  flags.AddString("data", &data, "EuRoC directory with ground truth (e.g. from mav-sim generate)");
  flags.AddString("method", &method_name, "sparse-pixel, sparse-subpixel, dense or all");
  flags.AddString("out", &out_dir,
                  "directory for TUM trajectories and the plot (default DIR/eval)");
  flags.AddString("json", &json_path, "write every figure as {method: {metric: value}}");
  flags.AddInt64("frames", &max_frames, "evaluate only the first N frames (0 = all)", 0,
                 std::numeric_limits<int64_t>::max());
  flags.AddBool("gyro", &use_gyro,
                "dense: use imu0's gyro (rotation prior and consistency check; --gyro=false: "
                "vision only, as in the paper)");
  flags.AddDouble("gyro-bias-gain", &gyro_bias_gain,
                  "dense: per-frame gain of the online gyro bias estimate (0 = bias fixed at 0)");
  flags.AddBool("consistency-check", &consistency_check,
                "dense: the per-frame consistency check (DEGRADED frames; =false: every tracked "
                "frame is published as measured)");
  flags.AddInt64("step", &step, "frames between segment starts of the relative error", 1, 1000000);
  std::vector<std::string> positional;
  bool help = false;
  if (Status s = flags.Parse(args, &positional, &help); !s.ok()) {
    std::cerr << "mav-eval localization: " << s.message() << "\n";
    return 2;
  }
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (data.empty() || !positional.empty()) {
    std::cerr << "mav-eval localization: --data DIR is required\n" << flags.Help();
    return 2;
  }
  std::vector<Method> methods;
  if (method_name == "all") {
    methods = localization::AllMethods();
  } else if (auto m = localization::ParseMethod(method_name)) {
    methods = {*m};
  } else {
    std::cerr << "mav-eval localization: --method: unknown method '" << method_name
              << "' (known: sparse-pixel, sparse-subpixel, dense, all)\n";
    return 2;
  }
  if (out_dir.empty()) out_dir = data + "/eval";

  auto reader = dataset::EurocReader::Open(data);
  if (!reader.ok()) {
    std::cerr << "mav-eval localization: " << reader.status().message() << "\n";
    return 1;
  }
  if (Status s = reader->CheckHasFrames(); !s.ok()) {
    std::cerr << "mav-eval localization: " << s.message() << "\n";
    return 1;
  }
  if (!reader->has_ground_truth()) {
    std::cerr << "mav-eval localization: " << reader->mav0()
              << "/state_groundtruth_estimate0/data.csv: no ground truth, nothing to compare\n";
    return 1;
  }
  // Ground truth as stamped body poses; each odometry starts at the first frame's true pose.
  std::vector<dataset::StampedPose> gt;
  for (const auto& s : reader->ground_truth()) gt.push_back({s.t_ns, s.T_world_body});
  const int64_t n =
      max_frames > 0 ? std::min(max_frames, reader->num_frames()) : reader->num_frames();
  auto first = eval::AssociateByTime({{reader->frame_times().front(), geometry::SE3()}}, gt);
  if (!first.ok()) {
    std::cerr << "mav-eval localization: first frame: " << first.status().message() << "\n";
    return 1;
  }
  std::vector<MethodRun> runs;
  for (Method m : methods) {
    localization::RigOdometryOptions options;
    options.method = m;
    options.calibration = reader->calibration();
    options.T_world_body0 = first->ground_truth.front();
    options.use_gyro = use_gyro;
    options.gyro_bias_gain = gyro_bias_gain;
    options.odometry.dense.consistency_check = consistency_check;
    auto odometry = localization::RigOdometry::Create(options);
    if (!odometry.ok()) {
      std::cerr << "mav-eval localization: " << odometry.status().message() << "\n";
      return 1;
    }
    MethodRun run;
    run.method = m;
    run.odometry = std::move(odometry).value();
    runs.push_back(std::move(run));
  }

  ProgressBar progress("localization", n);
  cv::Mat raw_left, raw_right, left, right;
  const std::vector<dataset::ImuSample>& imu = reader->imu();
  size_t next_imu = 0;
  for (int64_t i = 0; i < n; ++i) {
    if (Status s = reader->ReadStereo(i, &raw_left, &raw_right); !s.ok()) {
      std::cerr << "\nmav-eval localization: " << s.message() << "\n";
      return 1;
    }
    // Rectified once for all methods (they share the calibration).
    if (Status s = runs.front().odometry->Rectify(raw_left, raw_right, false, &left, &right);
        !s.ok()) {
      std::cerr << "\nmav-eval localization: " << s.message() << "\n";
      return 1;
    }
    const int64_t t_ns = reader->frame_times()[static_cast<size_t>(i)];
    // The gyro samples up to this frame, as the service receives them over DDS.
    for (; next_imu < imu.size() && imu[next_imu].t_ns <= t_ns; ++next_imu) {
      for (MethodRun& run : runs) run.odometry->AddGyro(imu[next_imu].t_ns, imu[next_imu].gyro);
    }
    for (MethodRun& run : runs) {
      const int64_t start = MonotonicNowNs();
      auto frame = run.odometry->Process(t_ns, left, right, /*rectified=*/true);
      run.runtime_ms.push_back(MsSince(start));
      if (!frame.ok()) {
        std::cerr << "\nmav-eval localization: frame " << i << ": " << frame.status().message()
                  << "\n";
        return 1;
      }
      if (frame->state == localization::ReportedState::kLost) {
        if (run.lost_frames++ == 0) run.first_lost_reason = frame->lost_reason;
      }
      if (frame->state == localization::ReportedState::kDegraded) {
        if (run.degraded_frames++ == 0) run.first_degraded_reason = frame->lost_reason;
      }
      run.T_world_body.push_back({t_ns, frame->T_world_out});
      run.frames_csv << i << ',' << t_ns << ',' << localization::ReportedStateName(frame->state)
                     << ',' << frame->matches << ',' << frame->inliers << ',' << frame->residual
                     << ',' << (frame->keyframe ? 1 : 0) << ',' << (frame->gyro_used ? 1 : 0) << ','
                     << frame->T_prev_cur.Translation().norm() << ',' << frame->prediction_error_m
                     << ',' << frame->gyro_rotation_error_deg << ",\"" << frame->lost_reason
                     << "\"\n";
    }
    progress.Update(i + 1);
  }
  progress.Finish();

  if (Status s = MakeDirectories(out_dir); !s.ok()) {
    std::cerr << "mav-eval localization: " << s.message() << "\n";
    return 1;
  }
  eval::RelativeErrorOptions rel_options;
  rel_options.step = static_cast<int>(step);
  JsonReport json;
  std::vector<MethodMetrics> metrics;
  std::vector<plot::PlotSeries> plot;
  std::vector<dataset::StampedPose> gt_at_frames;
  for (MethodRun& run : runs) {
    auto assoc = eval::AssociateByTime(run.T_world_body, gt);
    if (!assoc.ok()) {
      std::cerr << "mav-eval localization: " << assoc.status().message() << "\n";
      return 1;
    }
    MethodMetrics m;
    auto rel = eval::ComputeRelativeError(assoc->estimate, assoc->ground_truth, rel_options);
    auto ate = eval::AbsoluteTrajectoryRmse(assoc->estimate, assoc->ground_truth);
    auto end = eval::EndPointError(assoc->estimate, assoc->ground_truth);
    if (!rel.ok() || !ate.ok() || !end.ok()) {
      std::cerr << "mav-eval localization: too few frames to evaluate (" << assoc->estimate.size()
                << ")\n";
      return 1;
    }
    m.relative = *rel;
    m.ate_rmse_m = *ate;
    m.end_point_error_m = *end;
    m.path_length_m = eval::PathLength(assoc->ground_truth);
    m.runtime = SummarizeRuntimes(run.runtime_ms);
    metrics.push_back(m);

    const std::string name = localization::MethodName(run.method);
    if (m.relative.average_pct) json.Set(name, "avg_rel_error_pct", *m.relative.average_pct);
    for (const auto& e : m.relative.per_length) {
      if (e.segments > 0) {
        json.Set(name, "rel_error_" + Fmt("%.0f", e.length_m) + "m_pct", e.translation_error_pct);
      }
    }
    json.Set(name, "ate_rmse_m", m.ate_rmse_m);
    json.Set(name, "end_point_error_m", m.end_point_error_m);
    json.Set(name, "path_length_m", m.path_length_m);
    json.Set(name, "runtime_mean_ms", m.runtime.mean_ms);
    json.Set(name, "runtime_median_ms", m.runtime.median_ms);
    json.Set(name, "runtime_p95_ms", m.runtime.p95_ms);
    json.Set(name, "frames", static_cast<double>(run.T_world_body.size()));
    json.Set(name, "lost_frames", static_cast<double>(run.lost_frames));
    json.Set(name, "degraded_frames", static_cast<double>(run.degraded_frames));
    json.Set(name, "gyro", run.method == Method::kDense && use_gyro ? 1.0 : 0.0);

    const std::string tum_path = out_dir + "/" + name;
    Status written = dataset::WriteTumTrajectory(tum_path + ".tum", run.T_world_body);
    if (written.ok()) {
      written = WriteStringToFileAtomic(tum_path + "_frames.csv",
                                        "frame,t_ns,state,matches,support,residual,keyframe,gyro,"
                                        "step_m,prediction_error_m,gyro_error_deg,reason\n" +
                                            run.frames_csv.str());
    }
    if (!written.ok()) {
      std::cerr << "mav-eval localization: " << written.message() << "\n";
      return 1;
    }
    if (gt_at_frames.empty()) {
      for (size_t k = 0; k < assoc->t_ns.size(); ++k) {
        gt_at_frames.push_back({assoc->t_ns[k], assoc->ground_truth[k]});
      }
    }
    plot::PlotSeries series{name, {}, 0, 0, 0};
    for (const auto& p : run.T_world_body) series.positions.push_back(p.T_world_body.Translation());
    static const int kColours[3][3] = {{40, 40, 220}, {40, 160, 40}, {200, 110, 20}};
    const int c = static_cast<int>(run.method);
    series.b = kColours[c][0];
    series.g = kColours[c][1];
    series.r = kColours[c][2];
    plot.push_back(series);
  }
  plot::PlotSeries truth{"ground truth", {}, 0, 0, 0};
  for (const auto& p : gt_at_frames) truth.positions.push_back(p.T_world_body.Translation());
  plot.insert(plot.begin(), truth);

  const std::string preset = ReadPreset(data);
  std::printf("\ndata: %s (%s), %lld frames, ground-truth path %.1f m\n", data.c_str(),
              preset.empty() ? "not a mav-sim preset" : preset.c_str(), static_cast<long long>(n),
              metrics.empty() ? 0.0 : metrics.front().path_length_m);
  PrintTables(runs, metrics, preset);
  for (const MethodRun& run : runs) {
    if (run.lost_frames > 0) {
      std::printf("%s lost %d frames; first reason: %s\n", localization::MethodName(run.method),
                  run.lost_frames, run.first_lost_reason.c_str());
    }
    if (run.degraded_frames > 0) {
      std::printf("%s: %d frames DEGRADED (consistency check); first reason: %s\n",
                  localization::MethodName(run.method), run.degraded_frames,
                  run.first_degraded_reason.c_str());
    }
  }

  Status s = dataset::WriteTumTrajectory(out_dir + "/ground_truth.tum", gt_at_frames);
  if (s.ok())
    s = plot::WriteTopViewPlot(out_dir + "/trajectories.png", "localization: " + preset, plot);
  if (s.ok() && !json_path.empty()) s = json.WriteFile(json_path);
  if (!s.ok()) {
    std::cerr << "mav-eval localization: " << s.message() << "\n";
    return 1;
  }
  std::printf(
      "wrote %s/{<method>.tum, <method>_frames.csv, ground_truth.tum, trajectories.png}%s\n",
      out_dir.c_str(), json_path.empty() ? "" : (" and " + json_path).c_str());
  return 0;
}

}  // namespace mav::eval_cli
