#include "clients/mav-load/frames.h"

#include <algorithm>
#include <cstdlib>
#include <memory>
#include <optional>
#include <utility>

#include "mav/sim/scenario_source.h"
#include "services/common/proto_codec.h"

namespace mav::load {

namespace {

// The ground-truth state nearest to t_ns, when one is within 5 ms.
std::optional<geometry::SE3> PoseAt(const std::vector<dataset::GroundTruthState>& states,
                                    int64_t t_ns) {
  auto it =
      std::lower_bound(states.begin(), states.end(), t_ns,
                       [](const dataset::GroundTruthState& s, int64_t t) { return s.t_ns < t; });
  const dataset::GroundTruthState* best = nullptr;
  for (auto c : {it, it == states.begin() ? it : it - 1}) {
    if (c == states.end()) continue;
    if (best == nullptr || std::llabs(c->t_ns - t_ns) < std::llabs(best->t_ns - t_ns)) {
      best = &*c;
    }
  }
  if (best == nullptr || std::llabs(best->t_ns - t_ns) > 5'000'000) return std::nullopt;
  return best->T_world_body;
}

Result<std::shared_ptr<const sim::ScenarioSource>> OpenSource(const FrameSelection& s) {
  if (s.frames < 1) return Status::InvalidArgument("--frames: must be >= 1");
  if (s.stride < 1) return Status::InvalidArgument("frame stride: must be >= 1");
  if (!s.euroc.empty()) {
    Result<std::unique_ptr<sim::ScenarioSource>> source = sim::OpenEuroc(s.euroc);
    if (!source.ok()) return Status::InvalidArgument("--euroc: " + source.status().message());
    const int64_t available = ((*source)->info().frames - 1) / s.stride + 1;
    if ((*source)->info().frames < 1 || s.frames > available) {
      return Status::InvalidArgument("--frames: " + s.euroc + " has " +
                                     std::to_string((*source)->info().frames) + " frames");
    }
    return std::shared_ptr<const sim::ScenarioSource>(std::move(*source));
  }
  sim::PresetRequest request;
  request.name = s.preset;
  request.frames = (s.frames - 1) * s.stride + 1;
  request.seed = s.seed;
  request.rectified = s.rectified;
  Result<std::unique_ptr<sim::ScenarioSource>> source = sim::OpenPreset(request);
  if (!source.ok()) return Status::InvalidArgument("--frames: " + source.status().message());
  return std::shared_ptr<const sim::ScenarioSource>(std::move(*source));
}

}  // namespace

Result<StereoFrames> LoadFrames(const FrameSelection& selection) {
  MAV_ASSIGN_OR_RETURN(std::shared_ptr<const sim::ScenarioSource> source, OpenSource(selection));
  const int64_t stride = selection.stride;
  StereoFrames out;
  out.source = selection.euroc.empty()
                   ? selection.preset + " (seed " + std::to_string(selection.seed) + ")"
                   : selection.euroc;
  out.calibration = source->calibration();
  out.rectified = source->info().rectified;
  if (selection.frames > 1) out.period_ns = source->FrameTimeNs(stride) - source->FrameTimeNs(0);
  sim::FramePrefetcher::Frames frames;
  frames.frames = selection.frames;
  frames.time_ns = [source, stride](int64_t k) { return source->FrameTimeNs(k * stride); };
  frames.read = [source, stride](int64_t k, cv::Mat* left, cv::Mat* right) {
    return source->ReadStereo(k * stride, left, right);
  };
  sim::FramePrefetcher prefetcher(std::move(frames), /*threads=*/2, /*depth=*/4);
  const std::vector<dataset::GroundTruthState>& truth = source->ground_truth();
  for (int64_t k = 0; k < selection.frames; ++k) {
    MAV_ASSIGN_OR_RETURN(sim::RenderedFrame frame, prefetcher.Get(k));
    out.t_ns.push_back(frame.t_ns);
    out.left.push_back(frame.left);
    out.right.push_back(frame.right);
    if (std::optional<geometry::SE3> pose = PoseAt(truth, frame.t_ns)) {
      out.T_world_body.push_back(*pose);
    }
  }
  if (out.T_world_body.size() != out.t_ns.size()) out.T_world_body.clear();
  return out;
}

void SetImage(const cv::Mat& frame, v1::Image* out) {
  const cv::Mat image = frame.isContinuous() ? frame : frame.clone();
  out->set_width(static_cast<uint32_t>(image.cols));
  out->set_height(static_cast<uint32_t>(image.rows));
  out->set_encoding(v1::IMAGE_ENCODING_MONO8);
  out->set_data(std::string(reinterpret_cast<const char*>(image.data), image.total()));
}

void SetStereoImages(const StereoFrames& frames, size_t k, v1::StereoPair* out) {
  SetImage(frames.left[k], out->mutable_left());
  SetImage(frames.right[k], out->mutable_right());
  out->set_rectified(frames.rectified);
}

void SetCalibration(const StereoFrames& frames, v1::StereoCalibration* out) {
  const camera::StereoCalibration& c = frames.calibration;
  out->mutable_left()->set_camera_id("cam0");
  service_common::ToProto(c.cam0, out->mutable_left()->mutable_intrinsics());
  service_common::ToProto(c.T_body_cam0, out->mutable_left()->mutable_t_body_cam());
  out->mutable_right()->set_camera_id("cam1");
  service_common::ToProto(c.cam1, out->mutable_right()->mutable_intrinsics());
  service_common::ToProto(c.T_body_cam1, out->mutable_right()->mutable_t_body_cam());
  out->set_rectified(frames.rectified);
  out->set_baseline_m(c.Baseline());
}

}  // namespace mav::load
