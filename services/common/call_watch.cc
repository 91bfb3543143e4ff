#include "services/common/call_watch.h"

#include <chrono>
#include <mutex>
#include <unordered_set>

#include <grpcpp/server_context.h>

#include "mav/common/time.h"
#include "mav/common/work_queue.h"

namespace mav::service_common {

// The process's one watcher: a task on its own work queue (libs/common's WorkQueue), submitted
// with the first watch and ending when no call is watched, so an idle process polls nothing; the
// queue is stopped and joined at exit. Every access to a watched context happens under `mutex_`,
// and a CallWatch leaves the set under it before its context can go, so no context is read after
// its call ended.
class CallWatcher {
 public:
  static CallWatcher& Instance() {
    static CallWatcher watcher;
    return watcher;
  }

  void Add(CallWatch* call) {
    std::lock_guard<std::mutex> lock(mutex_);
    calls_.insert(call);
    if (polling_) return;
    polling_ = true;
    const Ticket<Status> ticket = queue_.Submit<Status>([this](const TaskContext& context) {
      Poll(context);
      return Status::Ok();
    });
    // Refused only while the queue stops (process exit): nothing is watched then.
    if (!ticket.accepted()) polling_ = false;
  }
  void Remove(CallWatch* call) {
    std::lock_guard<std::mutex> lock(mutex_);
    calls_.erase(call);
  }
  int size() {
    std::lock_guard<std::mutex> lock(mutex_);
    return static_cast<int>(calls_.size());
  }

 private:
  CallWatcher() = default;

  // Runs until no call is watched (or the queue stops).
  void Poll(const TaskContext& context) {
    while (true) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (calls_.empty()) {
          polling_ = false;
          return;
        }
        for (CallWatch* call : calls_) {
          // A call past its deadline is cancelled too, but its Termination says why already
          // (DEADLINE_EXCEEDED rather than CANCELLED).
          if (call->cancel_.cancelled() || call->termination_.expired()) continue;
          if (call->context_->IsCancelled()) call->cancel_.Cancel();
        }
      }
      if (!context.SleepUntil(context.NowNs() + CallWatch::kPollMs * 1'000'000)) {
        std::lock_guard<std::mutex> lock(mutex_);
        polling_ = false;
        return;
      }
    }
  }

  std::mutex mutex_;
  std::unordered_set<CallWatch*> calls_;
  bool polling_ = false;  // the poll task is queued or running
  WorkQueue queue_{WorkQueueOptions::Named("call watch", 1)};
};

CallWatch::CallWatch(grpc::ServerContext* context)
    : context_(context), termination_(DeadlineOf(*context).WithCancel(cancel_)) {
  CallWatcher::Instance().Add(this);
}

CallWatch::~CallWatch() { CallWatcher::Instance().Remove(this); }

int CallWatch::Watched() { return CallWatcher::Instance().size(); }

Termination DeadlineOf(const grpc::ServerContext& context) {
  const auto deadline = context.deadline();
  if (deadline == std::chrono::system_clock::time_point::max()) return Termination::Never();
  const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
                        deadline - std::chrono::system_clock::now())
                        .count();
  return Termination::AtMonotonicNs(MonotonicNowNs() + left);
}

}  // namespace mav::service_common
