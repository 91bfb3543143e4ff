// mav-eval localization: runs the stereo odometry methods over an EuRoC directory and prints the
// paper's Tables 1 and 2 (Holzmann et al. 2015) with its figures beside ours
// (mav/eval/localization_eval.h).

#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include "clients/plot/plot.h"
#include "commands.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/dataset/trajectory_io.h"
#include "mav/eval/localization_eval.h"
#include "output.h"

namespace mav::eval_cli {
namespace {

constexpr const char* kCommand = "mav-eval localization";

// DIR/<method>.tum, DIR/<method>_frames.csv, DIR/ground_truth.tum and DIR/trajectories.png.
Status WriteFiles(const std::string& out_dir, const eval::LocalizationSummary& summary) {
  MAV_RETURN_IF_ERROR(MakeDirectories(out_dir));
  std::vector<plot::PlotSeries> plot;
  plot::PlotSeries truth{"ground truth", {}, 0, 0, 0};
  for (const auto& p : summary.ground_truth_at_frames) {
    truth.positions.push_back(p.T_world_body.Translation());
  }
  plot.push_back(truth);
  for (const eval::LocalizationMethodResult& m : summary.methods) {
    const std::string path = out_dir + "/" + localization::MethodName(m.method);
    MAV_RETURN_IF_ERROR(dataset::WriteTumTrajectory(path + ".tum", m.T_world_body));
    MAV_RETURN_IF_ERROR(WriteStringToFileAtomic(
        path + "_frames.csv", eval::LocalizationFramesCsvHeader() + m.frames_csv));
    static const int kColours[3][3] = {{40, 40, 220}, {40, 160, 40}, {200, 110, 20}};
    const int c = static_cast<int>(m.method);
    plot::PlotSeries series{
        localization::MethodName(m.method), {}, kColours[c][0], kColours[c][1], kColours[c][2]};
    for (const auto& p : m.T_world_body) series.positions.push_back(p.T_world_body.Translation());
    plot.push_back(series);
  }
  MAV_RETURN_IF_ERROR(
      dataset::WriteTumTrajectory(out_dir + "/ground_truth.tum", summary.ground_truth_at_frames));
  return plot::WriteTopViewPlot(out_dir + "/trajectories.png", "localization: " + summary.preset,
                                plot);
}

}  // namespace

int RunLocalization(const std::vector<std::string>& args) {
  eval::LocalizationEvalOptions options;
  std::string method_name = "all", out_dir, json_path;
  int64_t step = options.step;
  FlagParser flags(
      "mav-eval localization --data DIR [--method sparse-pixel|sparse-subpixel|dense|all] "
      "[--out DIR] [--json FILE]");
  flags.AddString("data", &options.data,
                  "EuRoC directory with ground truth (e.g. from mav-sim generate)");
  flags.AddString("method", &method_name, "sparse-pixel, sparse-subpixel, dense or all");
  flags.AddString("out", &out_dir,
                  "directory for TUM trajectories and the plot (default DIR/eval)");
  flags.AddString("json", &json_path, "write every figure as {method: {metric: value}}");
  flags.AddInt64("frames", &options.max_frames, "evaluate only the first N frames (0 = all)", 0,
                 std::numeric_limits<int64_t>::max());
  flags.AddBool("gyro", &options.use_gyro,
                "dense: use imu0's gyro (rotation prior and consistency check; --gyro=false: "
                "vision only, as in the paper)");
  flags.AddDouble("gyro-bias-gain", &options.gyro_bias_gain,
                  "dense: per-frame gain of the online gyro bias estimate (0 = bias fixed at 0)");
  flags.AddBool("consistency-check", &options.consistency_check,
                "dense: the per-frame consistency check (DEGRADED frames; =false: every tracked "
                "frame is published as measured)");
  flags.AddInt64("step", &step, "frames between segment starts of the relative error", 1, 1000000);
  if (std::optional<int> done = ParseDataCommand(flags, args, kCommand, options.data)) {
    return *done;
  }
  if (method_name != "all") {
    const std::optional<localization::Method> m = localization::ParseMethod(method_name);
    if (!m) {
      return Fail(kCommand,
                  "--method: unknown method '" + method_name +
                      "' (known: sparse-pixel, sparse-subpixel, dense, all)",
                  2);
    }
    options.methods = {*m};
  }
  options.step = static_cast<int>(step);
  if (out_dir.empty()) out_dir = options.data + "/eval";

  ProgressPrinter progress;
  Result<eval::LocalizationSummary> summary =
      eval::EvaluateLocalization(options, progress.Callback());
  if (!summary.ok()) return Fail(kCommand, summary.status().message());
  if (Status s = PrintReport(eval::LocalizationReport(*summary), json_path); !s.ok()) {
    return Fail(kCommand, s.message());
  }
  if (Status s = WriteFiles(out_dir, *summary); !s.ok()) return Fail(kCommand, s.message());
  std::printf(
      "wrote %s/{<method>.tum, <method>_frames.csv, ground_truth.tum, trajectories.png}%s\n",
      out_dir.c_str(), json_path.empty() ? "" : (" and " + json_path).c_str());
  return 0;
}

}  // namespace mav::eval_cli
