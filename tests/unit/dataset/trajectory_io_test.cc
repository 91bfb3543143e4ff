#include "mav/dataset/trajectory_io.h"

#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <limits>

#include "test_util.h"

namespace mav::dataset {
namespace {

using testing::ReadFile;
using testing::TempDir;
using testing::WriteFile;

// What we wrote ourselves never repeats a stamp: read it back strictly.
ReadOptions Strict() {
  ReadOptions options;
  options.repeated_stamps = RepeatedStamps::kReject;
  return options;
}

Eigen::Quaterniond RandomQuaternion(std::mt19937* rng) {
  std::normal_distribution<double> n;
  return Eigen::Quaterniond(n(*rng), n(*rng), n(*rng), n(*rng)).normalized();
}

std::vector<StampedPose> RandomPoses(int count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n;
  std::uniform_int_distribution<int64_t> step(1, 90'000'000);
  std::vector<StampedPose> poses(count);
  int64_t t = 1403715273262142976;
  for (int i = 0; i < count; ++i) {
    t += step(rng);
    poses[i].t_ns = t;
    poses[i].T_world_body =
        geometry::SE3(RandomQuaternion(&rng), Eigen::Vector3d(n(rng), n(rng), n(rng)) * 10.0);
  }
  return poses;
}

TEST(Tum, RoundTripIsExact) {
  TempDir dir;
  const std::string path = dir.path() + "/traj.txt";
  const std::vector<StampedPose> poses = RandomPoses(500, 1);
  ASSERT_TRUE(WriteTumTrajectory(path, poses).ok());
  auto read = ReadTumTrajectory(path, Strict());
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ((*read)[i].t_ns, poses[i].t_ns);
    EXPECT_EQ((*read)[i].T_world_body.Translation(), poses[i].T_world_body.Translation());
    EXPECT_EQ((*read)[i].T_world_body.Rotation().coeffs(),
              poses[i].T_world_body.Rotation().coeffs());
  }
  // Rewriting what was read gives the same bytes.
  ASSERT_TRUE(WriteTumTrajectory(path + "2", *read).ok());
  EXPECT_EQ(ReadFile(path), ReadFile(path + "2"));
}

TEST(Tum, ManyRandomQuaternionsRoundTripBitForBit) {
  // SE3 keeps a quaternion that is unit to rounding as it is, so every normalised quaternion
  // written with shortest round-trip digits reads back bit for bit.
  TempDir dir;
  const std::string path = dir.path() + "/traj.txt";
  const std::vector<StampedPose> poses = RandomPoses(2000, 2);
  ASSERT_TRUE(WriteTumTrajectory(path, poses).ok());
  auto read = ReadTumTrajectory(path, Strict());
  ASSERT_TRUE(read.ok());
  ASSERT_EQ(read->size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ((*read)[i].t_ns, poses[i].t_ns);
    EXPECT_EQ((*read)[i].T_world_body.Translation(), poses[i].T_world_body.Translation());
    EXPECT_EQ((*read)[i].T_world_body.Rotation().coeffs(),
              poses[i].T_world_body.Rotation().coeffs())
        << "pose " << i;
  }
}

TEST(Tum, TimestampsAreWrittenWithNineDecimals) {
  TempDir dir;
  const std::string path = dir.path() + "/traj.txt";
  std::vector<StampedPose> poses(3);
  poses[0].t_ns = -1'500'000'000;
  poses[1].t_ns = 5;
  poses[2].t_ns = 1403715273262142976;
  ASSERT_TRUE(WriteTumTrajectory(path, poses).ok());
  const std::string text = ReadFile(path);
  EXPECT_NE(text.find("\n-1.500000000 0 0 0 0 0 0 1\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\n0.000000005 "), std::string::npos) << text;
  EXPECT_NE(text.find("\n1403715273.262142976 "), std::string::npos) << text;
  auto read = ReadTumTrajectory(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_EQ((*read)[0].t_ns, -1'500'000'000);
  EXPECT_EQ((*read)[1].t_ns, 5);
  EXPECT_EQ((*read)[2].t_ns, 1403715273262142976);
}

TEST(Tum, ReadsOtherToolsSpelling) {
  TempDir dir;
  const std::string path = dir.path() + "/traj.txt";
  WriteFile(path,
            "# written by some other tool\n"
            "\n"
            "1403715273.26   1.0\t2.0 3.0 0 0 0 1\r\n"
            "   # indented comment\n"
            "1.4037152733e9 1 2 3 0 0 0.7071067811865476 0.7071067811865476\n");
  auto read = ReadTumTrajectory(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), 2u);
  EXPECT_EQ((*read)[0].t_ns, 1403715273260000000);
  EXPECT_EQ((*read)[0].T_world_body.Translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ((*read)[1].t_ns, 1403715273300000000);
  EXPECT_NEAR((*read)[1].T_world_body.Rotation().z(), std::sqrt(0.5), 1e-15);
}

TEST(Tum, BadInputNamesLineAndField) {
  TempDir dir;
  const std::string path = dir.path() + "/traj.txt";
  EXPECT_EQ(ReadTumTrajectory(path).status().code(), StatusCode::kNotFound);

  WriteFile(path, "# header\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 x 0 1\n");
  Status s = ReadTumTrajectory(path).status();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find(path + ":3: column 'qy'"), std::string::npos) << s.message();

  WriteFile(path, "1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n");
  s = ReadTumTrajectory(path).status();
  EXPECT_NE(s.message().find(path + ":2: expected 8 columns, got 7"), std::string::npos)
      << s.message();

  WriteFile(path, "1.0 0 0 0 0 0 0 1\n0.5 0 0 0 0 0 0 1\n");
  s = ReadTumTrajectory(path).status();
  EXPECT_NE(s.message().find(path + ":2: timestamp"), std::string::npos) << s.message();

  WriteFile(path, "1.0 0 0 0 0 0 0 0\n");
  s = ReadTumTrajectory(path).status();
  EXPECT_NE(s.message().find("zero norm"), std::string::npos) << s.message();

  WriteFile(path, "1.0.0 0 0 0 0 0 0 1\n");
  s = ReadTumTrajectory(path).status();
  EXPECT_NE(s.message().find("column 'timestamp'"), std::string::npos) << s.message();
}

// Defect 16 of issue 8: TUM's own fr2/desk ground truth and ORB-SLAM's TUM output of EuRoC V1_02
// each repeat one stamp; such files used to be refused ("is not after the previous one").
TEST(Tum, RepeatedStampFromTheFieldKeepsTheFirstRowWithAWarning) {
  TempDir dir;
  const std::string path = dir.path() + "/groundtruth.txt";
  // The shape of those files (numbers made up): a header, then one stamp twice in a row.
  WriteFile(path,
            "# ground truth trajectory\n"
            "# timestamp tx ty tz qx qy qz qw\n"
            "1311868164.3631 -0.1 0.2 1.5 0.65 0.62 -0.29 -0.30\n"
            "1311868164.3731 -0.1 0.2 1.6 0.65 0.62 -0.29 -0.30\n"
            "1311868164.3731 -0.9 0.9 1.9 0.65 0.62 -0.29 -0.30\n"
            "1311868164.3831 -0.1 0.2 1.7 0.65 0.62 -0.29 -0.30\n");
  std::vector<std::string> warnings;
  ReadOptions options;
  options.warnings = &warnings;
  auto read = ReadTumTrajectory(path, options);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), 3u);
  EXPECT_EQ((*read)[1].t_ns, 1311868164373100000);
  EXPECT_EQ((*read)[1].T_world_body.Translation().z(), 1.6) << "the first row is kept";
  EXPECT_EQ((*read)[2].T_world_body.Translation().z(), 1.7);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0], path +
                             ":5: timestamp 1311868164373100000 repeats the previous row's; "
                             "row dropped (first kept)");
  // Default options: accepted too (the warning is logged).
  EXPECT_TRUE(ReadTumTrajectory(path).ok());
  // Strict, for our own outputs.
  ReadOptions strict;
  strict.repeated_stamps = RepeatedStamps::kReject;
  EXPECT_NE(ReadTumTrajectory(path, strict).status().message().find(path + ":5: timestamp"),
            std::string::npos);
  // Backwards is still an error.
  WriteFile(path, "2.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1\n1.5 0 0 0 0 0 0 1\n");
  EXPECT_NE(ReadTumTrajectory(path).status().message().find(path + ":3: timestamp 1500000000 is "
                                                                   "not after the previous one"),
            std::string::npos);
}

