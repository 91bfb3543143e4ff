#pragma once
// `mavctl listen`: a DDS subscriber of the simulator's streams that verifies every stereo frame
// (size, CRC-32), tracks sequence numbers, and reports what arrived.

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/transport/dds.h"

namespace mav::mavctl {

struct ListenOptions {
  transport::DdsOptions dds;
  // "stereo", "imu", "ground_truth" or "all".
  std::string topic = "all";
  // Stop after this many stereo frames (or IMU / ground-truth samples when only that topic is
  // selected); 0 = until the timeout.
  int64_t frames = 0;
  // Give up after this many seconds in total.
  double timeout_s = 30.0;
  // How stereo frames are taken: "listener" (on Cyclone's receive thread, as soon as a frame is
  // complete) or "waitset" (by this thread, woken by a waitset: one thread hand-off more).
  std::string wake = "listener";
  // The stereo reader's history: 0 = KEEP_ALL (a reader that falls behind throttles the writer
  // instead of losing frames), N in 1..256 = KEEP_LAST N (frames beyond N not yet taken are lost,
  // and counted missing). Cyclone carries only KEEP_LAST readers in shared memory (dds.
  // shared_memory), so -1 (the default) means KEEP_ALL without shared memory and
  // KEEP_LAST kSharedMemoryDepth with it.
  int64_t keep_last = -1;
  static constexpr int64_t kSharedMemoryDepth = 16;
  // Print one line per second while listening.
  bool progress = true;

  bool IsValid(std::string* why) const;
  // keep_last with -1 resolved as above.
  int64_t StereoDepth() const;
};

struct ListenReport {
  int64_t frames = 0;
  int64_t first_sequence = -1;
  int64_t last_sequence = -1;
  int64_t missing = 0;
  std::vector<int64_t> missing_examples;  // the first few missing sequence numbers
  int64_t out_of_order = 0;
  int64_t crc_failures = 0;
  std::string first_error;
  int width = 0;
  int height = 0;
  // How the stereo reader was set up: its history (0 = keep all) and whether Cyclone carries
  // its frames in shared memory.
  int64_t stereo_depth = 0;
  bool stereo_shared_memory = false;
  double rate_hz = 0.0;
  double latency_mean_ms = 0.0;
  double latency_p50_ms = 0.0;
  double latency_p95_ms = 0.0;
  double latency_p99_ms = 0.0;
  double latency_max_ms = 0.0;
  // The latency's two hops (ListenOptions::wake names how the DDS one ends).
  double publisher_p50_ms = 0.0;
  double publisher_p99_ms = 0.0;
  double dds_p50_ms = 0.0;
  double dds_p99_ms = 0.0;
  double throughput_mb_s = 0.0;
  int64_t imu_samples = 0;
  int64_t imu_missing = 0;
  double imu_rate_hz = 0.0;
  int64_t ground_truth = 0;
  int64_t ground_truth_missing = 0;
  double ground_truth_rate_hz = 0.0;
  bool reached_target = false;
  double elapsed_s = 0.0;
};

// Subscribes, receives until the target or the timeout, and returns the report. Errors only for
// DDS set-up failures.
Result<ListenReport> Listen(const ListenOptions& options, std::ostream& progress);

// Human-readable summary, ending with one machine-readable line
// "RESULT frames=N missing=M crc_failures=C out_of_order=O first_seq=S imu=I ground_truth=G".
void PrintReport(const ListenOptions& options, const ListenReport& report, std::ostream& out);

// True when the run passed: target reached (if any), no missing frames, no CRC failures.
bool ReportPassed(const ListenOptions& options, const ListenReport& report);

}  // namespace mav::mavctl
