#include "mav/common/work_queue.h"

#include <algorithm>
#include <chrono>

#include "mav/common/check.h"
#include "mav/common/time.h"

namespace mav {

namespace internal {

bool QueueCore::Withdraw(const std::shared_ptr<TaskBase>& task) {
  std::lock_guard<std::mutex> lock(mutex);
  int expected = TaskBase::kQueued;
  if (!task->phase.compare_exchange_strong(expected, TaskBase::kWithdrawn)) return false;
  const auto it = std::find(queue.begin(), queue.end(), task);
  if (it != queue.end()) queue.erase(it);
  ++counters.expired;
  return true;
}

}  // namespace internal

bool WorkQueueOptions::IsValid(std::string* why) const {
  if (capacity < 1) {
    if (why != nullptr) *why = "capacity: must be >= 1";
    return false;
  }
  if (stats_window < 1) {
    if (why != nullptr) *why = "stats_window: must be >= 1";
    return false;
  }
  return true;
}

bool TaskContext::stale() const {
  return core_->stopping.load() || core_->generation.load() != generation_;
}

int64_t TaskContext::NowNs() const { return mav::NowNs(core_->options.time_source); }

bool TaskContext::SleepUntil(int64_t wake_ns) const {
  std::unique_lock<std::mutex> lock(core_->mutex);
  while (!ShouldStop()) {
    const int64_t now = NowNs();
    if (now >= wake_ns) return true;
    // Wake at least every 50 ms to see a raised cancel flag, a passed deadline or a clock that
    // a test moved.
    const int64_t wait = std::min<int64_t>(wake_ns - now, 50'000'000);
    core_->wake_cv.wait_for(lock, std::chrono::nanoseconds(wait));
  }
  return false;
}

WorkQueue::WorkQueue(WorkQueueOptions options)
    : core_(std::make_shared<internal::QueueCore>(std::move(options))) {
  std::string why;
  MAV_CHECK(core_->options.IsValid(&why)) << "work queue '" << core_->options.name << "': " << why;
  worker_ = std::thread([this] { WorkerLoop(); });
  std::lock_guard<std::mutex> lock(core_->mutex);
  core_->worker_id = worker_.get_id();
}

WorkQueue::~WorkQueue() { Stop(); }

bool WorkQueue::OnWorkerThread() const { return std::this_thread::get_id() == worker_.get_id(); }

Status WorkQueue::Enqueue(std::shared_ptr<internal::TaskBase> task, const std::string& reset_reason,
                          bool* dropped_oldest) {
  const std::string& name = core_->options.name;
  if (Status s = task->termination.Check(name); !s.ok()) {
    std::lock_guard<std::mutex> lock(core_->mutex);
    ++core_->counters.rejected;
    return s;
  }
  std::unique_lock<std::mutex> lock(core_->mutex);
  if (core_->stopping) {
    ++core_->counters.rejected;
    return Status::Unavailable(name + ": shutting down");
  }
  if (!reset_reason.empty()) {
    MAV_CHECK(!OnWorkerThread()) << name << ": a resetting Submit from the worker would deadlock";
    ResetLocked(&lock, Status::Cancelled(name + ": " + reset_reason));
    if (core_->stopping) {
      ++core_->counters.rejected;
      return Status::Unavailable(name + ": shutting down");
    }
    task->generation = core_->generation.load();
    core_->queue.push_front(std::move(task));
    ++core_->counters.submitted;
    core_->work_cv.notify_one();
    return Status::Ok();
  }
  auto& queue = core_->queue;
  if (queue.size() >= core_->options.capacity) {
    const auto droppable =
        task->policy != QueuePolicy::kReject
            ? std::find_if(queue.begin(), queue.end(),
                           [](const auto& t) { return t->policy == QueuePolicy::kDropOldest; })
            : queue.end();
    if (droppable == queue.end()) {
      ++core_->counters.rejected;
      return Status::ResourceExhausted(name + ": queue full (" + std::to_string(queue.size()) +
                                       " waiting, capacity " +
                                       std::to_string(core_->options.capacity) + ")");
    }
    std::shared_ptr<internal::TaskBase> dropped = std::move(*droppable);
    queue.erase(droppable);
    dropped->phase = internal::TaskBase::kFinished;
    dropped->Fail(Status::ResourceExhausted(name + ": dropped to make room for newer input"));
    ++core_->counters.dropped;
    if (dropped_oldest != nullptr) *dropped_oldest = true;
  }
  task->generation = core_->generation.load();
  queue.push_back(std::move(task));
  ++core_->counters.submitted;
  core_->work_cv.notify_one();
  return Status::Ok();
}

void WorkQueue::ResetLocked(std::unique_lock<std::mutex>* lock, const Status& why) {
  for (const auto& task : core_->queue) {
    task->phase = internal::TaskBase::kFinished;
    task->Fail(why);
    ++core_->counters.cancelled;
  }
  core_->queue.clear();
  ++core_->generation;
  core_->wake_cv.notify_all();
  core_->hold = true;
  core_->idle_cv.wait(*lock, [&] { return !core_->busy; });
  core_->hold = false;
}

uint64_t WorkQueue::Reset(const std::string& why) {
  MAV_CHECK(!OnWorkerThread()) << name() << ": Reset from the worker would deadlock";
  std::unique_lock<std::mutex> lock(core_->mutex);
  ResetLocked(&lock, Status::Cancelled(name() + ": " + why));
  core_->work_cv.notify_one();
  return core_->generation.load();
}

void WorkQueue::Stop(const std::string& why) {
  {
    std::unique_lock<std::mutex> lock(core_->mutex);
    if (!core_->stopping) {
      MAV_CHECK(!OnWorkerThread()) << name() << ": Stop from the worker would deadlock";
      core_->stopping = true;
      const Status status = Status::Unavailable(name() + ": " + why);
      for (const auto& task : core_->queue) {
        task->phase = internal::TaskBase::kFinished;
        task->Fail(status);
        ++core_->counters.cancelled;
      }
      core_->queue.clear();
      ++core_->generation;
      core_->wake_cv.notify_all();
      core_->work_cv.notify_all();
    }
  }
  if (worker_.joinable() && !OnWorkerThread()) worker_.join();
}

void WorkQueue::SetCapacity(size_t capacity) {
  MAV_CHECK(capacity >= 1) << name() << ": capacity must be >= 1";
  std::lock_guard<std::mutex> lock(core_->mutex);
  core_->options.capacity = capacity;
}

size_t WorkQueue::capacity() const {
  std::lock_guard<std::mutex> lock(core_->mutex);
  return core_->options.capacity;
}

WorkQueueStats WorkQueue::GetStats() const {
  std::lock_guard<std::mutex> lock(core_->mutex);
  WorkQueueStats s = core_->counters;
  s.depth = core_->queue.size();
  s.busy = core_->busy;
  s.generation = core_->generation.load();
  s.run_ms = core_->run_ms.Summary();
  return s;
}

void WorkQueue::WorkerLoop() {
  internal::QueueCore& core = *core_;
  std::unique_lock<std::mutex> lock(core.mutex);
  while (true) {
    core.work_cv.wait(lock, [&] { return core.stopping || (!core.hold && !core.queue.empty()); });
    if (core.stopping) return;
    std::shared_ptr<internal::TaskBase> task = std::move(core.queue.front());
    core.queue.pop_front();
    int expected = internal::TaskBase::kQueued;
    if (!task->phase.compare_exchange_strong(expected, internal::TaskBase::kRunning)) continue;
    if (Status s = task->termination.Check(core.options.name); !s.ok()) {
      task->phase = internal::TaskBase::kFinished;
      task->Fail(s);
      ++core.counters.expired;
      continue;
    }
    core.busy = true;
    task->ran = true;
    lock.unlock();
    const TimeSource* time_source = core.options.time_source;
    const int64_t start_ns = NowNs(time_source);
    task->Run(TaskContext(&core, task->generation, task->termination));
    const double ms = NsToSeconds(NowNs(time_source) - start_ns) * 1e3;
    task->phase = internal::TaskBase::kFinished;
    lock.lock();
    core.busy = false;
    ++core.counters.completed;
    core.run_ms.Add(ms);
    core.idle_cv.notify_all();
    lock.unlock();
    task->Publish();
    task.reset();
    lock.lock();
  }
}

}  // namespace mav
