#pragma once
// The one bounded work queue of the stack: a single worker thread that owns the algorithm object
// of a service (a visual odometry, a mapper, a player, a planner's builder) and runs the tasks
// submitted from RPC handlers and DDS readers one at a time, in order.
//
//   WorkQueue queue(WorkQueueOptions::Named("localization", /*capacity=*/2));
//   Ticket<Result<Pose>> t = queue.Submit<Result<Pose>>(
//       [&](const TaskContext& ctx) { return vo.Process(frame); }, QueuePolicy::kReject, deadline);
//   Result<Pose> pose = t.Wait(deadline);   // DEADLINE_EXCEEDED: withdrawn, never ran
//
// Bounded: at most `capacity` tasks wait; a full queue refuses a kReject task (RESOURCE_EXHAUSTED)
// and makes room for a kDropOldest task by dropping the oldest waiting kDropOldest task (live
// sensor data: the newest frame matters most). Memory is the capacity times a task's captures.
//
// Deadlines: a task carries the submitter's Termination. It is refused at submission when the
// termination has already stopped, skipped (never run) when it has stopped by the time the
// worker takes it, and withdrawn from the queue when Ticket::Wait gives up on it. So a call whose
// deadline expired before its task started changes nothing. A running task is not interrupted:
// it may poll ctx.ShouldStop() between stages.
//
// Generations: Reset() discards the waiting tasks (CANCELLED with its reason), bumps the
// generation (the running task sees ctx.stale() and should stop early) and waits for the running
// task to return. SubmitAfterReset() does the same and then queues its task first, atomically:
// nothing submitted meanwhile runs before it (a Configure that swaps the algorithm object never
// races a frame).
//
// Thread-safety: every method may be called from any thread except the worker itself (Reset,
// Stop and a resetting Submit wait for the worker: calling them from a task is a bug, checked).

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/common/time.h"

namespace mav {

enum class QueuePolicy {
  kReject,      // a full queue refuses this task
  kDropOldest,  // a full queue drops its oldest waiting kDropOldest task to make room for this
                // one; this one may be dropped in turn (live sensor data)
  kMakeRoom,    // as kDropOldest, but this task is never dropped (a build behind live frames)
};

struct WorkQueueOptions {
  std::string name = "work queue";  // names the queue in messages ("localization: queue full")
  size_t capacity = 16;             // waiting tasks (the running one not counted), >= 1
  size_t stats_window = 1000;       // run times kept for the statistics, >= 1
  // The clock of TaskContext::SleepUntil / NowNs and of the run times; null: the monotonic
  // clock. Tests pass one they move by hand (it must outlive the queue). A task's deadline is on
  // its Termination's own clock.
  const TimeSource* time_source = nullptr;

  static WorkQueueOptions Named(std::string name, size_t capacity) {
    WorkQueueOptions o;
    o.name = std::move(name);
    o.capacity = capacity;
    return o;
  }
  bool IsValid(std::string* why) const;
};

struct WorkQueueStats {
  uint64_t submitted = 0;  // accepted into the queue
  uint64_t completed = 0;  // ran to the end
  uint64_t rejected = 0;   // refused at submission (full, stopped, expired)
  uint64_t dropped = 0;    // dropped from a full queue to make room (kDropOldest)
  uint64_t expired = 0;    // skipped or withdrawn: their termination stopped before they ran
  uint64_t cancelled = 0;  // discarded by Reset() or Stop()
  size_t depth = 0;        // waiting now
  bool busy = false;       // a task is running
  uint64_t generation = 0;
  RuntimeStats run_ms;  // of the last stats_window tasks that ran
};

class WorkQueue;
class TaskContext;

namespace internal {

struct QueueCore;

struct TaskBase {
  enum Phase : int { kQueued = 0, kRunning = 1, kFinished = 2, kWithdrawn = 3 };
  std::atomic<int> phase{kQueued};
  std::atomic<bool> ran{false};  // the worker called Run
  QueuePolicy policy = QueuePolicy::kReject;
  Termination termination;
  uint64_t generation = 0;

