// The service skeleton's per-call costs (libs/common): the work queue's hand-off to the worker and
// back (every stereo pair, keyframe and long operation of the services takes it), beside a thread
// started per call (std::async, the obvious alternative), the runtime statistics every GetStatus
// computes, and the quoting of a value echoed into an error.
//
//   taskset -c 1 build/bin/benchmarks/common_benchmark --benchmark_min_time=0.5

#include <benchmark/benchmark.h>

#include <future>
#include <random>
#include <string>
#include <vector>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/common/text.h"
#include "mav/common/work_queue.h"

namespace mav {
namespace {

// Submit a trivial task and wait for its result: the round trip through the worker thread.
// Real time: the submitting thread sleeps while the worker runs.
void BM_WorkQueueRoundTrip(benchmark::State& state) {
  WorkQueue queue(WorkQueueOptions::Named("bench", 16));
  int64_t sum = 0;
  for (auto _ : state) {
    Ticket<Result<int64_t>> t =
        queue.Submit<Result<int64_t>>([&](const TaskContext&) { return Result<int64_t>(++sum); });
    benchmark::DoNotOptimize(t.Wait());
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_WorkQueueRoundTrip)->UseRealTime();

// The same with a deadline on the task and on the wait, as every RPC handler submits.
void BM_WorkQueueRoundTripWithDeadline(benchmark::State& state) {
  WorkQueue queue(WorkQueueOptions::Named("bench", 16));
  int64_t sum = 0;
  for (auto _ : state) {
    const Termination deadline = Termination::AfterMs(1000);
    Ticket<Result<int64_t>> t = queue.Submit<Result<int64_t>>(
        [&](const TaskContext&) { return Result<int64_t>(++sum); }, QueuePolicy::kReject, deadline);
    benchmark::DoNotOptimize(t.Wait(deadline));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_WorkQueueRoundTripWithDeadline)->UseRealTime();

// A burst of N tasks submitted before the first result is awaited (a DDS reader's frames).
void BM_WorkQueueBurst(benchmark::State& state) {
  const size_t n = static_cast<size_t>(state.range(0));
  WorkQueue queue(WorkQueueOptions::Named("bench", n));
  int64_t sum = 0;
  std::vector<Ticket<Status>> tickets;
  tickets.reserve(n);
  for (auto _ : state) {
    tickets.clear();
    for (size_t i = 0; i < n; ++i) {
      tickets.push_back(queue.Submit<Status>([&](const TaskContext&) {
        ++sum;
        return Status::Ok();
      }));
    }
    for (Ticket<Status>& t : tickets) benchmark::DoNotOptimize(t.Wait());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(n));
}
BENCHMARK(BM_WorkQueueBurst)->Arg(16)->Arg(256)->UseRealTime();

// The peer: a thread per call (std::async), what a handler without a worker would do.
void BM_AsyncThreadPerCall(benchmark::State& state) {
  int64_t sum = 0;
  for (auto _ : state) {
    std::future<int64_t> f = std::async(std::launch::async, [&] { return ++sum; });
    benchmark::DoNotOptimize(f.get());
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_AsyncThreadPerCall)->UseRealTime();

// SummarizeRuntimes over a full window of N samples (GetStatus of every service).
void BM_SummarizeRuntimes(benchmark::State& state) {
  std::mt19937 rng(1);
  std::lognormal_distribution<double> ms(0.0, 0.5);
  std::vector<double> samples(static_cast<size_t>(state.range(0)));
  for (double& s : samples) s = ms(rng);
  for (auto _ : state) benchmark::DoNotOptimize(SummarizeRuntimes(samples));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_SummarizeRuntimes)->Arg(100)->Arg(1000);

// Quoting a 10 KB value into an error message (kept to 64 characters).
void BM_QuoteForError(benchmark::State& state) {
  const std::string value(static_cast<size_t>(state.range(0)), 'x');
  for (auto _ : state) benchmark::DoNotOptimize(QuoteForError(value));
}
BENCHMARK(BM_QuoteForError)->Arg(16)->Arg(10000);

}  // namespace
}  // namespace mav

BENCHMARK_MAIN();
