#include "mav/common/status.h"

#include <gtest/gtest.h>

#include <memory>

#include "mav/common/file.h"
#include "mav/common/time.h"

namespace mav {
namespace {

Result<int> Half(int x) {
  if (x % 2 != 0) return Status::InvalidArgument("x: " + std::to_string(x) + " is odd");
  return x / 2;
}

Result<int> Quarter(int x) {
  MAV_ASSIGN_OR_RETURN(const int half, Half(x));
  MAV_ASSIGN_OR_RETURN(const int quarter, Half(half));
  return quarter;
}

Status CheckPositive(int x) {
  if (x <= 0) return Status::OutOfRange("x: must be positive");
  return Status::Ok();
}

Status CheckBoth(int a, int b) {
  MAV_RETURN_IF_ERROR(CheckPositive(a));
  MAV_RETURN_IF_ERROR(CheckPositive(b));
  return Status::Ok();
}

TEST(StatusTest, OkAndErrorsCarryCodeAndMessage) {
  EXPECT_TRUE(Status::Ok().ok());
  const Status s = Status::NotFound("foo.csv: no such file");
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_EQ(s.ToString(), "NOT_FOUND: foo.csv: no such file");
  EXPECT_EQ(s.WithContext("loading").message(), "loading: foo.csv: no such file");
}

TEST(ResultTest, PropagatesFirstError) {
  EXPECT_EQ(*Quarter(12), 3);
  const Result<int> r = Quarter(6);  // 6 -> 3 -> odd
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().message(), "x: 3 is odd");
}

TEST(ResultTest, ReturnIfErrorStopsAtFirstFailure) {
  EXPECT_TRUE(CheckBoth(1, 2).ok());
  EXPECT_EQ(CheckBoth(1, -2).code(), StatusCode::kOutOfRange);
}

TEST(ResultTest, HoldsMoveOnlyValues) {
  Result<std::unique_ptr<int>> r = std::make_unique<int>(7);
  ASSERT_TRUE(r.ok());
  std::unique_ptr<int> p = std::move(r).value();
  EXPECT_EQ(*p, 7);
}

TEST(ResultDeathTest, ValueOfErrorAborts) {
  EXPECT_DEATH(
      {
        Result<int> r = Status::Internal("boom");
        (void)r.value();
      },
      "boom");
}

TEST(CheckDeathTest, FailedCheckPrintsConditionAndMessage) {
  const int width = -1;
  EXPECT_DEATH(MAV_CHECK(width > 0) << "width " << width, "width > 0.*width -1");
}

TEST(TimeTest, ConversionsRoundTrip) {
  EXPECT_EQ(SecondsToNs(1.5), 1'500'000'000);
  EXPECT_EQ(SecondsToNs(-0.25), -250'000'000);
  EXPECT_EQ(PeriodNs(20.0), 50'000'000);
  EXPECT_EQ(PeriodNs(200.0), 5'000'000);
  EXPECT_DOUBLE_EQ(NsToSeconds(2'500'000'000), 2.5);
  const int64_t a = MonotonicNowNs();
  EXPECT_LE(a, MonotonicNowNs());
}

TEST(FileTest, AtomicWriteThenRead) {
  const std::string dir = ::testing::TempDir() + "/mav_file_test/a/b";
  ASSERT_TRUE(MakeDirectories(dir).ok());
  const std::string path = dir + "/x.txt";
  ASSERT_TRUE(WriteStringToFileAtomic(path, std::string("hello\0world", 11)).ok());
  EXPECT_FALSE(PathExists(path + ".tmp"));
  const Result<std::string> back = ReadFileToString(path);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back, std::string("hello\0world", 11));
}

TEST(FileTest, MissingFileAndDirectoryAreNamed) {
  const Result<std::string> r = ReadFileToString("/nonexistent/mav/x.csv");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_NE(r.status().message().find("/nonexistent/mav/x.csv"), std::string::npos);
  const Result<std::string> d = ReadFileToString(::testing::TempDir());
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mav
