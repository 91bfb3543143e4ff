#include "mav/common/work_queue.h"

#include <gtest/gtest.h>

#include <atomic>
#include <future>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "mav/common/time.h"
#include "tests/common/fake_time_source.h"

namespace mav {
namespace {

using ::mav::test_support::FakeTimeSource;  // tests/common/fake_time_source.h

// A task that blocks the worker until released, so tests can fill the queue deterministically.
class Gate {
 public:
  void Open() { open_.set_value(); }
  void WaitOpen() { opened_.wait(); }
  void MarkEntered() { entered_.set_value(); }
  void WaitEntered() { entered_.get_future().wait(); }

 private:
  std::promise<void> open_;
  std::shared_future<void> opened_ = open_.get_future().share();
  std::promise<void> entered_;
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

// Runs a task through the queue and waits for it: the worker takes tasks in order, so every task
// queued before it has been run, skipped or discarded when this returns.
void Drain(WorkQueue* queue) {
  EXPECT_TRUE(queue->Submit<Status>([](const TaskContext&) { return Status::Ok(); }).Wait().ok());
}

// Submits a task that sleeps (TaskContext::SleepUntil) until the queue is reset or stopped, and
// returns once it runs; its result is what SleepUntil returned.
Ticket<Result<bool>> SleepUntilStale(WorkQueue* queue) {
  std::promise<void> started;
  auto t = queue->Submit<Result<bool>>([&started](const TaskContext& ctx) -> Result<bool> {
    started.set_value();
    return ctx.SleepUntil(Termination::kNever);
  });
  started.get_future().wait();
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
  Drain(&queue);
  EXPECT_FALSE(ran);
  EXPECT_FALSE(t.ran());
  const WorkQueueStats s = queue.GetStats();
  EXPECT_EQ(s.rejected, 1u);
  EXPECT_EQ(s.submitted, 1u);  // Drain's task alone
}

TEST(WorkQueueTest, WaitWithdrawsATaskWhoseDeadlinePassedWhileQueued) {
  WorkQueue queue(WorkQueueOptions::Named("map", 4));
  FakeTimeSource clock;
  Gate gate;
  auto blocker = BlockOn(&queue, &gate);
  std::atomic<bool> ran{false};
  const Termination deadline = Termination::AfterMs(30, &clock);
  auto t = queue.Submit<Status>(
      [&](const TaskContext&) {
        ran = true;
        return Status::Ok();
      },
      QueuePolicy::kReject, deadline);
  ASSERT_TRUE(t.accepted());
  clock.AdvanceMs(29);
  EXPECT_FALSE(deadline.ShouldStop());
  EXPECT_EQ(queue.GetStats().depth, 1u);
  clock.AdvanceMs(1);
  const Status s = t.Wait(deadline);
  EXPECT_EQ(s.code(), StatusCode::kDeadlineExceeded);
  EXPECT_EQ(queue.GetStats().depth, 0u);  // withdrawn at once, not left in the queue
  gate.Open();
  EXPECT_TRUE(blocker.Wait().ok());
  Drain(&queue);
  EXPECT_FALSE(ran);
  EXPECT_FALSE(t.ran());
  EXPECT_EQ(queue.GetStats().expired, 1u);
}

TEST(WorkQueueTest, TaskWhoseDeadlinePassedBeforeTheWorkerTookItIsSkipped) {
  WorkQueue queue(WorkQueueOptions::Named("q", 4));
  FakeTimeSource clock;
  Gate gate;
  auto blocker = BlockOn(&queue, &gate);
  std::atomic<bool> ran{false};
  auto t = queue.Submit<Status>(
      [&](const TaskContext&) {
        ran = true;
        return Status::Ok();
      },
      QueuePolicy::kReject, Termination::AfterMs(10, &clock));
  ASSERT_TRUE(t.accepted());
  clock.AdvanceMs(10);  // expires while the worker is busy with the blocker
  gate.Open();
  EXPECT_EQ(t.Wait().code(), StatusCode::kDeadlineExceeded);
  EXPECT_FALSE(ran);
  const WorkQueueStats s = queue.GetStats();
  EXPECT_EQ(s.expired, 1u);
  EXPECT_EQ(s.completed, 1u);  // the blocker alone
}

TEST(WorkQueueTest, ResetCancelsWaitingTasksAndMarksTheRunningOneStale) {
  WorkQueue queue(WorkQueueOptions::Named("loc", 4));
  std::atomic<bool> saw_stale{false};
  std::promise<void> started;
  auto running = queue.Submit<Status>([&](const TaskContext& ctx) {
    started.set_value();
    ctx.SleepUntil(Termination::kNever);  // returns when the reset marks the task stale
    saw_stale = ctx.stale();
    return Status::Ok();
  });
  started.get_future().wait();
  auto waiting = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); });
  const uint64_t before = queue.generation();
  const uint64_t after = queue.Reset("reconfigured");
  EXPECT_EQ(after, before + 1);
  EXPECT_TRUE(saw_stale);  // Reset waited for the running task
  const Status cancelled = waiting.Wait();
  EXPECT_EQ(cancelled.code(), StatusCode::kCancelled);
  EXPECT_EQ(cancelled.message(), "loc: reconfigured");
  EXPECT_TRUE(running.Wait().ok());
  EXPECT_EQ(queue.GetStats().cancelled, 1u);
}

