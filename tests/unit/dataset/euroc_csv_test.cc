// The EuRoC CSV and sensor.yaml readers on text in memory and through EurocReader::Open: numbers
// must be finite (defect 3 of issue 8), a repeated time stamp in a user's file is dropped with a
// warning rather than refused (defect 16), and a set without stereo frames says why (defect 11).

#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mav/dataset/euroc.h"
#include "test_util.h"
#include "tests/common/build_paths.h"

namespace mav::dataset {
namespace {

namespace fs = std::filesystem;
using testing::ReadFile;
using testing::TempDir;
using testing::WriteFile;

const char kImuHeader[] =
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
    "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";

std::string GroundTruthRow(int64_t t_ns, const std::string& x) {
  return std::to_string(t_ns) + "," + x +
         ",2.14,0.94,0.060514,-0.828459,-0.058956,-0.553641,0.0094,-0.014,-0.0021,-0.0022,0.0207,"
         "0.076,-0.012,0.547,0.069\n";
}

TEST(EurocCsv, InfiniteOrHugeNumbersAreRefusedNamingFileLineAndColumn) {
  const std::string imu =
      std::string(kImuHeader) + "100,0.1,0.2,0.3,9.8,0.1,0.2\n" + "200,0.1,inf,0.3,9.8,0.1,0.2\n";
  Status s = ParseImuCsv(imu, "seq/imu0/data.csv").status();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(),
            "seq/imu0/data.csv:3: column 'w_RS_S_y [rad s^-1]': must be a finite number, got "
            "'inf'");

  for (const char* bad : {"-inf", "nan", "1e309", "1e300", "-2e9"}) {
    const std::string gt =
        "#timestamp,...\n" + GroundTruthRow(100, "0.87") + GroundTruthRow(200, bad);
    s = ParseGroundTruthCsv(gt, "gt.csv").status();
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(s.message().find("gt.csv:3: column 'p_RS_R_x [m]'"), std::string::npos)
        << s.message();
  }
  // Large but plausible values still read.
  const std::string gt = GroundTruthRow(100, "6378137.5") + GroundTruthRow(200, "-1e9");
  auto states = ParseGroundTruthCsv(gt, "gt.csv");
  ASSERT_TRUE(states.ok()) << states.status().ToString();
  EXPECT_EQ((*states)[1].T_world_body.Translation().x(), -1e9);
}

TEST(EurocCsv, RepeatedStampKeepsTheFirstRowAndWarnsNamingFileAndLine) {
  const std::string imu = std::string(kImuHeader) + "100,0.1,0.2,0.3,9.8,0.1,0.2\n" +
                          "200,1.1,0.2,0.3,9.8,0.1,0.2\n" + "200,2.1,0.2,0.3,9.8,0.1,0.2\n" +
                          "300,3.1,0.2,0.3,9.8,0.1,0.2\n";
  std::vector<std::string> warnings;
  ReadOptions options;
  options.warnings = &warnings;
  auto samples = ParseImuCsv(imu, "seq/imu0/data.csv", options);
  ASSERT_TRUE(samples.ok()) << samples.status().ToString();
  ASSERT_EQ(samples->size(), 3u);
  EXPECT_EQ((*samples)[1].t_ns, 200);
  EXPECT_EQ((*samples)[1].gyro.x(), 1.1) << "the first row of a repeated stamp is kept";
  EXPECT_EQ((*samples)[2].t_ns, 300);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0],
            "seq/imu0/data.csv:4: timestamp 200 repeats the previous row's; row dropped (first "
            "kept)");

  // The same for the ground truth; and strict callers still refuse it.
  const std::string gt = GroundTruthRow(100, "1") + GroundTruthRow(100, "2");
  warnings.clear();
  auto states = ParseGroundTruthCsv(gt, "gt.csv", options);
  ASSERT_TRUE(states.ok()) << states.status().ToString();
  ASSERT_EQ(states->size(), 1u);
  EXPECT_EQ((*states)[0].T_world_body.Translation().x(), 1.0);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("gt.csv:2: timestamp 100 repeats"), std::string::npos);
  ReadOptions strict;
  strict.repeated_stamps = RepeatedStamps::kReject;
  const Status s = ParseGroundTruthCsv(gt, "gt.csv", strict).status();
  EXPECT_EQ(s.message(), "gt.csv:2: timestamp 100 is not after the previous one (100)");
  EXPECT_FALSE(ParseImuCsv(imu, "imu.csv", strict).ok());
}

TEST(EurocCsv, TimeGoingBackwardsIsStillAnError) {
  const std::string imu =
      std::string(kImuHeader) + "200,0.1,0.2,0.3,9.8,0.1,0.2\n" + "199,0.1,0.2,0.3,9.8,0.1,0.2\n";
  const Status s = ParseImuCsv(imu, "imu.csv").status();
  EXPECT_EQ(s.message(), "imu.csv:3: timestamp 199 is not after the previous one (200)");
  // A dropped repeat is still checked: a malformed duplicate row is an error.
  const std::string bad_repeat =
      std::string(kImuHeader) + "200,0.1,0.2,0.3,9.8,0.1,0.2\n" + "200,0.1,x,0.3,9.8,0.1,0.2\n";
  EXPECT_NE(ParseImuCsv(bad_repeat, "imu.csv").status().message().find("imu.csv:3: column"),
            std::string::npos);
}

