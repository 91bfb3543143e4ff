#include "clients/mavctl/listen.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iomanip>
#include <mutex>
#include <optional>
#include <ostream>
#include <thread>

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

bool WantsStereo(const ListenOptions& options) {
  return options.topic == "stereo" || options.topic == "all";
}
bool WantsImu(const ListenOptions& options) {
  return options.topic == "imu" || options.topic == "all";
}
bool WantsGroundTruth(const ListenOptions& options) {
  return options.topic == "ground_truth" || options.topic == "all";
}

// The topics and readers of the selected streams; the unselected ones stay empty. The members
// are declared topic before reader so that a reader is destroyed before its topic.
struct Subscriptions {
  std::optional<transport::Topic<mav_dds_StereoFrame>> stereo_topic;
  std::optional<transport::Reader<mav_dds_StereoFrame>> stereo;
  std::optional<transport::Topic<mav_dds_ImuSample>> imu_topic;
  std::optional<transport::Reader<mav_dds_ImuSample>> imu;
  std::optional<transport::Topic<mav_dds_GroundTruthState>> gt_topic;
  std::optional<transport::Reader<mav_dds_GroundTruthState>> gt;
};

// Readers keep everything (KEEP_ALL, reliable): a reader that falls behind throttles the writer
// instead of losing frames, which is what a verifying subscriber wants. The stereo reader keeps
// the last N instead when asked, or with shared memory (ListenOptions::keep_last).
Status Subscribe(const transport::Participant& participant, const ListenOptions& options,
                 Subscriptions* subs) {
  using transport::Qos;
  if (WantsStereo(options)) {
    MAV_ASSIGN_OR_RETURN(subs->stereo_topic,
                         transport::Topic<mav_dds_StereoFrame>::Create(
                             participant, transport::kStereoTopic, &mav_dds_StereoFrame_desc));
    const int64_t depth = options.StereoDepth();
    Qos qos = Qos::SensorStream();
    if (depth == 0) {
      qos.KeepAll();
    } else {
      qos.KeepLast(static_cast<int32_t>(depth));
    }
    MAV_ASSIGN_OR_RETURN(subs->stereo, transport::Reader<mav_dds_StereoFrame>::Create(
                                           participant, *subs->stereo_topic, qos));
  }
  if (WantsImu(options)) {
    MAV_ASSIGN_OR_RETURN(subs->imu_topic,
                         transport::Topic<mav_dds_ImuSample>::Create(
                             participant, transport::kImuTopic, &mav_dds_ImuSample_desc));
    MAV_ASSIGN_OR_RETURN(subs->imu, transport::Reader<mav_dds_ImuSample>::Create(
                                        participant, *subs->imu_topic, Qos::HighRate().KeepAll()));
  }
  if (WantsGroundTruth(options)) {
    MAV_ASSIGN_OR_RETURN(subs->gt_topic, transport::Topic<mav_dds_GroundTruthState>::Create(
                                             participant, transport::kGroundTruthTopic,
                                             &mav_dds_GroundTruthState_desc));
    MAV_ASSIGN_OR_RETURN(subs->gt, transport::Reader<mav_dds_GroundTruthState>::Create(
                                       participant, *subs->gt_topic, Qos::State().KeepAll()));
  }
  return Status::Ok();
}

// What has arrived so far, over all topics.
struct Received {
  SequenceTracker stereo, imu, gt;
  int64_t crc_failures = 0;
  std::string first_error;
  int width = 0;
  int height = 0;
  std::vector<double> latencies_ms;  // publish -> receive of every stereo frame
  // The two hops of it: the publisher's stamp -> its dds_write (the sample's source timestamp),
  // and dds_write -> the take here (DDS: serialisation, transport, delivery, the wake-up).
  std::vector<double> publisher_ms;
  std::vector<double> dds_ms;
  double bytes = 0.0;  // image bytes of every stereo frame
};

// True once the count of the main topic (stereo if selected, else imu, else ground truth)
// reaches --frames; never without --frames.
bool TargetReached(const ListenOptions& options, const Received& received) {
  if (options.frames <= 0) return false;
  if (WantsStereo(options)) return received.stereo.count >= options.frames;
  if (WantsImu(options)) return received.imu.count >= options.frames;
  return received.gt.count >= options.frames;
}

// Blocks for up to 5 ms on the main topic's waitset (stereo only when it is not taken by the
// listener); the others are drained on every wake-up.
Status WaitForMainTopic(Subscriptions& subs, bool stereo_by_listener) {
  if (subs.stereo.has_value() && !stereo_by_listener) {
    return subs.stereo->WaitForData(5'000'000).status();
  }
  if (subs.imu.has_value()) return subs.imu->WaitForData(5'000'000).status();
  if (subs.gt.has_value()) return subs.gt->WaitForData(5'000'000).status();
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  return Status::Ok();
}

