#include "mav/common/work_queue.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <random>
#include <thread>
#include <vector>

#include "mav/common/time.h"

namespace mav {
namespace {

using namespace std::chrono_literals;

// A task that blocks the worker until released, so tests can fill the queue deterministically.
class Gate {
 public:
  void Open() {
    std::lock_guard<std::mutex> lock(mutex_);
    open_ = true;
    cv_.notify_all();
  }
  void WaitOpen() {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [&] { return open_; });
  }
  void MarkEntered() { entered_ = true; }
  void WaitEntered() {
    while (!entered_) std::this_thread::sleep_for(1ms);
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool open_ = false;
  std::atomic<bool> entered_{false};
};

Ticket<Status> BlockOn(WorkQueue* queue, Gate* gate) {
  auto t = queue->Submit<Status>([gate](const TaskContext&) {
    gate->MarkEntered();
    gate->WaitOpen();
    return Status::Ok();
  });
  gate->WaitEntered();
  return t;
}

TEST(WorkQueueTest, RunsTasksInOrderAndReturnsResults) {
  WorkQueue queue(WorkQueueOptions::Named("q", 8));
  std::vector<int> order;
  std::vector<Ticket<Result<int>>> tickets;
  tickets.reserve(5);
  for (int i = 0; i < 5; ++i) {
    tickets.push_back(queue.Submit<Result<int>>([i, &order](const TaskContext&) -> Result<int> {
      order.push_back(i);
      return i * i;
    }));
  }
  for (int i = 0; i < 5; ++i) {
    Result<int> r = tickets[i].Wait();
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(*r, i * i);
  }
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3, 4}));
  const WorkQueueStats s = queue.GetStats();
  EXPECT_EQ(s.submitted, 5u);
  EXPECT_EQ(s.completed, 5u);
  EXPECT_EQ(s.run_ms.count, 5u);
}

TEST(WorkQueueTest, FullQueueRejectsOrDropsTheOldestLiveTask) {
  WorkQueue queue(WorkQueueOptions::Named("loc", 2));
  Gate gate;
  auto blocker = BlockOn(&queue, &gate);
  auto live1 = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); },
                                    QueuePolicy::kDropOldest);
  auto unary = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); });
  ASSERT_TRUE(live1.accepted());
  ASSERT_TRUE(unary.accepted());
  // Full: a unary task is refused...
  auto refused = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); });
  EXPECT_EQ(refused.submit_status().code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(refused.submit_status().message(), "loc: queue full (2 waiting, capacity 2)");
  EXPECT_EQ(refused.Wait().code(), StatusCode::kResourceExhausted);
  // ...a live one replaces the oldest live one.
  std::atomic<bool> live2_ran{false};
  auto live2 = queue.Submit<Status>(
      [&](const TaskContext&) {
        live2_ran = true;
        return Status::Ok();
      },
      QueuePolicy::kDropOldest);
  EXPECT_TRUE(live2.accepted());
  EXPECT_TRUE(live2.dropped_oldest());
  EXPECT_EQ(live1.Wait().code(), StatusCode::kResourceExhausted);
  // No live task left to drop: the new live task is refused.
  auto live3 = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); },
                                    QueuePolicy::kDropOldest);
  EXPECT_TRUE(live3.accepted());  // live2 was droppable
  auto live4 = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); },
                                    QueuePolicy::kDropOldest);
  EXPECT_TRUE(live4.dropped_oldest());
  gate.Open();
  EXPECT_TRUE(blocker.Wait().ok());
  EXPECT_TRUE(unary.Wait().ok());
  EXPECT_TRUE(live4.Wait().ok());
  EXPECT_FALSE(live2_ran);
  const WorkQueueStats s = queue.GetStats();
  EXPECT_EQ(s.dropped, 3u);
  EXPECT_EQ(s.rejected, 1u);
}

TEST(WorkQueueTest, ExpiredTerminationIsRefusedAtSubmissionAndNeverRuns) {
  WorkQueue queue(WorkQueueOptions::Named("map", 4));
  std::atomic<bool> ran{false};
  auto t = queue.Submit<Status>(
      [&](const TaskContext&) {
        ran = true;
        return Status::Ok();
      },
      QueuePolicy::kReject, Termination::AfterMs(0));
  EXPECT_EQ(t.submit_status().code(), StatusCode::kDeadlineExceeded);
  std::this_thread::sleep_for(20ms);
  EXPECT_FALSE(ran);
}