TEST(Tum, NonFiniteHugeAndOutOfRangeValuesAreRefused) {
  const struct {
    const char* row;
    const char* expected;
  } cases[] = {
      {"1.0 inf 0 0 0 0 0 1", "mem:1: column 'tx': must be a finite number, got 'inf'"},
      {"1.0 0 -inf 0 0 0 0 1", "mem:1: column 'ty': must be a finite number"},
      {"1.0 0 0 1e300 0 0 0 1", "mem:1: column 'tz': '1e300' is beyond +-1e9"},
      {"1.0 0 0 0 0 0 0 nan", "mem:1: column 'qw': must be a finite number"},
      // Ten digits of seconds overflowed int64 nanoseconds (undefined behaviour) before.
      {"9999999999.5 0 0 0 0 0 0 1", "mem:1: column 'timestamp': '9999999999.5' s is out of range"},
      {"-9999999999 0 0 0 0 0 0 1", "mem:1: column 'timestamp': '-9999999999' s is out of range"},
      {"1e300 0 0 0 0 0 0 1", "mem:1: column 'timestamp': '1e300' s is out of range"},
      {"inf 0 0 0 0 0 0 1", "mem:1: column 'timestamp': must be a finite number"},
  };
  for (const auto& c : cases) {
    const Status s = ParseTumTrajectory(c.row, "mem").status();
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << c.row;
    EXPECT_NE(s.message().find(c.expected), std::string::npos) << c.row << " -> " << s.message();
  }
  auto ok = ParseTumTrajectory("9223372035.999999999 0 0 0 0 0 0 1\n", "mem");
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  EXPECT_EQ(ok->front().t_ns, 9223372035999999999);
}

