#include "mav/common/parse.h"

#include <gtest/gtest.h>

#include <string>

namespace mav {
namespace {

TEST(ParseTest, Doubles) {
  EXPECT_DOUBLE_EQ(*ParseDouble(" 1.5e-3 ", "x"), 1.5e-3);
  EXPECT_DOUBLE_EQ(*ParseDouble("-7", "x"), -7.0);
  EXPECT_DOUBLE_EQ(*ParseDouble("1e300", "x"), 1e300);  // large but finite
  for (const char* bad : {"", "abc", "1.0x", "1,0", "nan"}) {
    const Result<double> r = ParseDouble(bad, "column 'p_x'");
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("column 'p_x'"), std::string::npos);
  }
}

TEST(ParseTest, DoublesMustBeFinite) {
  for (const char* bad :
       {"inf", "-inf", "+inf", "INF", "infinity", "-Infinity", "nan", "-nan", "NAN(123)"}) {
    const Result<double> r = ParseDouble(bad, "column 'p_x'");
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("column 'p_x'"), std::string::npos);
    EXPECT_NE(r.status().message().find("finite"), std::string::npos) << r.status().message();
  }
  for (const char* overflow : {"1e309", "-1e309", "1e99999"}) {
    const Result<double> r = ParseDouble(overflow, "rate_hz");
    ASSERT_FALSE(r.ok()) << overflow;
    EXPECT_NE(r.status().message().find("rate_hz"), std::string::npos);
    EXPECT_NE(r.status().message().find("out of the range of a double"), std::string::npos)
        << r.status().message();
  }
  // Underflow rounds to the nearest double, like any other rounding.
  EXPECT_EQ(*ParseDouble("1e-400", "x"), 0.0);
  EXPECT_GT(*ParseDouble("4e-320", "x"), 0.0);
}

TEST(ParseTest, ErrorsQuoteTheValueShortly) {
  const std::string huge(100000, '7');
  const Result<double> d = ParseDouble(huge + "x", "field");
  ASSERT_FALSE(d.ok());
  EXPECT_LT(d.status().message().size(), 200u) << d.status().message();
  EXPECT_NE(d.status().message().find("(100001 bytes)"), std::string::npos);
  const Result<int64_t> i = ParseInt64("12\n\x01", "t");
  ASSERT_FALSE(i.ok());
  EXPECT_NE(i.status().message().find("'12\\n\\x01'"), std::string::npos) << i.status().message();
}

TEST(ParseTest, Integers) {
  EXPECT_EQ(*ParseInt64("1403636579763555584", "t"), 1403636579763555584LL);
  EXPECT_EQ(*ParseInt64(" -3\r", "t"), -3);
  EXPECT_EQ(*ParseInt64("9223372036854775807", "t"), INT64_MAX);
  EXPECT_EQ(*ParseInt64("-9223372036854775808", "t"), INT64_MIN);
  EXPECT_FALSE(ParseInt64("1.5", "t").ok());
  EXPECT_FALSE(ParseInt64("", "t").ok());
  EXPECT_NE(ParseInt64("ten", "t").status().message().find("is not an integer"), std::string::npos);
}

TEST(ParseTest, IntegerOverflowIsOutOfRangeNotGarbage) {
  for (const char* big : {"99999999999999999999", "9223372036854775808", "-9223372036854775809"}) {
    const Result<int64_t> r = ParseInt64(big, "--frames");
    ASSERT_FALSE(r.ok()) << big;
    EXPECT_EQ(r.status().message(),
              std::string("--frames: '") + big +
                  "' is out of range [-9223372036854775808, 9223372036854775807]");
  }
  EXPECT_EQ(*ParseUint64("18446744073709551615", "seed"), UINT64_MAX);
  EXPECT_NE(ParseUint64("18446744073709551616", "seed").status().message().find("out of range"),
            std::string::npos);
  EXPECT_NE(ParseUint64("-5", "seed").status().message().find("out of range [0, "),
            std::string::npos);
  EXPECT_NE(ParseUint64("five", "seed").status().message().find("not an integer"),
            std::string::npos);
}

TEST(ParseTest, SplitKeepsEmptyFieldsAndDropsCarriageReturn) {
  const auto f = SplitFields("a,,b,\r\n", ',');
  ASSERT_EQ(f.size(), 4u);
  EXPECT_EQ(f[0], "a");
  EXPECT_EQ(f[1], "");
  EXPECT_EQ(f[2], "b");
  EXPECT_EQ(f[3], "");
  EXPECT_EQ(SplitFields("single", ',').size(), 1u);
  EXPECT_EQ(Trim("  x y \t"), "x y");
}

}  // namespace
}  // namespace mav
