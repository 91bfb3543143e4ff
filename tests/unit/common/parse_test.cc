#include "mav/common/parse.h"

#include <gtest/gtest.h>

namespace mav {
namespace {

TEST(ParseTest, Doubles) {
  EXPECT_DOUBLE_EQ(*ParseDouble(" 1.5e-3 ", "x"), 1.5e-3);
  EXPECT_DOUBLE_EQ(*ParseDouble("-7", "x"), -7.0);
  for (const char* bad : {"", "abc", "1.0x", "1,0", "nan"}) {
    const Result<double> r = ParseDouble(bad, "column 'p_x'");
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("column 'p_x'"), std::string::npos);
  }
}

TEST(ParseTest, Integers) {
  EXPECT_EQ(*ParseInt64("1403636579763555584", "t"), 1403636579763555584LL);
  EXPECT_EQ(*ParseInt64(" -3\r", "t"), -3);
  EXPECT_FALSE(ParseInt64("1.5", "t").ok());
  EXPECT_FALSE(ParseInt64("99999999999999999999", "t").ok());
  EXPECT_FALSE(ParseInt64("", "t").ok());
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