  virtual ~TaskBase() = default;
  // Runs the task and keeps its result; Publish() hands it to the ticket (after the queue's
  // statistics count the task, so a waiter that wakes up sees them).
  virtual void Run(const TaskContext& context) = 0;
  virtual void Publish() = 0;
  virtual void Fail(const Status& status) = 0;
};

template <typename R>
struct Task final : TaskBase {
  std::function<R(const TaskContext&)> fn;
  std::promise<R> promise;
  std::optional<R> result;
  void Run(const TaskContext& context) override {
    result.emplace(fn(context));
    fn = nullptr;  // release the captures (frames, maps) before the result is published
  }
  void Publish() override { promise.set_value(std::move(*result)); }
  void Fail(const Status& status) override { promise.set_value(R(status)); }
};

// Shared by the queue, its worker, the running task's context and the tickets (a ticket may
// outlive the queue).
struct QueueCore {
  WorkQueueOptions options;
  mutable std::mutex mutex;
  std::condition_variable work_cv;  // wakes the worker
  std::condition_variable idle_cv;  // wakes Reset/Stop waiting for the running task
  std::condition_variable wake_cv;  // wakes a task sleeping in TaskContext::SleepUntil
  std::deque<std::shared_ptr<TaskBase>> queue;
  std::atomic<uint64_t> generation{0};
  std::atomic<bool> stopping{false};
  bool hold = false;  // a resetting Submit is waiting for the running task: take nothing new
  bool busy = false;
  std::thread::id worker_id;
  WorkQueueStats counters;  // everything but depth/busy/generation/run_ms
  RuntimeWindow run_ms;

  explicit QueueCore(WorkQueueOptions o) : options(std::move(o)), run_ms(options.stats_window) {}
  // Withdraws a waiting task (true), or false when it already started or finished.
  bool Withdraw(const std::shared_ptr<TaskBase>& task);
};

}  // namespace internal

// What a running task sees.
class TaskContext {
 public:
  uint64_t generation() const { return generation_; }
  // True once Reset() or Stop() happened after the task was submitted: stop early, its result
  // will be discarded by whoever reset the queue.
  bool stale() const;
  const Termination& termination() const { return termination_; }
  bool ShouldStop() const { return stale() || termination_.ShouldStop(); }
  // The queue's clock (WorkQueueOptions::time_source; by default MonotonicNowNs()).
  int64_t NowNs() const;
  // Sleeps until NowNs() >= wake_ns; returns false early when ShouldStop() becomes true (Reset,
  // Stop, or the task's own termination). For paced work such as real-time playback.
  bool SleepUntil(int64_t wake_ns) const;

 private:
  friend class WorkQueue;
  TaskContext(internal::QueueCore* core, uint64_t generation, Termination termination)
      : core_(core), generation_(generation), termination_(std::move(termination)) {}
  internal::QueueCore* core_;
  uint64_t generation_;
  Termination termination_;
};

// The handle of a submitted task. R is the task's return type: Status or Result<T>.
template <typename R>
class Ticket {
 public:
  // OK when the task was queued; else why it was refused (RESOURCE_EXHAUSTED when full,
  // UNAVAILABLE when stopped, DEADLINE_EXCEEDED / CANCELLED when its termination had stopped).
  const Status& submit_status() const { return submit_status_; }
  bool accepted() const { return submit_status_.ok(); }
  // The queue was full and the oldest kDropOldest task was dropped for this one.
  bool dropped_oldest() const { return dropped_oldest_; }
  // The worker ran (or is running) the task: its effects happen whatever Wait returned.
  bool ran() const { return task_ != nullptr && task_->ran.load(); }

  // The task's result. Waits until `termination` stops; then a task that has not started is
  // withdrawn (it never runs) and DEADLINE_EXCEEDED / CANCELLED is returned; for a task already
  // running DEADLINE_EXCEEDED / CANCELLED is returned at once (it runs on; its effect may land).
  // Without a termination, waits until the task ran or was discarded.
  R Wait(const Termination& termination = {}) {
    if (!submit_status_.ok()) return R(submit_status_);
    MAV_CHECK(future_.valid()) << "Ticket::Wait called twice";
    while (true) {
      const int64_t remaining = termination.RemainingNs();
      // Poll the cancel flag at least every 50 ms.
      const int64_t slice = std::min<int64_t>(remaining, 50'000'000);
      if (slice > 0 &&
          future_.wait_for(std::chrono::nanoseconds(slice)) == std::future_status::ready) {
        return future_.get();
      }
      if (future_.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
        return future_.get();
      }
      if (termination.ShouldStop()) {
        const bool withdrawn = core_->Withdraw(task_);
        if (!withdrawn && future_.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
          return future_.get();
        }
        const std::string what = core_->options.name + (withdrawn ? "" : " (the task runs on)");
        return R(termination.Check(what));
      }
    }
  }

