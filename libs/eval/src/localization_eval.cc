#include "mav/eval/localization_eval.h"

#include <memory>
#include <optional>
#include <sstream>
#include <utility>

#include <opencv2/core/mat.hpp>

#include "mav/common/time.h"
#include "mav/dataset/euroc.h"
#include "mav/eval/paper_figures.h"

namespace mav::eval {
namespace {

using localization::Method;

// A method while it runs.
struct MethodRun {
  std::unique_ptr<localization::RigOdometry> odometry;
  std::vector<double> runtime_ms;
  std::ostringstream frames_csv;
  LocalizationMethodResult result;
};

Result<std::vector<MethodRun>> CreateRuns(const LocalizationEvalOptions& options,
                                          const dataset::EurocReader& reader,
                                          const geometry::SE3& T_world_body0) {
  std::vector<MethodRun> runs;
  for (Method m : options.methods) {
    localization::RigOdometryOptions o;
    o.method = m;
    o.calibration = reader.calibration();
    o.T_world_body0 = T_world_body0;
    o.use_gyro = options.use_gyro;
    o.gyro_bias_gain = options.gyro_bias_gain;
    o.odometry.dense.consistency_check = options.consistency_check;
    MAV_ASSIGN_OR_RETURN(std::unique_ptr<localization::RigOdometry> odometry,
                         localization::RigOdometry::Create(o));
    MethodRun& run = runs.emplace_back();
    run.odometry = std::move(odometry);
    run.result.method = m;
    run.result.gyro = m == Method::kDense && options.use_gyro;
  }
  return runs;
}

// One frame through one method: its pose, runtime, state counts and CSV line.
Status ProcessFrame(int64_t i, int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                    MethodRun* run) {
  const int64_t start = MonotonicNowNs();
  auto frame = run->odometry->Process(t_ns, left, right, /*rectified=*/true);
  run->runtime_ms.push_back(MsSince(start));
  if (!frame.ok()) {
    return Status(frame.status().code(),
                  "frame " + std::to_string(i) + ": " + frame.status().message());
  }
  LocalizationMethodResult& r = run->result;
  if (frame->state == localization::ReportedState::kLost) {
    if (r.lost_frames++ == 0) r.first_lost_reason = frame->lost_reason;
  }
  if (frame->state == localization::ReportedState::kDegraded) {
    if (r.degraded_frames++ == 0) r.first_degraded_reason = frame->lost_reason;
  }
  r.T_world_body.push_back({t_ns, frame->T_world_out});
  run->frames_csv << i << ',' << t_ns << ',' << localization::ReportedStateName(frame->state) << ','
                  << frame->matches << ',' << frame->inliers << ',' << frame->residual << ','
                  << (frame->keyframe ? 1 : 0) << ',' << (frame->gyro_used ? 1 : 0) << ','
                  << frame->T_prev_cur.Translation().norm() << ',' << frame->prediction_error_m
                  << ',' << frame->gyro_rotation_error_deg << ",\"" << frame->lost_reason << "\"\n";
  return Status::Ok();
}

// Every frame through every method: read and rectified once, the gyro samples up to the frame
// first, as the service receives them over DDS.
Status RunFrames(const dataset::EurocReader& reader, int64_t n, const StepProgress& progress,
                 std::vector<MethodRun>* runs) {
  cv::Mat raw_left, raw_right, left, right;
  const std::vector<dataset::ImuSample>& imu = reader.imu();
  size_t next_imu = 0;
  for (int64_t i = 0; i < n; ++i) {
    MAV_RETURN_IF_ERROR(reader.ReadStereo(i, &raw_left, &raw_right));
    MAV_RETURN_IF_ERROR(runs->front().odometry->Rectify(raw_left, raw_right, false, &left, &right));
    const int64_t t_ns = reader.frame_times()[static_cast<size_t>(i)];
    for (; next_imu < imu.size() && imu[next_imu].t_ns <= t_ns; ++next_imu) {
      for (MethodRun& run : *runs) {
        run.odometry->AddGyro(imu[next_imu].t_ns, imu[next_imu].gyro);
      }
    }
    for (MethodRun& run : *runs) MAV_RETURN_IF_ERROR(ProcessFrame(i, t_ns, left, right, &run));
    if (progress) progress("localization", i + 1, n);
  }
  return Status::Ok();
}

std::string Fmt(const char* format, double v) { return FormatLine(format, v); }

const PaperLocalizationRow* PaperRow(Method m) {
  for (const auto& row : PaperLocalization()) {
    if (std::string(row.method) == localization::MethodName(m)) return &row;
  }
  return nullptr;
}

void AddTable1(const LocalizationSummary& s, std::optional<int> ds, Report* report) {
  ReportTable& t =
      report->AddTable("Table 1: runtime per frame and average relative translational error" +
                       (ds ? " (paper: data set " + std::to_string(*ds + 1) + ")" : std::string()));
  t.header.push_back(FormatLine("%-16s %10s %10s %10s %10s %9s %9s %9s %6s", "method", "runtime",
                                "p95", "paper", "error", "paper", "ATE", "end-pt", "lost"));
  for (const LocalizationMethodResult& m : s.methods) {
    const PaperLocalizationRow* p = PaperRow(m.method);
    const RelativeError& rel = m.accuracy.relative;
    t.rows.push_back(
        FormatLine("%-16s %8.1fms %8.1fms %10s %10s %9s %8.3fm %8.3fm %6d",
                   localization::MethodName(m.method), m.runtime.mean_ms, m.runtime.p95_ms,
                   ds && p ? Fmt("%.0fms", p->runtime_ms[*ds]).c_str() : "-",
                   rel.average_pct ? Fmt("%.2f%%", *rel.average_pct).c_str() : "n/a",
                   ds && p ? Fmt("%.1f%%", p->error_pct[*ds]).c_str() : "-", m.accuracy.ate_rmse_m,
                   m.accuracy.end_point_error_m, m.lost_frames));
  }
}

void AddTable2(const LocalizationSummary& s, std::optional<int> ds, Report* report) {
  ReportTable& t =
      report->AddTable(std::string("Table 2: relative translational error (%) per segment length") +
                       (ds == 2 ? " (paper: data set 3)" : ""));
  std::string header = FormatLine("%-22s", "method");
  for (double l : PaperSegmentLengths()) header += FormatLine(" %6.0fm", l);
  t.header.push_back(header);
  for (const LocalizationMethodResult& m : s.methods) {
    std::string row = FormatLine("%-22s", localization::MethodName(m.method));
    for (const auto& e : m.accuracy.relative.per_length) {
      row +=
          e.segments > 0 ? FormatLine(" %7.2f", e.translation_error_pct) : FormatLine(" %7s", "-");
    }
    t.rows.push_back(row);
    const PaperLocalizationRow* p = PaperRow(m.method);
    if (ds == 2 && p) {
      std::string paper = FormatLine("%-22s", (std::string("  paper ") + p->method).c_str());
      for (double v : p->ds3_error_per_length_pct) paper += FormatLine(" %7.1f", v);
      t.rows.push_back(paper);
    }
  }
  t.notes.push_back(
      "(segments start every 10 frames; '-' = the trajectory is shorter than that length)");
  for (const LocalizationMethodResult& m : s.methods) {
    if (m.lost_frames > 0) {
      t.notes.push_back(FormatLine("%s lost %d frames; first reason: %s",
                                   localization::MethodName(m.method), m.lost_frames,
                                   m.first_lost_reason.c_str()));
    }
    if (m.degraded_frames > 0) {
      t.notes.push_back(FormatLine("%s: %d frames DEGRADED (consistency check); first reason: %s",
                                   localization::MethodName(m.method), m.degraded_frames,
                                   m.first_degraded_reason.c_str()));
    }
  }
}

void AddJson(const LocalizationMethodResult& m, JsonReport* json) {
  const std::string name = localization::MethodName(m.method);
  const TrajectoryAccuracy& a = m.accuracy;
  if (a.relative.average_pct) json->Set(name, "avg_rel_error_pct", *a.relative.average_pct);
  for (const auto& e : a.relative.per_length) {
    if (e.segments > 0) {
      json->Set(name, "rel_error_" + Fmt("%.0f", e.length_m) + "m_pct", e.translation_error_pct);
    }
  }
  json->Set(name, "ate_rmse_m", a.ate_rmse_m);
  json->Set(name, "end_point_error_m", a.end_point_error_m);
  json->Set(name, "path_length_m", a.path_length_m);
  json->Set(name, "runtime_mean_ms", m.runtime.mean_ms);
  json->Set(name, "runtime_median_ms", m.runtime.median_ms);
  json->Set(name, "runtime_p95_ms", m.runtime.p95_ms);
  json->Set(name, "frames", static_cast<double>(m.T_world_body.size()));
  json->Set(name, "lost_frames", static_cast<double>(m.lost_frames));
  json->Set(name, "degraded_frames", static_cast<double>(m.degraded_frames));
  json->Set(name, "gyro", m.gyro ? 1.0 : 0.0);
}

}  // namespace

const char* LocalizationFramesCsvHeader() {
  return "frame,t_ns,state,matches,support,residual,keyframe,gyro,step_m,prediction_error_m,"
         "gyro_error_deg,reason\n";
}

Result<LocalizationSummary> EvaluateLocalization(const LocalizationEvalOptions& options,
                                                 const StepProgress& progress) {
  if (options.methods.empty()) return Status::InvalidArgument("methods: empty");
  if (options.step < 1) return Status::InvalidArgument("step: must be >= 1");
  MAV_ASSIGN_OR_RETURN(const dataset::EurocReader reader, dataset::EurocReader::Open(options.data));
  MAV_RETURN_IF_ERROR(reader.CheckHasFrames());
  if (!reader.has_ground_truth()) {
    return Status::FailedPrecondition(reader.mav0() +
                                      "/state_groundtruth_estimate0/data.csv: no ground truth, "
                                      "nothing to compare");
  }
  // Ground truth as stamped body poses; each odometry starts at the first frame's true pose.
  std::vector<dataset::StampedPose> gt;
  for (const auto& s : reader.ground_truth()) gt.push_back({s.t_ns, s.T_world_body});
  LocalizationSummary out;
  out.data = options.data;
  out.preset = ReadPresetName(options.data);
  out.frames = options.max_frames > 0 ? std::min(options.max_frames, reader.num_frames())
                                      : reader.num_frames();
  auto first = AssociateByTime({{reader.frame_times().front(), geometry::SE3()}}, gt);
  if (!first.ok()) return Status(first.status().code(), "first frame: " + first.status().message());
  MAV_ASSIGN_OR_RETURN(std::vector<MethodRun> runs,
                       CreateRuns(options, reader, first->ground_truth.front()));
  MAV_RETURN_IF_ERROR(RunFrames(reader, out.frames, progress, &runs));

  RelativeErrorOptions rel_options;
  rel_options.step = options.step;
  for (MethodRun& run : runs) {
    LocalizationMethodResult& r = run.result;
    MAV_ASSIGN_OR_RETURN(r.accuracy, EvaluateTrajectory(r.T_world_body, gt, rel_options));
    r.runtime = SummarizeRuntimes(run.runtime_ms);
    r.frames_csv = run.frames_csv.str();
    if (out.ground_truth_at_frames.empty()) {
      const AssociatedTrajectories& a = r.accuracy.associated;
      for (size_t k = 0; k < a.t_ns.size(); ++k) {
        out.ground_truth_at_frames.push_back({a.t_ns[k], a.ground_truth[k]});
      }
    }
    out.methods.push_back(std::move(r));
  }
  return out;
}

Report LocalizationReport(const LocalizationSummary& s) {
  Report report;
  report.AddTable(FormatLine("data: %s (%s), %lld frames, ground-truth path %.1f m", s.data.c_str(),
                             s.preset.empty() ? "not a mav-sim preset" : s.preset.c_str(),
                             static_cast<long long>(s.frames),
                             s.methods.empty() ? 0.0 : s.methods.front().accuracy.path_length_m));
  const std::optional<int> ds = PaperDataSetIndex(s.preset);
  AddTable1(s, ds, &report);
  AddTable2(s, ds, &report);
  for (const LocalizationMethodResult& m : s.methods) AddJson(m, &report.json);
  return report;
}

}  // namespace mav::eval
