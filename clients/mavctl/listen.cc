#include "clients/mavctl/listen.h"

#include <algorithm>
#include <cstdio>
#include <iomanip>
#include <optional>
#include <ostream>

#include "mav_sensors.h"
#include "mav_state.h"

#include "mav/common/text.h"
#include "mav/common/time.h"
#include "services/common/dds_codec.h"

namespace mav::mavctl {

namespace {

constexpr size_t kMaxMissingExamples = 10;
constexpr int32_t kTakeBatch = 64;

// Sequence bookkeeping shared by the three topics.
struct SequenceTracker {
  int64_t count = 0;
  int64_t first = -1;
  int64_t expected = -1;
  int64_t missing = 0;
  int64_t out_of_order = 0;
  std::vector<int64_t> missing_examples;
  int64_t first_receive_ns = 0;
  int64_t last_receive_ns = 0;

  void Add(int64_t sequence, int64_t receive_ns) {
    if (count == 0) {
      first = sequence;
      first_receive_ns = receive_ns;
    } else if (sequence > expected) {
      for (int64_t s = expected; s < sequence && missing_examples.size() < kMaxMissingExamples;
           ++s) {
        missing_examples.push_back(s);
      }
      missing += sequence - expected;
    } else if (sequence < expected) {
      ++out_of_order;
    }
    expected = std::max(expected, sequence + 1);
    last_receive_ns = receive_ns;
    ++count;
  }
  double RateHz() const {
    if (count < 2 || last_receive_ns <= first_receive_ns) return 0.0;
    return static_cast<double>(count - 1) / NsToSeconds(last_receive_ns - first_receive_ns);
  }
};

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const size_t i = std::min(values.size() - 1, static_cast<size_t>(p * values.size()));
  return values[i];
}

}  // namespace

bool ListenOptions::IsValid(std::string* why) const {
  if (topic != "stereo" && topic != "imu" && topic != "ground_truth" && topic != "all") {
    if (why != nullptr)
      *why = "--topic: " + QuoteForError(topic) + " is not one of stereo|imu|ground_truth|all";
    return false;
  }
  if (frames < 0) {
    if (why != nullptr) *why = "--frames: must be >= 0, got " + std::to_string(frames);
    return false;
  }
  if (!(timeout_s > 0.0)) {
    if (why != nullptr) *why = "--timeout: must be > 0 s";
    return false;
  }
  return dds.IsValid(why);
}