TEST(WorkQueueTest, ResettingSubmitRunsFirst) {
  WorkQueue queue(WorkQueueOptions::Named("q", 8));
  std::vector<std::string> order;
  // The racer submits while the reset waits for the running task: the running task sees the
  // reset (stale), lets the racer submit and returns only once the racer's task is queued.
  std::promise<void> entered, reset_seen, racer_queued;
  auto blocker = queue.Submit<Status>([&](const TaskContext& ctx) {
    entered.set_value();
    ctx.SleepUntil(Termination::kNever);
    reset_seen.set_value();
    racer_queued.get_future().wait();
    return Status::Ok();
  });
  entered.get_future().wait();
  auto old_task = queue.Submit<Status>([&](const TaskContext&) {
    order.push_back("old");
    return Status::Ok();
  });
  Ticket<Status> racer_task;
  std::thread racer([&] {
    reset_seen.get_future().wait();
    racer_task = queue.Submit<Status>([&](const TaskContext&) {
      order.push_back("racer");
      return Status::Ok();
    });
    racer_queued.set_value();
  });
  auto configure = queue.SubmitAfterReset<Status>(
      [&](const TaskContext&) {
        order.push_back("configure");
        return Status::Ok();
      },
      "reconfigured");
  racer.join();
  ASSERT_TRUE(racer_task.accepted());
  EXPECT_TRUE(configure.Wait().ok());
  EXPECT_TRUE(racer_task.Wait().ok());
  EXPECT_EQ(old_task.Wait().code(), StatusCode::kCancelled);
  EXPECT_TRUE(blocker.Wait().ok());
  EXPECT_EQ(order, (std::vector<std::string>{"configure", "racer"}));
}

