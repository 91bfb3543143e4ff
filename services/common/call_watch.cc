#include "services/common/call_watch.h"

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <unordered_set>

#include <grpcpp/server_context.h>

#include "mav/common/time.h"

namespace mav::service_common {

// The process's one watcher thread: started with the first watch, asleep while nothing is
// watched, joined at exit. Every access to a watched context happens under `mutex_`, and a
// CallWatch leaves the set under it before its context can go, so no context is read after its
// call ended.
class CallWatcher {
 public:
  static CallWatcher& Instance() {
    static CallWatcher watcher;
    return watcher;
  }

  void Add(CallWatch* call) {
    std::lock_guard<std::mutex> lock(mutex_);
    calls_.insert(call);
    if (!thread_.joinable()) thread_ = std::thread([this] { Loop(); });
    wake_.notify_one();
  }
  void Remove(CallWatch* call) {
    std::lock_guard<std::mutex> lock(mutex_);
    calls_.erase(call);
  }
  int size() {
    std::lock_guard<std::mutex> lock(mutex_);
    return static_cast<int>(calls_.size());
  }

  ~CallWatcher() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    if (thread_.joinable()) thread_.join();
  }

 private:
  CallWatcher() = default;

  void Loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stop_) {
      if (calls_.empty()) {
        wake_.wait(lock, [this] { return stop_ || !calls_.empty(); });
        continue;
      }
      for (CallWatch* call : calls_) {
        // A call past its deadline is cancelled too, but its Termination says why already
        // (DEADLINE_EXCEEDED rather than CANCELLED).
        if (call->cancel_.cancelled() || call->termination_.expired()) continue;
        if (call->context_->IsCancelled()) call->cancel_.Cancel();
      }
      wake_.wait_for(lock, std::chrono::milliseconds(CallWatch::kPollMs), [this] { return stop_; });
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::unordered_set<CallWatch*> calls_;
  bool stop_ = false;
  std::thread thread_;
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