TEST(WorkQueueTest, WaitWithdrawsATaskWhoseDeadlinePassedWhileQueued) {
  WorkQueue queue(WorkQueueOptions::Named("map", 4));
  Gate gate;
  auto blocker = BlockOn(&queue, &gate);
  std::atomic<bool> ran{false};
  const Termination deadline = Termination::AfterMs(30);
  auto t = queue.Submit<Status>(
      [&](const TaskContext&) {
        ran = true;
        return Status::Ok();
      },
      QueuePolicy::kReject, deadline);
  ASSERT_TRUE(t.accepted());
  const Status s = t.Wait(deadline);
  EXPECT_EQ(s.code(), StatusCode::kDeadlineExceeded);
  EXPECT_EQ(queue.GetStats().depth, 0u);  // withdrawn at once, not left in the queue
  gate.Open();
  EXPECT_TRUE(blocker.Wait().ok());
  std::this_thread::sleep_for(20ms);
  EXPECT_FALSE(ran);
  EXPECT_EQ(queue.GetStats().expired, 1u);
}

TEST(WorkQueueTest, TaskWhoseDeadlinePassedBeforeTheWorkerTookItIsSkipped) {
  WorkQueue queue(WorkQueueOptions::Named("q", 4));
  Gate gate;
  auto blocker = BlockOn(&queue, &gate);
  std::atomic<bool> ran{false};
  auto t = queue.Submit<Status>(
      [&](const TaskContext&) {
        ran = true;
        return Status::Ok();
      },
      QueuePolicy::kReject, Termination::AfterMs(10));
  std::this_thread::sleep_for(30ms);
  gate.Open();
  EXPECT_EQ(t.Wait().code(), StatusCode::kDeadlineExceeded);
  EXPECT_FALSE(ran);
}

TEST(WorkQueueTest, ResetCancelsWaitingTasksAndMarksTheRunningOneStale) {
  WorkQueue queue(WorkQueueOptions::Named("loc", 4));
  std::atomic<bool> saw_stale{false};
  std::atomic<bool> started{false};
  auto running = queue.Submit<Status>([&](const TaskContext& ctx) {
    started = true;
    while (!ctx.stale()) std::this_thread::sleep_for(1ms);
    saw_stale = true;
    return Status::Ok();
  });
  while (!started) std::this_thread::sleep_for(1ms);
  auto waiting = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); });
  const uint64_t before = queue.generation();
  const uint64_t after = queue.Reset("reconfigured");
  EXPECT_EQ(after, before + 1);
  EXPECT_TRUE(saw_stale);  // Reset waited for the running task
  const Status cancelled = waiting.Wait();
  EXPECT_EQ(cancelled.code(), StatusCode::kCancelled);
  EXPECT_EQ(cancelled.message(), "loc: reconfigured");
  EXPECT_TRUE(running.Wait().ok());
}

TEST(WorkQueueTest, ResettingSubmitRunsFirst) {
  WorkQueue queue(WorkQueueOptions::Named("q", 8));
  Gate gate;
  std::vector<std::string> order;
  auto blocker = queue.Submit<Status>([&](const TaskContext& ctx) {
    gate.MarkEntered();
    while (!ctx.stale()) std::this_thread::sleep_for(1ms);
    return Status::Ok();
  });
  gate.WaitEntered();
  auto old_task = queue.Submit<Status>([&](const TaskContext&) {
    order.push_back("old");
    return Status::Ok();
  });
  // Tasks submitted while the reset waits for the running task must run after the reset's own.
  std::thread racer([&] {
    std::this_thread::sleep_for(5ms);
    queue.Submit<Status>([&](const TaskContext&) {
      order.push_back("racer");
      return Status::Ok();
    });
  });
  auto configure = queue.SubmitAfterReset<Status>(
      [&](const TaskContext&) {
        order.push_back("configure");
        return Status::Ok();
      },
      "reconfigured");
  racer.join();
  EXPECT_TRUE(configure.Wait().ok());
  EXPECT_EQ(old_task.Wait().code(), StatusCode::kCancelled);
  auto last = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); });
  EXPECT_TRUE(last.Wait().ok());
  ASSERT_GE(order.size(), 1u);
  EXPECT_EQ(order.front(), "configure");
  EXPECT_TRUE(blocker.Wait().ok());
}