Result<ListenReport> Listen(const ListenOptions& options, std::ostream& progress) {
  using transport::Qos;
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  const bool want_stereo = options.topic == "stereo" || options.topic == "all";
  const bool want_imu = options.topic == "imu" || options.topic == "all";
  const bool want_gt = options.topic == "ground_truth" || options.topic == "all";

  MAV_ASSIGN_OR_RETURN(transport::Participant participant,
                       transport::Participant::Create(options.dds));
  // Readers keep everything (KEEP_ALL, reliable): a reader that falls behind throttles the
  // writer instead of losing frames, which is what a verifying subscriber wants.
  std::optional<transport::Topic<mav_dds_StereoFrame>> stereo_topic;
  std::optional<transport::Reader<mav_dds_StereoFrame>> stereo;
  std::optional<transport::Topic<mav_dds_ImuSample>> imu_topic;
  std::optional<transport::Reader<mav_dds_ImuSample>> imu;
  std::optional<transport::Topic<mav_dds_GroundTruthState>> gt_topic;
  std::optional<transport::Reader<mav_dds_GroundTruthState>> gt;
  if (want_stereo) {
    MAV_ASSIGN_OR_RETURN(stereo_topic,
                         transport::Topic<mav_dds_StereoFrame>::Create(
                             participant, transport::kStereoTopic, &mav_dds_StereoFrame_desc));
    MAV_ASSIGN_OR_RETURN(stereo, transport::Reader<mav_dds_StereoFrame>::Create(
                                     participant, *stereo_topic, Qos::SensorStream().KeepAll()));
  }
  if (want_imu) {
    MAV_ASSIGN_OR_RETURN(
        imu_topic, transport::Topic<mav_dds_ImuSample>::Create(participant, transport::kImuTopic,
                                                               &mav_dds_ImuSample_desc));
    MAV_ASSIGN_OR_RETURN(imu, transport::Reader<mav_dds_ImuSample>::Create(
                                  participant, *imu_topic, Qos::HighRate().KeepAll()));
  }
  if (want_gt) {
    MAV_ASSIGN_OR_RETURN(
        gt_topic, transport::Topic<mav_dds_GroundTruthState>::Create(
                      participant, transport::kGroundTruthTopic, &mav_dds_GroundTruthState_desc));
    MAV_ASSIGN_OR_RETURN(gt, transport::Reader<mav_dds_GroundTruthState>::Create(
                                 participant, *gt_topic, Qos::State().KeepAll()));
  }

  ListenReport report;
  SequenceTracker stereo_seq, imu_seq, gt_seq;
  std::vector<double> latencies_ms;
  double bytes = 0.0;
  const int64_t start_ns = MonotonicNowNs();
  const int64_t end_ns = start_ns + SecondsToNs(options.timeout_s);
  int64_t next_progress_ns = start_ns + kNsPerSecond;
  auto target_reached = [&] {
    if (options.frames <= 0) return false;
    if (want_stereo) return stereo_seq.count >= options.frames;
    if (want_imu) return imu_seq.count >= options.frames;
    return gt_seq.count >= options.frames;
  };

  while (!target_reached() && MonotonicNowNs() < end_ns) {
    // Block on the main topic's waitset; the others are drained on every wake-up.
    if (stereo.has_value()) {
      MAV_RETURN_IF_ERROR(stereo->WaitForData(5'000'000).status());
    } else if (imu.has_value()) {
      MAV_RETURN_IF_ERROR(imu->WaitForData(5'000'000).status());
    } else {
      MAV_RETURN_IF_ERROR(gt->WaitForData(5'000'000).status());
    }
    if (stereo.has_value()) {
      while (true) {
        MAV_ASSIGN_OR_RETURN(auto samples, stereo->Take(8));
        if (samples.size() == 0) break;
        const int64_t now_wall = WallNowNs();
        const int64_t now_mono = MonotonicNowNs();
        for (int32_t i = 0; i < samples.size(); ++i) {
          if (!samples.valid(i)) continue;
          const mav_dds_StereoFrame& frame = samples[i];
          stereo_seq.Add(static_cast<int64_t>(frame.sequence_number), now_mono);
          const Status check = service_common::CheckStereoFrame(frame);
          if (!check.ok()) {
            ++report.crc_failures;
            if (report.first_error.empty()) report.first_error = check.message();
          }
          report.width = static_cast<int>(frame.width);
          report.height = static_cast<int>(frame.height);
          bytes += static_cast<double>(frame.left._length) + frame.right._length;
          latencies_ms.push_back(static_cast<double>(now_wall - frame.publish_t_ns) * 1e-6);
          if (target_reached()) break;
        }
        if (target_reached()) break;
      }
    }
    if (imu.has_value()) {
      while (true) {
        MAV_ASSIGN_OR_RETURN(auto samples, imu->Take(kTakeBatch));
        if (samples.size() == 0) break;
        const int64_t now_mono = MonotonicNowNs();
        for (int32_t i = 0; i < samples.size(); ++i) {
          if (samples.valid(i)) {
            imu_seq.Add(static_cast<int64_t>(samples[i].sequence_number), now_mono);
          }
        }
      }
    }
    if (gt.has_value()) {
      while (true) {
        MAV_ASSIGN_OR_RETURN(auto samples, gt->Take(kTakeBatch));
        if (samples.size() == 0) break;
        const int64_t now_mono = MonotonicNowNs();
        for (int32_t i = 0; i < samples.size(); ++i) {
          if (samples.valid(i)) {
            gt_seq.Add(static_cast<int64_t>(samples[i].sequence_number), now_mono);
          }
        }
      }
    }
    if (options.progress && MonotonicNowNs() >= next_progress_ns) {
      next_progress_ns += kNsPerSecond;
      progress << "  t=" << std::fixed << std::setprecision(0)
               << NsToSeconds(MonotonicNowNs() - start_ns) << " s: stereo " << stereo_seq.count
               << ", imu " << imu_seq.count << ", ground truth " << gt_seq.count << std::endl;
    }
  }

  report.reached_target = target_reached();
  report.elapsed_s = NsToSeconds(MonotonicNowNs() - start_ns);
  report.frames = stereo_seq.count;
  report.first_sequence = stereo_seq.first;
  report.last_sequence = stereo_seq.expected - 1;
  report.missing = stereo_seq.missing;
  report.missing_examples = stereo_seq.missing_examples;
  report.out_of_order = stereo_seq.out_of_order;
  report.rate_hz = stereo_seq.RateHz();
  if (!latencies_ms.empty()) {
    double sum = 0;
    for (double v : latencies_ms) sum += v;
    report.latency_mean_ms = sum / static_cast<double>(latencies_ms.size());
    report.latency_p50_ms = Percentile(latencies_ms, 0.5);
    report.latency_p95_ms = Percentile(latencies_ms, 0.95);
    report.latency_max_ms = Percentile(latencies_ms, 1.0);
  }
  if (stereo_seq.count >= 2 && stereo_seq.last_receive_ns > stereo_seq.first_receive_ns) {
    // Bytes after the first frame over the time between the first and the last.
    const double per_frame = bytes / static_cast<double>(stereo_seq.count);
    report.throughput_mb_s = per_frame * static_cast<double>(stereo_seq.count - 1) /
                             NsToSeconds(stereo_seq.last_receive_ns - stereo_seq.first_receive_ns) /
                             1e6;
  }
  report.imu_samples = imu_seq.count;
  report.imu_missing = imu_seq.missing;
  report.imu_rate_hz = imu_seq.RateHz();
  report.ground_truth = gt_seq.count;
  report.ground_truth_missing = gt_seq.missing;
  report.ground_truth_rate_hz = gt_seq.RateHz();
  return report;
}

