// ValidateOctomapBinary / ReadOctomapBinary: OctoMap .bt bytes checked before OctoMap sees them.

#include "mav/dataset/octomap_bt.h"

#include <octomap/OcTree.h>

#include <cmath>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "test_util.h"
#include "tests/common/build_paths.h"

namespace mav::dataset {
namespace {

const char kHeader[] =
    "# Octomap OcTree binary file\n# (a comment)\n#\nid OcTree\nsize SIZE\nres 0.1\ndata\n";

std::string Header(int64_t size, const std::string& res = "0.1") {
  std::string h = kHeader;
  h.replace(h.find("SIZE"), 4, std::to_string(size));
  h.replace(h.find("res 0.1"), 7, "res " + res);
  return h;
}

// A small tree written by OctoMap itself.
std::string SmallTreeBytes(octomap::OcTree* tree) {
  for (int i = 0; i < 20; ++i) {
    tree->updateNode(octomap::point3d(0.1f * i, 0.05f * i, 0.3f), i % 3 != 0);
  }
  std::ostringstream out;
  EXPECT_TRUE(tree->writeBinary(out));
  return out.str();
}

TEST(OctomapBt, SmallTreeRoundTrips) {
  octomap::OcTree written(0.1);
  const std::string bytes = SmallTreeBytes(&written);
  OctomapBinaryInfo info;
  ASSERT_TRUE(ValidateOctomapBinary(bytes, "small.bt", {}, &info).ok());
  EXPECT_EQ(info.id, "OcTree");
  EXPECT_EQ(info.resolution_m, 0.1);
  EXPECT_EQ(info.num_nodes, static_cast<int64_t>(written.size()));
  auto read = ReadOctomapBinary(bytes, "small.bt");
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_EQ((*read)->size(), written.size());
  EXPECT_EQ((*read)->getNumLeafNodes(), written.getNumLeafNodes());
  EXPECT_EQ((*read)->getResolution(), 0.1);
}

TEST(OctomapBt, ReadsThePowerPlantMap) {
  const std::string path = mav::testing::SourceDir() + "/maps/power_plant.bt";
  const std::string bytes = testing::ReadFile(path);
  OctomapBinaryInfo info;
  const Status s = ValidateOctomapBinary(bytes, path, {}, &info);
  ASSERT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(info.num_nodes, 377475);
  EXPECT_EQ(info.resolution_m, 0.25);
  auto tree = ReadOctomapBinary(bytes, path);
  ASSERT_TRUE(tree.ok()) << tree.status().ToString();
  EXPECT_EQ((*tree)->size(), 377475u);
  EXPECT_EQ((*tree)->getNumLeafNodes(), 328805u);  // as maps/README.md says
}

TEST(OctomapBt, MalformedBytesAreRefusedBeforeOctomapSeesThem) {
  octomap::OcTree written(0.1);
  const std::string good = SmallTreeBytes(&written);
  const size_t data_start = good.find("data\n") + 5;
  const std::string data = good.substr(data_start);
  const int64_t n = static_cast<int64_t>(written.size());
  const struct {
    std::string bytes;
    std::string expected;
  } cases[] = {
      {"", "first line is not"},
      {std::string("\x03\0\0\0", 4) + "legacy", "first line is not"},
      {good.substr(0, good.size() - 1), "truncated"},
      {good + "x", "1 bytes after the end of the tree"},
      {Header(n + 1) + data, "size says " + std::to_string(n + 1)},
      {Header(n, "nan") + data, "res 'nan' is not a decimal number"},
      {Header(n, "inf") + data, "res 'inf' is not a decimal number"},
      {Header(n, "1e999") + data, "out of the range of a double"},
      {Header(n, "-0.1") + data, "outside [0.001"},
      {Header(n, "0x10") + data, "is not a decimal number"},
      {Header(n, "1e-320") + data, "outside [0.001"},
      {Header(99999999999) + data, "exceeds 32 bits"},
      {Header(-1) + data, "header: size"},
      {Header(20000000) + data, "above the limit"},
      // Every child an inner node, 2 bytes a level: OctoMap recursed past depth 16.
      {Header(1000) + std::string(4000, '\xff'), "deeper than 16 levels"},
      {"# Octomap OcTree binary file\nid OcTree\r\nsize 1\nres 0.1\ndata\n" + std::string(2, '\0'),
       "carriage return"},
      {"# Octomap OcTree binary file\nid OcTree\nres 0.1\ndata\n", "missing 'size'"},
      {"# Octomap OcTree binary file\nid OcTree\nsize 1\nres 0.1\n", "ends before the 'data'"},
      {"# Octomap OcTree binary file\nid OcTree\nsize 1\nres 0.1\nfoo bar\ndata\n",
       "unknown keyword 'foo'"},
  };
  for (const auto& c : cases) {
    const Status s = ValidateOctomapBinary(c.bytes, "up.bt");
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << c.expected;
    EXPECT_NE(s.message().find("up.bt: "), std::string::npos) << s.message();
    EXPECT_NE(s.message().find(c.expected), std::string::npos)
        << "expected '" << c.expected << "' in: " << s.message();
    EXPECT_FALSE(ReadOctomapBinary(c.bytes, "up.bt").ok());
  }
}

TEST(OctomapBt, NodeLimitCountsEveryNode) {
  octomap::OcTree written(0.1);
  const std::string bytes = SmallTreeBytes(&written);
  OctomapReadLimits limits;
  limits.max_nodes = static_cast<int64_t>(written.size());
  EXPECT_TRUE(ValidateOctomapBinary(bytes, "t.bt", limits).ok());
  limits.max_nodes -= 1;
  EXPECT_NE(ValidateOctomapBinary(bytes, "t.bt", limits).message().find("above the limit"),
            std::string::npos);
  limits.max_nodes = 0;
  EXPECT_NE(ValidateOctomapBinary(bytes, "t.bt", limits).message().find("limits: max_nodes"),
            std::string::npos);
}

TEST(OctomapBt, EmptyTree) {
  const std::string bytes = Header(0);
  OctomapBinaryInfo info;
  ASSERT_TRUE(ValidateOctomapBinary(bytes, "e.bt", {}, &info).ok());
  EXPECT_EQ(info.num_nodes, 0);
  auto tree = ReadOctomapBinary(bytes, "e.bt");
  ASSERT_TRUE(tree.ok()) << tree.status().ToString();
  EXPECT_EQ((*tree)->size(), 0u);
}

}  // namespace
}  // namespace mav::dataset
