#include "mav/common/text.h"

#include <gtest/gtest.h>

#include <string>

namespace mav {
namespace {

// True if `s` is well-formed UTF-8 (checked independently of the code under test: decode every
// sequence and re-check the ranges RFC 3629 allows).
bool IsValidUtf8(const std::string& s) {
  size_t i = 0;
  while (i < s.size()) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    int n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xe ? 3 : (c >> 3) == 0x1e ? 4 : 0;
    if (n == 0 || i + n > s.size()) return false;
    uint32_t cp = n == 1 ? c : c & (0x7f >> n);
    for (int k = 1; k < n; ++k) {
      const unsigned char d = static_cast<unsigned char>(s[i + k]);
      if ((d & 0xc0) != 0x80) return false;
      cp = (cp << 6) | (d & 0x3f);
    }
    const uint32_t min_cp[] = {0, 0, 0x80, 0x800, 0x10000};
    if (cp < min_cp[n] || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return false;
    i += n;
  }
  return true;
}

TEST(QuoteForErrorTest, QuotesShortValuesAsTheyAre) {
  EXPECT_EQ(QuoteForError("abc"), "'abc'");
  EXPECT_EQ(QuoteForError(""), "''");
  EXPECT_EQ(QuoteForError("room-easy 2"), "'room-easy 2'");
}

TEST(QuoteForErrorTest, EscapesControlCharactersQuotesAndBackslashes) {
  EXPECT_EQ(QuoteForError("a\nb\tc\rd"), "'a\\nb\\tc\\rd'");
  EXPECT_EQ(QuoteForError(std::string("x\0y", 3)), "'x\\x00y'");
  EXPECT_EQ(QuoteForError("\x1b[31m"), "'\\x1b[31m'");
  EXPECT_EQ(QuoteForError("\x7f"), "'\\x7f'");
  EXPECT_EQ(QuoteForError("it's"), "'it\\'s'");
  EXPECT_EQ(QuoteForError("a\\b"), "'a\\\\b'");
}

TEST(QuoteForErrorTest, KeepsValidUtf8AndEscapesInvalidBytes) {
  EXPECT_EQ(QuoteForError("Zürich €"), "'Zürich €'");
  EXPECT_EQ(QuoteForError("\xf0\x9f\x9a\x81"), "'\xf0\x9f\x9a\x81'");  // U+1F681, 4 bytes
  EXPECT_EQ(QuoteForError("a\xffz"), "'a\\xffz'");
  EXPECT_EQ(QuoteForError("\xc3"), "'\\xc3'");                    // truncated sequence
  EXPECT_EQ(QuoteForError("\xc0\xaf"), "'\\xc0\\xaf'");           // overlong '/'
  EXPECT_EQ(QuoteForError("\xed\xa0\x80"), "'\\xed\\xa0\\x80'");  // a UTF-16 surrogate
  EXPECT_EQ(QuoteForError("\xc2\x85"), "'\\xc2\\x85'");           // U+0085, a C1 control
}

TEST(QuoteForErrorTest, TruncatesLongValuesWithTheirSize) {
  const std::string big(10000, 'x');
  EXPECT_EQ(QuoteForError(big, 3), "'xxx...' (10000 bytes)");
  const std::string quoted = QuoteForError(big);
  EXPECT_EQ(quoted, "'" + std::string(64, 'x') + "...' (10000 bytes)");
  // Exactly max_chars characters: nothing is cut.
  EXPECT_EQ(QuoteForError("abcd", 4), "'abcd'");
  EXPECT_EQ(QuoteForError("abcde", 4), "'abcd...' (5 bytes)");
  // A multi-byte character counts as one and is never cut in half.
  EXPECT_EQ(QuoteForError("ééé", 2), "'éé...' (6 bytes)");
}

TEST(QuoteForErrorTest, OutputIsBoundedAndValidUtf8ForEveryByte) {
  // Every single byte, and a long run of the worst case (bytes that each become \xNN).
  for (int b = 0; b < 256; ++b) {
    const std::string q = QuoteForError(std::string(1, static_cast<char>(b)));
    EXPECT_TRUE(IsValidUtf8(q)) << b;
    EXPECT_LE(q.size(), 6u) << b;
  }
  std::string worst;
  for (int i = 0; i < 100000; ++i) worst += static_cast<char>(0x80 + i % 64);
  const std::string q = QuoteForError(worst);
  EXPECT_TRUE(IsValidUtf8(q));
  EXPECT_LE(q.size(), 4u * 64 + 30);
  EXPECT_NE(q.find("(100000 bytes)"), std::string::npos);
}

}  // namespace
}  // namespace mav
