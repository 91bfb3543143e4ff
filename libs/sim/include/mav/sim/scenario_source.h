#pragma once
// Data sets that can be replayed frame by frame: a rendered preset (sim::Scenario) or a recorded
// EuRoC ASL directory, behind one interface, and the render-ahead pool that produces their stereo
// pairs in parallel. The simulator service replays a ScenarioSource on DDS; mav-sim generate
// renders one into an EuRoC directory; both use the same FramePrefetcher.

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/dataset/occupancy_grid.h"
#include "mav/dataset/types.h"

namespace mav::sim {

// What a loaded scenario is (ScenarioSummary in the simulator's proto).
struct ScenarioInfo {
  std::string name;  // preset name, or the EuRoC directory
  bool is_preset = false;
  int64_t frames = 0;
  int64_t imu_samples = 0;
  int64_t start_t_ns = 0;
  int64_t end_t_ns = 0;
  double camera_rate_hz = 20.0;
  double imu_rate_hz = 200.0;
  bool rectified = false;
  uint64_t seed = 0;
  bool has_ground_truth = false;
  bool has_ground_truth_occupancy = false;
  // For a recorded set with ground_truth/occupancy.mavocc: that grid's resolution (0 for presets,
  // whose occupancy is computed at any resolution).
  double occupancy_resolution_m = 0;
  int width = 0;
  int height = 0;
};

// A data set that can be replayed: frames by index, IMU and ground truth in time order.
class ScenarioSource {
 public:
  virtual ~ScenarioSource() = default;
  virtual const ScenarioInfo& info() const = 0;
  virtual int64_t FrameTimeNs(int64_t frame) const = 0;
  // Renders or reads frame `frame` as two CV_8UC1 images. Thread-safe.
  virtual Status ReadStereo(int64_t frame, cv::Mat* left, cv::Mat* right) const = 0;
  virtual const std::vector<dataset::ImuSample>& imu() const = 0;
  virtual const std::vector<dataset::GroundTruthState>& ground_truth() const = 0;
  virtual const camera::StereoCalibration& calibration() const = 0;
  virtual const dataset::ImuNoise& imu_noise() const = 0;
  // The grid ground-truth occupancy at `resolution_m` would have, without computing it (to
  // refuse a huge request first). InvalidArgument naming "resolution_m" when the source cannot
  // give that resolution; NotFound without ground-truth occupancy.
  virtual Result<dataset::GridGeometry> OccupancyGeometry(double resolution_m) const = 0;
  // Ground-truth occupancy: computed exactly for a preset; read from the data set's
  // ground_truth/occupancy.mavocc for a recorded set (written by mav-sim generate). Errors as
  // OccupancyGeometry; DEADLINE_EXCEEDED / CANCELLED when `termination` stops the computation.
  virtual Result<dataset::OccupancyGrid> Occupancy(double resolution_m,
                                                   const Termination& termination) const = 0;
};

struct PresetRequest {
  std::string name;
  int64_t frames = 0;  // 0 = full length
  uint64_t seed = 1;
  bool rectified = false;
};

// InvalidArgument naming "preset.name" / "preset.frames".
Result<std::unique_ptr<ScenarioSource>> OpenPreset(const PresetRequest& request);
// InvalidArgument "euroc.directory: empty"; NotFound naming the path (directory or data.csv);
// InvalidArgument naming file:line:field for a corrupt data set. A ground_truth/occupancy.mavocc
// beside mav0/ (a set written by mav-sim generate) is the set's ground-truth occupancy; a corrupt
// one is DataLoss naming the file.
Result<std::unique_ptr<ScenarioSource>> OpenEuroc(const std::string& directory);

// One rendered stereo pair.
struct RenderedFrame {
  int64_t index = 0;
  int64_t t_ns = 0;
  cv::Mat left;
  cv::Mat right;
  double render_ms = 0.0;
  // A checksum of the images its consumer computed ahead, on the rendering thread (the
  // simulator's DDS sink: the stereo sample's CRC-32), so that it is off the publishing path.
  std::optional<uint32_t> crc32;
};

// Renders frames of a source ahead of their consumer on `threads` threads, at most `depth`
// frames ahead of the last requested one, so rendering (tens of ms per pair) overlaps the
// consumer's work. `on_rendered` (optional) runs on the rendering thread right after a frame is
// rendered (mav-sim generate writes its PNGs there, in parallel); its error becomes the frame's.
// Get() returns frames in any order the caller asks for; frames outside the window are dropped.
// With Priority::kIdle the rendering threads run under SCHED_IDLE: they take only CPU time no
// other thread wants, so a real-time consumer (the simulator's publisher, the DDS subscribers on
// the same machine) is never queued behind a render (docs/benchmarks.md, "DDS stereo stream").
// A machine busy with other work then starves the rendering: use it for real-time playback only.
class FramePrefetcher {
 public:
  using OnRendered = std::function<Status(RenderedFrame& frame)>;
  enum class Priority { kNormal, kIdle };
  // What to render: `frames` stereo pairs; frame k at time_ns(k), rendered by read(k, l, r)
  // (called from several threads at once: it must be thread-safe).
  struct Frames {
    int64_t frames = 0;
    std::function<int64_t(int64_t)> time_ns;
    std::function<Status(int64_t, cv::Mat*, cv::Mat*)> read;
  };

  // The frames of a source (kept alive by the prefetcher).
  FramePrefetcher(const std::shared_ptr<const ScenarioSource>& source, int threads = 2,
                  int depth = 4, OnRendered on_rendered = {},
                  Priority priority = Priority::kNormal);
  FramePrefetcher(Frames frames, int threads, int depth, OnRendered on_rendered = {},
                  Priority priority = Priority::kNormal);
  ~FramePrefetcher();
  FramePrefetcher(const FramePrefetcher&) = delete;
  FramePrefetcher& operator=(const FramePrefetcher&) = delete;

  // Frame `index` (blocks until rendered), and schedules index+1 .. index+depth-1.
  Result<RenderedFrame> Get(int64_t index);

 private:
  struct Slot {
    bool started = false;
    bool done = false;
    Status status;
    RenderedFrame frame;
  };
  void Work(Priority priority);
  void ScheduleLocked(int64_t index);

  Frames frames_;
  const int depth_;
  OnRendered on_rendered_;
  std::mutex mutex_;
  std::condition_variable work_cv_;
  std::condition_variable done_cv_;
  std::map<int64_t, Slot> slots_;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace mav::sim
