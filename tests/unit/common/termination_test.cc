#include "mav/common/termination.h"

#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "mav/common/time.h"

namespace mav {
namespace {

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
  const Termination t = Termination::AfterMs(20);
  EXPECT_FALSE(t.ShouldStop());
  EXPECT_GT(t.RemainingNs(), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  EXPECT_TRUE(t.ShouldStop());
  EXPECT_LE(t.RemainingNs(), 0);
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
  EXPECT_LT(MsSince(start), 1000.0);
  EXPECT_GE(SecondsSince(start), 0.002);
}

}  // namespace
}  // namespace mav