// Takes every stereo frame waiting (stopping early at the target) and checks each one.
Status DrainStereo(const ListenOptions& options, transport::Reader<mav_dds_StereoFrame>& reader,
                   Received* received) {
  while (true) {
    MAV_ASSIGN_OR_RETURN(auto samples, reader.Take(8));
    if (samples.size() == 0) break;
    const int64_t now_wall = WallNowNs();
    const int64_t now_mono = MonotonicNowNs();
    for (int32_t i = 0; i < samples.size(); ++i) {
      if (!samples.valid(i)) continue;
      const mav_dds_StereoFrame& frame = samples[i];
      received->stereo.Add(static_cast<int64_t>(frame.sequence_number), now_mono);
      const Status check = service_common::CheckStereoFrame(frame);
      if (!check.ok()) {
        ++received->crc_failures;
        if (received->first_error.empty()) received->first_error = check.message();
      }
      received->width = static_cast<int>(frame.width);
      received->height = static_cast<int>(frame.height);
      received->bytes += static_cast<double>(frame.left._length) + frame.right._length;
      const int64_t written_ns = samples.info(i).source_timestamp;
      received->latencies_ms.push_back(static_cast<double>(now_wall - frame.publish_t_ns) * 1e-6);
      received->publisher_ms.push_back(static_cast<double>(written_ns - frame.publish_t_ns) * 1e-6);
      received->dds_ms.push_back(static_cast<double>(now_wall - written_ns) * 1e-6);
      if (TargetReached(options, *received)) break;
    }
    if (TargetReached(options, *received)) break;
  }
  return Status::Ok();
}

// Takes every IMU or ground-truth sample waiting; only their sequence numbers are tracked.
template <typename Sample>
Status DrainSequence(transport::Reader<Sample>& reader, SequenceTracker* tracker) {
  while (true) {
    MAV_ASSIGN_OR_RETURN(auto samples, reader.Take(kTakeBatch));
    if (samples.size() == 0) break;
    const int64_t now_mono = MonotonicNowNs();
    for (int32_t i = 0; i < samples.size(); ++i) {
      if (samples.valid(i))
        tracker->Add(static_cast<int64_t>(samples[i].sequence_number), now_mono);
    }
  }
  return Status::Ok();
}

ListenReport MakeReport(const Received& received) {
  const SequenceTracker& stereo = received.stereo;
  ListenReport report;
  report.frames = stereo.count;
  report.first_sequence = stereo.first;
  report.last_sequence = stereo.expected - 1;
  report.missing = stereo.missing;
  report.missing_examples = stereo.missing_examples;
  report.out_of_order = stereo.out_of_order;
  report.crc_failures = received.crc_failures;
  report.first_error = received.first_error;
  report.width = received.width;
  report.height = received.height;
  report.rate_hz = stereo.RateHz();
  const std::vector<double>& latencies_ms = received.latencies_ms;
  if (!latencies_ms.empty()) {
    double sum = 0;
    for (double v : latencies_ms) sum += v;
    report.latency_mean_ms = sum / static_cast<double>(latencies_ms.size());
    report.latency_p50_ms = Percentile(latencies_ms, 0.5);
    report.latency_p95_ms = Percentile(latencies_ms, 0.95);
    report.latency_p99_ms = Percentile(latencies_ms, 0.99);
    report.latency_max_ms = Percentile(latencies_ms, 1.0);
    report.publisher_p50_ms = Percentile(received.publisher_ms, 0.5);
    report.publisher_p99_ms = Percentile(received.publisher_ms, 0.99);
    report.dds_p50_ms = Percentile(received.dds_ms, 0.5);
    report.dds_p99_ms = Percentile(received.dds_ms, 0.99);
  }
  if (stereo.count >= 2 && stereo.last_receive_ns > stereo.first_receive_ns) {
    // Bytes after the first frame over the time between the first and the last.
    const double per_frame = received.bytes / static_cast<double>(stereo.count);
    report.throughput_mb_s = per_frame * static_cast<double>(stereo.count - 1) /
                             NsToSeconds(stereo.last_receive_ns - stereo.first_receive_ns) / 1e6;
  }
  report.imu_samples = received.imu.count;
  report.imu_missing = received.imu.missing;
  report.imu_rate_hz = received.imu.RateHz();
  report.ground_truth = received.gt.count;
  report.ground_truth_missing = received.gt.missing;
  report.ground_truth_rate_hz = received.gt.RateHz();
  return report;
}

}  // namespace

int64_t ListenOptions::StereoDepth() const {
  if (keep_last >= 0) return keep_last;
  return dds.shared_memory ? kSharedMemoryDepth : 0;
}

bool ListenOptions::IsValid(std::string* why) const {
  if (topic != "stereo" && topic != "imu" && topic != "ground_truth" && topic != "all") {
    if (why != nullptr)
      *why = "--topic: " + QuoteForError(topic) + " is not one of stereo|imu|ground_truth|all";
    return false;
  }
  if (wake != "listener" && wake != "waitset") {
    if (why != nullptr) *why = "--wake: " + QuoteForError(wake) + " is not one of listener|waitset";
    return false;
  }
  if (frames < 0) {
    if (why != nullptr) *why = "--frames: must be >= 0, got " + std::to_string(frames);
    return false;
  }
  if (keep_last < -1 || keep_last > 256) {
    if (why != nullptr) {
      *why = "--keep-last: must be 0 (keep all) or 1..256, got " + std::to_string(keep_last);
    }
    return false;
  }
  if (!(timeout_s > 0.0)) {
    if (why != nullptr) *why = "--timeout: must be > 0 s";
    return false;
  }
  return dds.IsValid(why);
}