 private:
  friend class WorkQueue;
  Status submit_status_;
  bool dropped_oldest_ = false;
  std::shared_ptr<internal::QueueCore> core_;
  std::shared_ptr<internal::TaskBase> task_;
  std::future<R> future_;
};

class WorkQueue {
 public:
  // MAV_CHECKs valid options (a programming error: the options are the service's own).
  explicit WorkQueue(WorkQueueOptions options);
  ~WorkQueue();  // Stop()
  WorkQueue(const WorkQueue&) = delete;
  WorkQueue& operator=(const WorkQueue&) = delete;

  // Queues `fn` (called on the worker as fn(const TaskContext&) and returning R: Status or a
  // Result<T>). `termination` is the submitter's deadline / cancel flag (see the file comment).
  template <typename R, typename Fn>
  Ticket<R> Submit(Fn&& fn, QueuePolicy policy = QueuePolicy::kReject,
                   Termination termination = {}) {
    return SubmitImpl<R>(std::forward<Fn>(fn), policy, std::move(termination), "");
  }

  // Reset(reset_reason), then queues `fn` ahead of everything, atomically: nothing submitted
  // meanwhile runs before it. For the calls that replace the worker's object (Configure).
  template <typename R, typename Fn>
  Ticket<R> SubmitAfterReset(Fn&& fn, const std::string& reset_reason,
                             Termination termination = {}) {
    MAV_CHECK(!reset_reason.empty()) << "SubmitAfterReset needs a reason";
    return SubmitImpl<R>(std::forward<Fn>(fn), QueuePolicy::kReject, std::move(termination),
                         reset_reason);
  }

  // Discards the waiting tasks (CANCELLED "<name>: <why>"), bumps the generation and waits for
  // the running task to return. Returns the new generation.
  uint64_t Reset(const std::string& why);

  // Refuses new tasks, discards the waiting ones (UNAVAILABLE "<name>: <why>"), waits for the
  // running one and joins the worker. Idempotent.
  void Stop(const std::string& why = "shutting down");

  // Changes the capacity (>= 1, MAV_CHECKed); tasks already waiting beyond it stay queued.
  void SetCapacity(size_t capacity);

  WorkQueueStats GetStats() const;
  uint64_t generation() const { return core_->generation.load(); }
  const std::string& name() const { return core_->options.name; }
  size_t capacity() const;
  // True on the worker thread (for MAV_CHECKs of code that must run there).
  bool OnWorkerThread() const;

 private:
  template <typename R, typename Fn>
  Ticket<R> SubmitImpl(Fn&& fn, QueuePolicy policy, const Termination& termination,
                       const std::string& reset_reason) {
    static_assert(std::is_constructible_v<R, Status>, "R must be Status or Result<T>");
    auto task = std::make_shared<internal::Task<R>>();
    task->fn = std::forward<Fn>(fn);
    task->policy = policy;
    task->termination = termination;
    Ticket<R> ticket;
    ticket.core_ = core_;
    ticket.task_ = task;
    ticket.future_ = task->promise.get_future();
    ticket.submit_status_ = Enqueue(task, reset_reason, &ticket.dropped_oldest_);
    return ticket;
  }
  Status Enqueue(std::shared_ptr<internal::TaskBase> task, const std::string& reset_reason,
                 bool* dropped_oldest);
  // With the lock held: discards the waiting tasks, bumps the generation, waits for the worker.
  void ResetLocked(std::unique_lock<std::mutex>* lock, const Status& why);
  void WorkerLoop();

  std::shared_ptr<internal::QueueCore> core_;
  std::thread worker_;
};

}  // namespace mav