TEST(EurocCsv, CameraRowsStayStrictAndFileNamesAreQuotedShortly) {
  Status s = ParseCameraCsv("#t,f\n1,1.png\n1,2.png\n", "cam0/data.csv").status();
  EXPECT_EQ(s.message(), "cam0/data.csv:3: timestamp 1 is not after the previous one (1)");
  const std::string long_name = "../" + std::string(5000, 'a') + "\n";
  s = ParseCameraCsv("1," + long_name, "cam0/data.csv").status();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_LT(s.message().size(), 200u) << s.message().substr(0, 300);
  EXPECT_NE(s.message().find("is not a plain file name"), std::string::npos) << s.message();
  auto rows = ParseCameraCsv("#t,f\n1,1.png\n2, 2.png\r\n", "cam0/data.csv");
  ASSERT_TRUE(rows.ok());
  EXPECT_EQ(rows->t_ns, (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(rows->files, (std::vector<std::string>{"1.png", "2.png"}));
}

TEST(EurocCsv, SensorYamlFromMemoryNamesTheGivenName) {
  const std::string yaml =
      ReadFile(mav::testing::SourceDir() + "/tests/data/euroc_tiny/mav0/imu0/sensor.yaml");
  auto imu = ParseImuSensorYaml(yaml, "upload:imu0/sensor.yaml");
  ASSERT_TRUE(imu.ok()) << imu.status().ToString();
  EXPECT_EQ(imu->rate_hz, 200);
  std::string bad = yaml;
  bad.replace(bad.find("rate_hz: 200"), 12, "rate_hz: inf");
  const Status s = ParseImuSensorYaml(bad, "upload:imu0/sensor.yaml").status();
  EXPECT_EQ(s.message(),
            "upload:imu0/sensor.yaml: field 'rate_hz': must be a finite number, got 'inf'");
}

// A copy of tests/data/euroc_tiny without images (Open does not read them).
class EurocOpen : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = dir_.path() + "/seq";
    fs::copy(mav::testing::SourceDir() + "/tests/data/euroc_tiny", root_,
             fs::copy_options::recursive);
  }
  std::string Path(const std::string& rel) const { return root_ + "/mav0/" + rel; }
  void AppendLine(const std::string& rel, const std::string& line) {
    WriteFile(Path(rel), ReadFile(Path(rel)) + line + "\n");
  }
  // The last line of a file.
  std::string LastLine(const std::string& rel) const {
    std::string text = ReadFile(Path(rel));
    while (!text.empty() && text.back() == '\n') text.pop_back();
    return text.substr(text.rfind('\n') + 1);
  }

  TempDir dir_;
  std::string root_;
};

TEST_F(EurocOpen, InfiniteGroundTruthPositionIsRefused) {
  AppendLine("state_groundtruth_estimate0/data.csv", GroundTruthRow(1403715273277142784, "inf"));
  const Status s = EurocReader::Open(root_).status();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("state_groundtruth_estimate0/data.csv:5: column 'p_RS_R_x [m]': "
                             "must be a finite number"),
            std::string::npos)
      << s.message();
}

TEST_F(EurocOpen, RepeatedImuAndGroundTruthStampsOpenWithWarnings) {
  AppendLine("imu0/data.csv", LastLine("imu0/data.csv"));
  AppendLine("state_groundtruth_estimate0/data.csv",
             LastLine("state_groundtruth_estimate0/data.csv"));
  std::vector<std::string> warnings;
  ReadOptions options;
  options.warnings = &warnings;
  auto reader = EurocReader::Open(root_, options);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  EXPECT_EQ(reader->imu().size(), 5u);
  EXPECT_EQ(reader->ground_truth().size(), 3u);
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_NE(warnings[0].find("imu0/data.csv:7: timestamp 1403715273282142976 repeats"),
            std::string::npos)
      << warnings[0];
  EXPECT_NE(warnings[1].find("state_groundtruth_estimate0/data.csv:5: timestamp"),
            std::string::npos)
      << warnings[1];
  // Logged (not collected) by default, and refused when asked to be strict.
  EXPECT_TRUE(EurocReader::Open(root_).ok());
  ReadOptions strict;
  strict.repeated_stamps = RepeatedStamps::kReject;
  const Status s = EurocReader::Open(root_, strict).status();
  EXPECT_NE(s.message().find("imu0/data.csv:7: timestamp 1403715273282142976 is not after"),
            std::string::npos)
      << s.message();
}

TEST_F(EurocOpen, NoStereoFramesSaysWhyNamingTheDirectory) {
  {
    auto reader = EurocReader::Open(root_);
    ASSERT_TRUE(reader.ok());
    EXPECT_TRUE(reader->CheckHasFrames().ok());
    EXPECT_EQ(reader->cam0_rows(), 4);
    EXPECT_EQ(reader->cam1_rows(), 3);
  }
  WriteFile(Path("cam1/data.csv"), "#timestamp [ns],filename\n");
  auto reader = EurocReader::Open(root_);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  Status s = reader->CheckHasFrames();
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(s.message(), root_ + "/mav0: no stereo frames: cam1/data.csv has no rows (cam0 has 4)");
  WriteFile(Path("cam1/data.csv"), "#timestamp [ns],filename\n5,5.png\n");
  reader = EurocReader::Open(root_);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  EXPECT_EQ(reader->CheckHasFrames().message(),
            root_ +
                "/mav0: no stereo frames: cam0/data.csv (4 rows) and cam1/data.csv (1 rows) "
                "share no timestamp");
}

}  // namespace
}  // namespace mav::dataset
