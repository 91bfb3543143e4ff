#include "mav/common/termination.h"

#include <gtest/gtest.h>

#include <cmath>

#include "mav/common/time.h"
#include "tests/common/fake_time_source.h"

namespace mav {
namespace {

using ::mav::test_support::FakeTimeSource;  // tests/common/fake_time_source.h

TEST(TerminationTest, NeverStopsByDefault) {
  const Termination t;
  EXPECT_FALSE(t.ShouldStop());
  EXPECT_TRUE(t.Check("work").ok());
  EXPECT_EQ(t.deadline_ns(), Termination::kNever);
  EXPECT_EQ(t.RemainingNs(), Termination::kNever);
}

TEST(TerminationTest, ExpiredBudgetReportsDeadlineExceeded) {
  const Termination t = Termination::AfterMs(0);
  EXPECT_TRUE(t.expired());
  const Status s = t.Check("roadmap build");
  EXPECT_EQ(s.code(), StatusCode::kDeadlineExceeded);
  EXPECT_EQ(s.message(), "roadmap build: deadline exceeded");
  EXPECT_TRUE(Termination::AfterMs(-5).expired());
  EXPECT_TRUE(Termination::AfterMs(std::nan("")).expired());
}

TEST(TerminationTest, DeadlinePassesInTime) {
  FakeTimeSource clock;
  const Termination t = Termination::AfterMs(20, &clock);
  EXPECT_EQ(t.deadline_ns(), clock.NowNs() + 20'000'000);
  EXPECT_FALSE(t.ShouldStop());
  EXPECT_EQ(t.RemainingNs(), 20'000'000);
  clock.AdvanceMs(19);
  EXPECT_FALSE(t.ShouldStop());
  EXPECT_EQ(t.RemainingNs(), 1'000'000);
  clock.AdvanceMs(1);  // the deadline itself is past
  EXPECT_TRUE(t.ShouldStop());
  EXPECT_EQ(t.RemainingNs(), 0);
  EXPECT_EQ(t.Check("build").code(), StatusCode::kDeadlineExceeded);
  clock.AdvanceMs(5);
  EXPECT_EQ(t.RemainingNs(), -5'000'000);
}

TEST(TerminationTest, CopiesAndNarrowedDeadlinesKeepTheirClock) {
  FakeTimeSource clock;
  const Termination t =
      Termination::AtNs(clock.NowNs() + 10, &clock).WithDeadlineNs(clock.NowNs() + 5);
  EXPECT_EQ(t.NowNs(), clock.NowNs());
  EXPECT_EQ(t.RemainingNs(), 5);
  CancelFlag flag;
  const Termination u = t.WithCancel(flag);
  clock.AdvanceNs(5);
  EXPECT_TRUE(u.expired());
  EXPECT_FALSE(u.cancelled());
  // A zero budget expires at once on the source's time too.
  EXPECT_EQ(Termination::AfterMs(0, &clock).deadline_ns(), clock.NowNs());
  EXPECT_TRUE(Termination::AfterMs(0, &clock).expired());
}

TEST(TerminationTest, HugeBudgetMeansNoDeadline) {
  EXPECT_EQ(Termination::AfterMs(1e300).deadline_ns(), Termination::kNever);
}

TEST(TerminationTest, CancelFlagIsSharedByCopies) {
  CancelFlag flag;
  const Termination t = Termination::Never().WithCancel(flag);
  const Termination copy = t;  // NOLINT(performance-unnecessary-copy-initialization): the test
  EXPECT_FALSE(copy.ShouldStop());
  flag.Cancel();
  EXPECT_TRUE(t.cancelled());
  EXPECT_TRUE(copy.ShouldStop());
  EXPECT_EQ(copy.Check("build").code(), StatusCode::kCancelled);
}

TEST(TerminationTest, EitherOfTwoFlagsStopsIt) {
  CancelFlag client, owner;
  const Termination t = Termination::Never().WithCancel(client).WithCancel(owner);
  EXPECT_FALSE(t.ShouldStop());
  owner.Cancel();
  EXPECT_TRUE(t.cancelled());
  CancelFlag client2, owner2;
  const Termination u = Termination::Never().WithCancel(client2).WithCancel(owner2);
  client2.Cancel();
  EXPECT_EQ(u.Check("plan").code(), StatusCode::kCancelled);
  // The same flag twice takes no second slot.
  CancelFlag once;
  const Termination v = Termination::Never().WithCancel(once).WithCancel(once).WithCancel(client2);
  EXPECT_TRUE(v.cancelled());
}

TEST(TerminationTest, EarlierDeadlineWins) {
  const int64_t now = MonotonicNowNs();
  const Termination t = Termination::AtMonotonicNs(now + 1'000'000'000).WithDeadlineNs(now - 1);
  EXPECT_TRUE(t.expired());
  const Termination u = Termination::AtMonotonicNs(now - 1).WithDeadlineNs(Termination::kNever);
  EXPECT_TRUE(u.expired());
}

TEST(TimeTest, MsAndSecondsSince) {
  const int64_t start = MonotonicNowNs() - 2'000'000;  // 2 ms ago
  EXPECT_GE(MsSince(start), 2.0);
  EXPECT_GE(SecondsSince(start), 0.002);
}

TEST(TimeTest, NowNsReadsTheSourceOrTheMonotonicClock) {
  FakeTimeSource clock(42);
  EXPECT_EQ(NowNs(&clock), 42);
  clock.AdvanceNs(8);
  EXPECT_EQ(NowNs(&clock), 50);
  const int64_t before = MonotonicNowNs();
  EXPECT_GE(NowNs(nullptr), before);  // the monotonic clock never goes back
}

}  // namespace
}  // namespace mav