Result<ListenReport> Listen(const ListenOptions& options, std::ostream& progress) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  MAV_ASSIGN_OR_RETURN(transport::Participant participant,
                       transport::Participant::Create(options.dds));
  // `received` is shared with the listener's thread (Cyclone's receive thread) when it takes the
  // stereo frames; its first error ends the loop. Declared before the subscriptions so that on
  // every return the readers (whose destructors remove the listener and wait for a call in
  // progress) go first.
  std::mutex mutex;
  Received received;
  Status listener_error;
  Subscriptions subs;
  MAV_RETURN_IF_ERROR(Subscribe(participant, options, &subs));

  const bool stereo_by_listener = subs.stereo.has_value() && options.wake == "listener";
  if (stereo_by_listener) {
    MAV_RETURN_IF_ERROR(subs.stereo->OnData([&] {
      std::lock_guard<std::mutex> lock(mutex);
      if (!listener_error.ok() || TargetReached(options, received)) return;
      listener_error = DrainStereo(options, *subs.stereo, &received);
    }));
  }
  const int64_t start_ns = MonotonicNowNs();
  const int64_t end_ns = start_ns + SecondsToNs(options.timeout_s);
  int64_t next_progress_ns = start_ns + kNsPerSecond;
  while (MonotonicNowNs() < end_ns) {
    MAV_RETURN_IF_ERROR(WaitForMainTopic(subs, stereo_by_listener));
    std::lock_guard<std::mutex> lock(mutex);
    MAV_RETURN_IF_ERROR(listener_error);
    if (subs.stereo.has_value() && !stereo_by_listener) {
      MAV_RETURN_IF_ERROR(DrainStereo(options, *subs.stereo, &received));
    }
    if (subs.imu.has_value()) MAV_RETURN_IF_ERROR(DrainSequence(*subs.imu, &received.imu));
    if (subs.gt.has_value()) MAV_RETURN_IF_ERROR(DrainSequence(*subs.gt, &received.gt));
    if (TargetReached(options, received)) break;
    if (options.progress && MonotonicNowNs() >= next_progress_ns) {
      next_progress_ns += kNsPerSecond;
      progress << "  t=" << std::fixed << std::setprecision(0)
               << NsToSeconds(MonotonicNowNs() - start_ns) << " s: stereo " << received.stereo.count
               << ", imu " << received.imu.count << ", ground truth " << received.gt.count
               << std::endl;
    }
  }
  if (stereo_by_listener) MAV_RETURN_IF_ERROR(subs.stereo->ClearOnData());

  std::lock_guard<std::mutex> lock(mutex);
  const bool reached_target = TargetReached(options, received);
  const double elapsed_s = NsToSeconds(MonotonicNowNs() - start_ns);
  ListenReport report = MakeReport(received);
  report.reached_target = reached_target;
  report.elapsed_s = elapsed_s;
  if (subs.stereo.has_value()) {
    report.stereo_depth = options.StereoDepth();
    report.stereo_shared_memory = subs.stereo->UsesSharedMemory();
  }
  return report;
}

bool ReportPassed(const ListenOptions& options, const ListenReport& report) {
  if (options.frames > 0 && !report.reached_target) return false;
  return report.missing == 0 && report.crc_failures == 0 && report.out_of_order == 0;
}

void PrintReport(const ListenOptions& options, const ListenReport& report, std::ostream& out) {
  out << std::fixed;
  const bool want_stereo = WantsStereo(options);
  const bool want_imu = WantsImu(options);
  const bool want_gt = WantsGroundTruth(options);
  out << "listened " << std::setprecision(1) << report.elapsed_s << " s on DDS domain "
      << options.dds.domain << (report.reached_target ? " (target reached)" : "") << "\n";
  if (want_stereo) {
    out << "stereo:       " << report.frames << " frames";
    if (report.frames > 0) {
      out << " (seq " << report.first_sequence << ".." << report.last_sequence << ", "
          << report.width << "x" << report.height << ")";
    }
    out << ", " << (report.stereo_shared_memory ? "shared memory" : "udp") << ", "
        << (report.stereo_depth == 0 ? std::string("keep all")
                                     : "keep last " + std::to_string(report.stereo_depth));
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
        << report.latency_p95_ms << " ms, p99 " << report.latency_p99_ms << " ms, max "
        << report.latency_max_ms << " ms\n";
    out << "              hops p50 / p99: publisher (stamp -> dds_write) "
        << report.publisher_p50_ms << " / " << report.publisher_p99_ms
        << " ms, DDS (dds_write -> take, " << options.wake << ") " << report.dds_p50_ms << " / "
        << report.dds_p99_ms << " ms\n";
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
      << " ground_truth=" << report.ground_truth << " shm=" << (report.stereo_shared_memory ? 1 : 0)
      << " passed=" << (ReportPassed(options, report) ? 1 : 0) << "\n";
}

}  // namespace mav::mavctl
