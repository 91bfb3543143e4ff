#include "mav/mapping/mesh.h"

#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "mav/common/file.h"
#include "tests/common/build_paths.h"

namespace mav::mapping {
namespace {

TriangleMesh Tetrahedron() {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1.5}};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

std::string TempPath(const std::string& name) {
  return mav::testing::BinaryDir() + "/mapping_mesh_test_" + name;
}

TEST(PlyTest, RoundTripBothEncodings) {
  const TriangleMesh mesh = Tetrahedron();
  for (PlyEncoding encoding : {PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian}) {
    const std::string path = TempPath(encoding == PlyEncoding::kAscii ? "ascii.ply" : "binary.ply");
    ASSERT_TRUE(WritePly(path, mesh, encoding).ok());
    const auto read = ReadPly(path);
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    ASSERT_EQ(read->vertices.size(), 4u);
    ASSERT_EQ(read->triangles.size(), 4u);
    for (size_t i = 0; i < 4; ++i) {
      EXPECT_TRUE(read->vertices[i].isApprox(mesh.vertices[i], 1e-6));
      EXPECT_EQ(read->triangles[i], mesh.triangles[i]);
    }
    EXPECT_NEAR(read->Area(), mesh.Area(), 1e-6);
    std::remove(path.c_str());
  }
}

TEST(PlyTest, HeaderIsStandard) {
  const std::string bytes = EncodePly(Tetrahedron(), PlyEncoding::kAscii);
  EXPECT_EQ(bytes.rfind("ply\nformat ascii 1.0\n", 0), 0u);
  EXPECT_NE(bytes.find("element vertex 4\n"), std::string::npos);
  EXPECT_NE(bytes.find("element face 4\n"), std::string::npos);
  EXPECT_NE(bytes.find("property list uchar int vertex_indices\n"), std::string::npos);
}

TEST(PlyTest, ReadsDoublesAndExtraProperties) {
  const std::string text =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
      "property double z\nproperty uchar red\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n"
      "0 0 0 255\n1 0 0 255\n0 1 0 255\n3 0 1 2\n";
  const auto mesh = DecodePly(text, "inline");
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_EQ(mesh->vertices.size(), 3u);
  EXPECT_EQ(mesh->triangles.size(), 1u);
}

TEST(PlyTest, BadInputNamesTheProblem) {
  auto r = DecodePly("plx\n", "a.ply");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("a.ply"), std::string::npos);
  // Truncated binary body.
  std::string bytes = EncodePly(Tetrahedron(), PlyEncoding::kBinaryLittleEndian);
  bytes.resize(bytes.size() - 5);
  r = DecodePly(bytes, "b.ply");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("truncated"), std::string::npos);
  // Face index out of range.
  r = DecodePly(
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n3 0 0 7\n",
      "c.ply");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("face[0]"), std::string::npos);
  EXPECT_FALSE(ReadPly(TempPath("does_not_exist.ply")).ok());
}

}  // namespace
}  // namespace mav::mapping