TEST(WorkQueueTest, SleepUntilWakesOnReset) {
  // The queue's clock never moves: only the reset can end the sleep (Reset waits for the task, so
  // a sleep the reset did not wake would hang here).
  FakeTimeSource clock;
  WorkQueueOptions options = WorkQueueOptions::Named("player", 2);
  options.time_source = &clock;
  WorkQueue queue(options);
  const int64_t start_ns = clock.NowNs();
  std::promise<void> started;
  auto sleeper = queue.Submit<Result<bool>>([&](const TaskContext& ctx) -> Result<bool> {
    started.set_value();
    return ctx.SleepUntil(ctx.NowNs() + 10'000'000'000);
  });
  started.get_future().wait();
  queue.Reset("paused");
  Result<bool> r = sleeper.Wait();
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(*r);  // stopped early, not woken by the clock
  EXPECT_EQ(clock.NowNs(), start_ns);
}

TEST(WorkQueueTest, SleepUntilReturnsWhenTheQueuesClockReachesTheWakeTime) {
  FakeTimeSource clock;
  WorkQueueOptions options = WorkQueueOptions::Named("player", 2);
  options.time_source = &clock;
  WorkQueue queue(options);
  const int64_t wake_ns = clock.NowNs() + 40'000'000;
  std::promise<void> started;
  auto sleeper = queue.Submit<Result<bool>>([&](const TaskContext& ctx) -> Result<bool> {
    started.set_value();
    return ctx.SleepUntil(wake_ns);
  });
  started.get_future().wait();
  clock.AdvanceMs(40);
  Result<bool> r = sleeper.Wait();
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(*r);  // woke on time, not stopped
  EXPECT_EQ(queue.generation(), 0u);
}

TEST(WorkQueueTest, RunTimesAreMeasuredOnTheQueuesClock) {
  FakeTimeSource clock;
  WorkQueueOptions options = WorkQueueOptions::Named("q", 4);
  options.time_source = &clock;
  WorkQueue queue(options);
  for (int ms : {5, 20}) {
    EXPECT_TRUE(queue
                    .Submit<Status>([&clock, ms](const TaskContext&) {
                      clock.AdvanceMs(ms);
                      return Status::Ok();
                    })
                    .Wait()
                    .ok());
  }
  const WorkQueueStats s = queue.GetStats();
  EXPECT_EQ(s.run_ms.count, 2u);
  EXPECT_DOUBLE_EQ(s.run_ms.max_ms, 20.0);
}

TEST(WorkQueueTest, StopFailsWaitingTasksAndRefusesNewOnes) {
  auto queue = std::make_unique<WorkQueue>(WorkQueueOptions::Named("q", 4));
  std::atomic<bool> blocker_returned{false};
  std::promise<void> started;
  auto blocker = queue->Submit<Status>([&](const TaskContext& ctx) {
    started.set_value();
    ctx.SleepUntil(Termination::kNever);  // until Stop marks it stale
    blocker_returned = true;
    return Status::Ok();
  });
  started.get_future().wait();
  auto waiting = queue->Submit<Status>([](const TaskContext&) { return Status::Ok(); });
  queue->Stop("the service is shutting down");
  EXPECT_TRUE(blocker_returned);  // Stop waited for the running task
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
    auto blocker = SleepUntilStale(&queue);
    t = queue.Submit<Status>([](const TaskContext&) { return Status::Ok(); });
    ASSERT_TRUE(t.accepted());
    queue.Stop();
    Result<bool> slept = blocker.Wait();
    ASSERT_TRUE(slept.ok());
    EXPECT_FALSE(*slept);  // woken by Stop
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
              // A little work, so that tasks overlap with submissions and the queue fills.
              volatile double sink = 0;
              for (int k = 0; k < 2000; ++k) sink = sink + k;
              running.fetch_sub(1);
              ++ran;
              return 1;
            },
            policy, termination);
        if (t.accepted()) ++accepted;
        (void)t.Wait(rng() % 3 == 0 ? Termination::AfterMs(1) : Termination());
        ++resolved;
        // Resets among the submissions (24 in all), from the producers' own threads.
        if (i % 100 == 50) queue.Reset("stress reset");
      }
    });
  }
  for (auto& t : producers) t.join();
  // Let tasks abandoned by their waiters (running on) finish: a last task, queued behind them
  // (room for it is made first), runs after all of them.
  queue.SetCapacity(64);
  Drain(&queue);
  EXPECT_EQ(resolved.load(), kThreads * kPerThread);
  EXPECT_EQ(overlaps.load(), 0);
  const WorkQueueStats s = queue.GetStats();
  EXPECT_EQ(s.depth, 0u);
  EXPECT_FALSE(s.busy);
  EXPECT_EQ(s.submitted, static_cast<uint64_t>(accepted.load()) + 1);  // + Drain's task
  EXPECT_EQ(s.submitted, s.completed + s.dropped + s.expired + s.cancelled);
  EXPECT_EQ(s.completed, static_cast<uint64_t>(ran.load()) + 1);
  EXPECT_EQ(s.submitted - 1 + s.rejected, static_cast<uint64_t>(kThreads * kPerThread));
  EXPECT_EQ(s.generation, static_cast<uint64_t>(kThreads * kPerThread / 100));
  EXPECT_EQ(s.run_ms.count, 64u);  // the window is full
}

}  // namespace
}  // namespace mav
