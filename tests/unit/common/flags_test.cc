#include "mav/common/flags.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace mav {
namespace {

struct Flags {
  int64_t frames = 0;
  int64_t offset = 0;
  uint64_t seed = 1;
  double resolution = 0.05;
  double gain = 1.0;
  bool force = false;
  std::string out;
};

// A parser shaped like mav-sim generate's: ranged and unranged flags of every kind.
FlagParser MakeParser(Flags* f) {
  FlagParser parser("test [flags]");
  parser.AddInt64("frames", &f->frames, "frames", 0, 1000000);
  parser.AddInt64("offset", &f->offset, "any integer");
  parser.AddUint64("seed", &f->seed, "seed");
  parser.AddDouble("resolution", &f->resolution, "voxel edge, m", 0.005, 1.0);
  parser.AddDouble("gain", &f->gain, "any finite number");
  parser.AddBool("force", &f->force, "switch");
  parser.AddString("out", &f->out, "directory");
  return parser;
}

Status Parse(const std::vector<std::string>& args, Flags* f) {
  FlagParser parser = MakeParser(f);
  return parser.Parse(args, nullptr);
}

TEST(FlagParserTest, ParsesEveryKind) {
  Flags f;
  ASSERT_TRUE(Parse({"--frames", "12", "--offset=-4", "--seed", "18446744073709551615",
                     "--resolution=0.1", "--gain", "-2.5", "--force", "--out", "dir"},
                    &f)
                  .ok());
  EXPECT_EQ(f.frames, 12);
  EXPECT_EQ(f.offset, -4);
  EXPECT_EQ(f.seed, UINT64_MAX);
  EXPECT_EQ(f.resolution, 0.1);
  EXPECT_EQ(f.gain, -2.5);
  EXPECT_TRUE(f.force);
  EXPECT_EQ(f.out, "dir");
}

// Defect 12: an integer too long for 64 bits was "not an integer".
TEST(FlagParserTest, HugeIntegerIsOutOfRangeNamingTheRange) {
  Flags f;
  Status s = Parse({"--frames", "99999999999999999999"}, &f);
  EXPECT_EQ(s.message(), "--frames: '99999999999999999999' is out of range [0, 1000000]");
  s = Parse({"--frames", "-3"}, &f);
  EXPECT_EQ(s.message(), "--frames: '-3' is out of range [0, 1000000]");
  s = Parse({"--frames", "1000001"}, &f);
  EXPECT_EQ(s.message(), "--frames: '1000001' is out of range [0, 1000000]");
  s = Parse({"--offset", "99999999999999999999"}, &f);
  EXPECT_EQ(s.message(),
            "--offset: '99999999999999999999' is out of range "
            "[-9223372036854775808, 9223372036854775807]");
  s = Parse({"--seed", "-1"}, &f);
  EXPECT_NE(s.message().find("--seed: '-1' is out of range [0, 18446744073709551615]"),
            std::string::npos)
      << s.message();
  s = Parse({"--frames", "ten"}, &f);
  EXPECT_EQ(s.message(), "--frames: 'ten' is not an integer");
  EXPECT_EQ(f.frames, 0) << "a refused value leaves the target alone";
}

// Defect 12: "--occupancy-resolution inf" was reported as "must be >= 0.005".
TEST(FlagParserTest, NonFiniteDoubleIsRefusedAsNotFinite) {
  for (const char* v : {"inf", "-inf", "nan", "infinity"}) {
    Flags f;
    Status s = Parse({"--resolution", v}, &f);
    EXPECT_EQ(s.message(), std::string("--resolution: must be a finite number, got '") + v + "'");
    s = Parse({"--gain", v}, &f);
    EXPECT_NE(s.message().find("--gain: must be a finite number"), std::string::npos);
    EXPECT_EQ(f.resolution, 0.05);
    EXPECT_EQ(f.gain, 1.0);
  }
  Flags f;
  EXPECT_EQ(Parse({"--resolution", "1e309"}, &f).message(),
            "--resolution: '1e309' is out of the range of a double (about +-1.8e308)");
  EXPECT_EQ(Parse({"--resolution", "0.001"}, &f).message(),
            "--resolution: '0.001' is out of range [0.005, 1]");
}

TEST(FlagParserTest, ErrorsQuoteValuesShortly) {
  Flags f;
  const std::string huge(20000, 'z');
  for (const std::vector<std::string>& args : {std::vector<std::string>{"--frames", huge},
                                               {"--force=" + huge},
                                               {"--" + huge},
                                               {"-" + huge},
                                               {huge},
                                               {"--out", "--" + huge}}) {
    const Status s = Parse(args, &f);
    ASSERT_FALSE(s.ok());
    EXPECT_LT(s.message().size(), 200u) << s.message().substr(0, 300);
    EXPECT_NE(s.message().find("bytes)"), std::string::npos) << s.message().substr(0, 300);
  }
  EXPECT_EQ(Parse({"--prot", "1"}, &f).message(), "unknown flag --prot (see --help)");
  EXPECT_EQ(Parse({"--pr\x01t"}, &f).message(), "unknown flag '--pr\\x01t' (see --help)");
  const Status s = Parse({"--force=yes\n"}, &f);
  EXPECT_EQ(s.message(), "--force: expected true or false, got 'yes\\n'");
}

TEST(FlagParserTest, HelpShowsRanges) {
  Flags f;
  const std::string help = MakeParser(&f).Help();
  EXPECT_NE(help.find("(default: 0, [0, 1000000])"), std::string::npos) << help;
  EXPECT_NE(help.find("(default: 0.05, [0.005, 1])"), std::string::npos) << help;
  EXPECT_NE(help.find("any integer (default: 0)\n"), std::string::npos) << help;
}

}  // namespace
}  // namespace mav
