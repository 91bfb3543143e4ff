#pragma once
// The one DDS read loop of the services: a thread that sleeps until the wake reader has data (or
// a poll period passes), then drains every other reader first, in the order they were added, then
// the wake reader, handing each valid sample to its handler, then calls the poll callback.
//
//   DdsReadLoop loop("mapping input");
//   loop.AddReader(&pose_reader, [&](const mav_dds_GroundTruthState& s) { mapper.AddPose(...); });
//   loop.SetWakeReader(&stereo_reader, [&](const mav_dds_StereoFrame& f) { ... }, /*batch=*/4);
//   loop.SetOnPoll([&] { mapper.Tick(); });
//   MAV_RETURN_IF_ERROR(loop.Start());
//   ...
//   loop.Stop();  // joins; the readers and handlers must outlive the loop until then
//
// Draining the other readers first keeps causality for the services: a frame finds the poses
// published before it (mapping), a control step finds the delayed pose that arrived before its
// IMU sample (control). Handlers run on the loop's thread and must not block for long: they hand
// work to a WorkQueue (mav/common/work_queue.h).

#include <atomic>
#include <functional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "mav/common/log.h"
#include "mav/common/status.h"
#include "mav/transport/dds.h"

namespace mav::transport {

class DdsReadLoop {
 public:
  explicit DdsReadLoop(std::string name, int64_t poll_ns = 100'000'000)
      : name_(std::move(name)), poll_ns_(poll_ns) {}
  ~DdsReadLoop() { Stop(); }
  DdsReadLoop(const DdsReadLoop&) = delete;
  DdsReadLoop& operator=(const DdsReadLoop&) = delete;

  // A reader drained on every wake, before the wake reader. Call before Start().
  template <typename T>
  void AddReader(Reader<T>* reader, std::function<void(const T&)> on_sample, int32_t batch = 64) {
    drains_.push_back(MakeDrain(reader, std::move(on_sample), batch));
  }
  // The reader whose data wakes the loop. Exactly one; call before Start().
  template <typename T>
  void SetWakeReader(Reader<T>* reader, std::function<void(const T&)> on_sample,
                     int32_t batch = 16) {
    wake_ = MakeDrain(reader, std::move(on_sample), batch);
    wait_ = [reader](int64_t timeout_ns) { return reader->WaitForData(timeout_ns); };
  }
  // Called after each wake or poll period (e.g. to expire stale work).
  void SetOnPoll(std::function<void()> on_poll) { on_poll_ = std::move(on_poll); }

  // FailedPrecondition without a wake reader or when already running.
  Status Start() {
    if (!wake_) return Status::FailedPrecondition(name_ + ": no wake reader");
    if (thread_.joinable()) return Status::FailedPrecondition(name_ + ": already running");
    stop_ = false;
    thread_ = std::thread([this] { Run(); });
    return Status::Ok();
  }
  // Stops and joins (idempotent). The loop finishes the sample in hand first.
  void Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  bool running() const { return thread_.joinable(); }

 private:
  template <typename T>
  std::function<void()> MakeDrain(Reader<T>* reader, std::function<void(const T&)> on_sample,
                                  int32_t batch) {
    return [this, reader, on_sample = std::move(on_sample), batch] {
      while (!stop_) {
        Result<LoanedSamples<T>> samples = reader->Take(batch);
        if (!samples.ok()) {
          MAV_LOG(kWarning) << name_ << ": " << samples.status().ToString();
          return;
        }
        for (int32_t i = 0; i < samples->size(); ++i) {
          if (samples->valid(i)) on_sample((*samples)[i]);
        }
        if (samples->size() < batch) return;
      }
    };
  }

  void Run() {
    while (!stop_) {
      Result<bool> ready = wait_(poll_ns_);
      if (!ready.ok()) {
        MAV_LOG(kWarning) << name_ << ": " << ready.status().ToString();
      }
      for (const auto& drain : drains_) drain();
      if (ready.ok() && *ready) wake_();
      if (on_poll_) on_poll_();
    }
  }

  std::string name_;
  int64_t poll_ns_;
  std::vector<std::function<void()>> drains_;
  std::function<void()> wake_;
  std::function<Result<bool>(int64_t)> wait_;
  std::function<void()> on_poll_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace mav::transport