TEST(Kitti, InMemoryAndLineNumbersCountCommentsAndBlanks) {
  auto poses = ParseKittiTrajectory("1 0 0 5 0 1 0 6 0 0 1 7\n", "upload.txt");
  ASSERT_TRUE(poses.ok()) << poses.status().ToString();
  EXPECT_EQ(poses->front().Translation(), Eigen::Vector3d(5, 6, 7));
  const Status s =
      ParseKittiTrajectory("# poses\n\n1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 1 0 0 0 0 1 0\n",
                           "upload.txt")
          .status();
  EXPECT_NE(s.message().find("upload.txt:4: rotation block is not a rotation"), std::string::npos)
      << s.message();
  EXPECT_NE(ParseKittiMatrices("1 0 0 inf 0 1 0 0 0 0 1 0\n", "k")
                .status()
                .message()
                .find("k:1: column 'tx': must be a finite number"),
            std::string::npos);
}

TEST(Kitti, MatricesRoundTripExactlyAndRewriteIsByteIdentical) {
  TempDir dir;
  const std::string path = dir.path() + "/poses.txt";
  const std::vector<StampedPose> stamped = RandomPoses(300, 3);
  std::vector<geometry::SE3> poses;
  for (const StampedPose& p : stamped) poses.push_back(p.T_world_body);
  ASSERT_TRUE(WriteKittiTrajectory(path, poses).ok());

  auto matrices = ReadKittiMatrices(path);
  ASSERT_TRUE(matrices.ok()) << matrices.status().ToString();
  ASSERT_EQ(matrices->size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ((*matrices)[i], poses[i].Matrix3x4()) << "pose " << i;
  }
  ASSERT_TRUE(WriteKittiMatrices(path + "2", *matrices).ok());
  EXPECT_EQ(ReadFile(path), ReadFile(path + "2"));

  // Through SE3, which stores a quaternion: matrix -> quaternion -> matrix costs a few units in
  // the last place (entries are <= 1, so 8 ulp of 1.0 bounds it).
  auto read = ReadKittiTrajectory(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ((*read)[i].Translation(), poses[i].Translation());
    EXPECT_LE(((*read)[i].Matrix3x4() - poses[i].Matrix3x4()).cwiseAbs().maxCoeff(),
              8 * std::numeric_limits<double>::epsilon())
        << "pose " << i;
  }
}

TEST(Kitti, BadInput) {
  TempDir dir;
  const std::string path = dir.path() + "/poses.txt";
  EXPECT_EQ(ReadKittiTrajectory(path).status().code(), StatusCode::kNotFound);

  WriteFile(path, "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n");
  Status s = ReadKittiTrajectory(path).status();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find(path + ":2: expected 12 columns, got 11"), std::string::npos)
      << s.message();

  WriteFile(path, "1 0 0 0 0 1 nan? 0 0 0 1 0\n");
  s = ReadKittiTrajectory(path).status();
  EXPECT_NE(s.message().find(path + ":1: column 'r12'"), std::string::npos) << s.message();

  WriteFile(path, "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 1 0 0 0 0 1 0\n");
  s = ReadKittiTrajectory(path).status();
  EXPECT_NE(s.message().find("not a rotation"), std::string::npos) << s.message();
  // The raw matrices are still readable.
  EXPECT_TRUE(ReadKittiMatrices(path).ok());
}

}  // namespace
}  // namespace mav::dataset