bool ReportPassed(const ListenOptions& options, const ListenReport& report) {
  if (options.frames > 0 && !report.reached_target) return false;
  return report.missing == 0 && report.crc_failures == 0 && report.out_of_order == 0;
}

void PrintReport(const ListenOptions& options, const ListenReport& report, std::ostream& out) {
  out << std::fixed;
  const bool want_stereo = options.topic == "stereo" || options.topic == "all";
  const bool want_imu = options.topic == "imu" || options.topic == "all";
  const bool want_gt = options.topic == "ground_truth" || options.topic == "all";
  out << "listened " << std::setprecision(1) << report.elapsed_s << " s on DDS domain "
      << options.dds.domain << (report.reached_target ? " (target reached)" : "") << "\n";
  if (want_stereo) {
    out << "stereo:       " << report.frames << " frames";
    if (report.frames > 0) {
      out << " (seq " << report.first_sequence << ".." << report.last_sequence << ", "
          << report.width << "x" << report.height << ")";
    }
    out << "\n              missing " << report.missing;
    if (!report.missing_examples.empty()) {
      out << " (e.g.";
      for (int64_t s : report.missing_examples) out << " " << s;
      out << ")";
    }
    out << ", out of order " << report.out_of_order << ", checksum failures " << report.crc_failures
        << "\n";
    if (!report.first_error.empty())
      out << "              first error: " << report.first_error << "\n";
    out << "              rate " << std::setprecision(2) << report.rate_hz << " Hz, throughput "
        << report.throughput_mb_s << " MB/s\n";
    out << "              latency (publish -> receive) mean " << std::setprecision(3)
        << report.latency_mean_ms << " ms, p50 " << report.latency_p50_ms << " ms, p95 "
        << report.latency_p95_ms << " ms, max " << report.latency_max_ms << " ms\n";
  }
  if (want_imu) {
    out << "imu:          " << report.imu_samples << " samples, missing " << report.imu_missing
        << ", rate " << std::setprecision(1) << report.imu_rate_hz << " Hz\n";
  }
  if (want_gt) {
    out << "ground_truth: " << report.ground_truth << " states, missing "
        << report.ground_truth_missing << ", rate " << std::setprecision(1)
        << report.ground_truth_rate_hz << " Hz\n";
  }
  out << "RESULT frames=" << report.frames << " missing=" << report.missing
      << " crc_failures=" << report.crc_failures << " out_of_order=" << report.out_of_order
      << " first_seq=" << report.first_sequence << " imu=" << report.imu_samples
      << " ground_truth=" << report.ground_truth
      << " passed=" << (ReportPassed(options, report) ? 1 : 0) << "\n";
}

}  // namespace mav::mavctl