TEST(WorkQueueTest, SleepUntilWakesOnReset) {
  WorkQueue queue(WorkQueueOptions::Named("player", 2));
  std::atomic<bool> started{false};
  auto sleeper = queue.Submit<Result<bool>>([&](const TaskContext& ctx) -> Result<bool> {
    started = true;
    return ctx.SleepUntil(MonotonicNowNs() + 10'000'000'000);
  });
  while (!started) std::this_thread::sleep_for(1ms);
  const int64_t t0 = MonotonicNowNs();
  queue.Reset("paused");
  EXPECT_LT(MsSince(t0), 1000.0);
  Result<bool> r = sleeper.Wait();
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(*r);
}

TEST(WorkQueueTest, StopFailsWaitingTasksAndRefusesNewOnes) {
  auto queue = std::make_unique<WorkQueue>(WorkQueueOptions::Named("q", 4));
  Gate gate;
  auto blocker = BlockOn(queue.get(), &gate);
  auto waiting = queue->Submit<Status>([](const TaskContext&) { return Status::Ok(); });
  std::thread stopper([&] { queue->Stop("the service is shutting down"); });
  std::this_thread::sleep_for(20ms);
  gate.Open();
  stopper.join();
  EXPECT_TRUE(blocker.Wait().ok());
  const Status s = waiting.Wait();
  EXPECT_EQ(s.code(), StatusCode::kUnavailable);
  EXPECT_EQ(s.message(), "q: the service is shutting down");
  EXPECT_EQ(
      queue->Submit<Status>([](const TaskContext&) { return Status::Ok(); }).submit_status().code(),
      StatusCode::kUnavailable);
  queue->Stop();  // idempotent
  queue.reset();
}

TEST(WorkQueueTest, TicketOutlivesTheQueue) {
  Ticket<Status> t;
  {
    WorkQueue queue(WorkQueueOptions::Named("q", 1));
    Gate gate;
    auto blocker = BlockOn(&queue, &gate);
    t = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); });
    std::thread opener([&] {
      std::this_thread::sleep_for(10ms);
      gate.Open();
    });
    queue.Stop();
    opener.join();
  }
  EXPECT_EQ(t.Wait().code(), StatusCode::kUnavailable);
}

// Many producers, both policies, resets and deadlines at once: every ticket resolves, tasks never
// overlap, and the counters add up.
TEST(WorkQueueStressTest, ConcurrentProducersResetsAndDeadlines) {
  WorkQueue queue([] {
    WorkQueueOptions o = WorkQueueOptions::Named("stress", 8);
    o.stats_window = 64;
    return o;
  }());
  std::atomic<int> running{0};
  std::atomic<int> overlaps{0};
  std::atomic<int> ran{0};
  constexpr int kThreads = 6;
  constexpr int kPerThread = 400;
  std::atomic<int> resolved{0};
  std::atomic<int> accepted{0};
  std::vector<std::thread> producers;
  producers.reserve(kThreads);
  for (int p = 0; p < kThreads; ++p) {
    producers.emplace_back([&, p] {
      std::mt19937 rng(p);
      for (int i = 0; i < kPerThread; ++i) {
        const QueuePolicy policy = rng() % 2 ? QueuePolicy::kDropOldest : QueuePolicy::kReject;
        const Termination termination =
            rng() % 4 == 0 ? Termination::AfterMs(rng() % 3) : Termination::Never();
        auto t = queue.Submit<Result<int>>(
            [&](const TaskContext&) -> Result<int> {
              if (running.fetch_add(1) != 0) ++overlaps;
              std::this_thread::sleep_for(std::chrono::microseconds(50));
              running.fetch_sub(1);
              ++ran;
              return 1;
            },
            policy, termination);
        if (t.accepted()) ++accepted;
        (void)t.Wait(rng() % 3 == 0 ? Termination::AfterMs(1) : Termination());
        ++resolved;
      }
    });
  }
  std::thread resetter([&] {
    for (int i = 0; i < 20; ++i) {
      std::this_thread::sleep_for(2ms);
      queue.Reset("stress reset");
    }
  });
  for (auto& t : producers) t.join();
  resetter.join();
  // Let tasks abandoned by their waiters (running on) finish.
  while (queue.GetStats().busy || queue.GetStats().depth > 0) std::this_thread::sleep_for(1ms);
  EXPECT_EQ(resolved.load(), kThreads * kPerThread);
  EXPECT_EQ(overlaps.load(), 0);
  const WorkQueueStats s = queue.GetStats();
  EXPECT_EQ(s.submitted, static_cast<uint64_t>(accepted.load()));
  EXPECT_EQ(s.submitted, s.completed + s.dropped + s.expired + s.cancelled);
  EXPECT_EQ(s.completed, static_cast<uint64_t>(ran.load()));
  EXPECT_EQ(s.submitted + s.rejected, static_cast<uint64_t>(kThreads * kPerThread));
  EXPECT_LE(s.run_ms.count, 64u);
}

}  // namespace
}  // namespace mav
