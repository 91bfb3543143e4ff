// Runs the built mav-sim and mav-eval binaries on small generated data sets with one thing
// broken, as a user would: each run must end quickly with a message that names the real problem
// (defects 1, 3 and 11 of issue 8).

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/unit/dataset/test_util.h"

namespace {

namespace fs = std::filesystem;

using mav::dataset::testing::ReadFile;
using mav::dataset::testing::RunResult;
using mav::dataset::testing::RunTool;
using mav::dataset::testing::WriteFile;

class MavEvalCli : public ::testing::Test {
 protected:
  // One 12-frame room-easy set for the whole suite; each test works on its own copy.
  static void SetUpTestSuite() {
    base_ = (fs::temp_directory_path() / ("mav_eval_cli_" + std::to_string(getpid()))).string();
    fs::remove_all(base_);
    const RunResult r = RunTool("mav-sim",
                                "generate --preset room-easy --frames 12 --seed 5 "
                                "--threads 2 --out " +
                                    base_ + "/set");
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  static void TearDownTestSuite() { fs::remove_all(base_); }

  void SetUp() override {
    set_ = base_ + "/" + ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(set_);
    fs::copy(base_ + "/set", set_, fs::copy_options::recursive);
  }

  std::string Gt() const { return set_ + "/mav0/state_groundtruth_estimate0/data.csv"; }

  // Sets p_x of the ground-truth row at frame `frame`'s time stamp; returns its line number.
  int SetGroundTruthX(int frame, const std::string& x) {
    const std::string cam = ReadFile(set_ + "/mav0/cam0/data.csv");
    std::istringstream cam_lines(cam);
    std::string line, stamp;
    for (int i = 0; i <= frame + 1 && std::getline(cam_lines, line); ++i) {
      stamp = line.substr(0, line.find(','));
    }
    std::istringstream in(ReadFile(Gt()));
    std::string out;
    int number = 0, found = 0;
    while (std::getline(in, line)) {
      ++number;
      if (line.rfind(stamp + ",", 0) == 0) {
        const size_t a = line.find(',');
        const size_t b = line.find(',', a + 1);
        line = line.substr(0, a + 1) + x + line.substr(b);
        found = number;
      }
      out += line + "\n";
    }
    WriteFile(Gt(), out);
    return found;
  }

  static std::string base_;
  std::string set_;
};

std::string MavEvalCli::base_;

TEST_F(MavEvalCli, RunsOnTheUntouchedSet) {
  const RunResult r = RunTool("mav-eval", "localization --data " + set_);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(set_ + "/eval/trajectories.png"));
}

// Defect 1: a huge ground-truth position made the plot draw ~1e8 grid lines.
TEST_F(MavEvalCli, HugeGroundTruthPositionFinishesQuickly) {
  ASSERT_GT(SetGroundTruthX(6, "5e8"), 0);
  // The deadline is the call's own: `timeout` stops a run that draws for too long (exit 124).
  const RunResult r = RunTool("mav-eval", "localization --data " + set_, /*timeout_s=*/60);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(set_ + "/eval/trajectories.png"));
}

// Defects 1 and 3: an infinite position is refused by the reader, naming file and line.
TEST_F(MavEvalCli, InfiniteGroundTruthPositionIsRefusedNamingFileAndLine) {
  const int line = SetGroundTruthX(6, "inf");
  ASSERT_GT(line, 0);
  const RunResult r = RunTool("mav-eval", "localization --data " + set_);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("state_groundtruth_estimate0/data.csv:" + std::to_string(line) +
                          ": column 'p_RS_R_x [m]': must be a finite number, got 'inf'"),
            std::string::npos)
      << r.output;
  const RunResult info = RunTool("mav-sim", "info " + set_);
  EXPECT_NE(info.exit_code, 0);
  EXPECT_EQ(info.output.find("inf m"), std::string::npos) << info.output;
}

// Defect 11: without stereo frames, say so (not "no pose lies inside the ground truth's span").
TEST_F(MavEvalCli, NoStereoFramesSaysWhyNamingTheDirectory) {
  WriteFile(set_ + "/mav0/cam1/data.csv", "#timestamp [ns],filename\n");
  for (const char* command : {"localization", "mapping"}) {
    const RunResult r = RunTool("mav-eval", std::string(command) + " --data " + set_);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(set_ + "/mav0: no stereo frames: cam1/data.csv has no rows (cam0 has "
                                   "12)"),
              std::string::npos)
        << command << ": " << r.output;
    EXPECT_EQ(r.output.find("time span"), std::string::npos) << r.output;
  }
  // cam0 and cam1 with rows that share no stamp.
  WriteFile(set_ + "/mav0/cam1/data.csv", "#timestamp [ns],filename\n7,7.png\n");
  const RunResult r = RunTool("mav-eval", "localization --data " + set_);
  EXPECT_NE(r.output.find("share no timestamp"), std::string::npos) << r.output;
}

// The map preference, the weak-surface weight and the occlusion check's range and margin are
// checked before any work, naming the flag or the field.
TEST_F(MavEvalCli, MappingPreferenceIsValidated) {
  RunResult r = RunTool("mav-eval", "mapping --method sparse-mesh --prefer fast --data " + set_);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--prefer: 'fast' is not safety or mcc"), std::string::npos) << r.output;
  r = RunTool("mav-eval", "mapping --method sparse-mesh --weak-surface-weight -2 --data " + set_);
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("weak_surface_weight must be >= 0"), std::string::npos) << r.output;
  r = RunTool("mav-eval",
              "mapping --method sparse-mesh --occlusion-check-range -1.5 --data " + set_);
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("occlusion_check.min_range_m: must be finite and > 0"), std::string::npos)
      << r.output;
  r = RunTool("mav-eval",
              "mapping --method sparse-mesh --occlusion-check-margin -1 --data " + set_);
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("occlusion_check.margin_m: must be finite and >= 0"), std::string::npos)
      << r.output;
}

// A figure of the JSON report, or NaN when the key is missing.
double JsonNumber(const std::string& json, const std::string& key) {
  const size_t at = json.find("\"" + key + "\": ");
  if (at == std::string::npos) return std::nan("");
  return std::stod(json.substr(at + key.size() + 4));
}

// The sparse-mesh grid is written in the stack's own format too, the protocol's sensitivity is
// reported, and the weak-surface view gate and the stereo uniqueness ratio are checked before any
// work.
TEST_F(MavEvalCli, MappingWritesTheGridAsMavocc) {
  RunResult r = RunTool("mav-eval", "mapping --method sparse-mesh --no-figure --json " + set_ +
                                        "/mapping.json --data " + set_);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Protocol sensitivity"), std::string::npos) << r.output;
  // A truth one voxel thicker never misses a collision and loses MCC; one voxel thinner misses.
  const std::string json = ReadFile(set_ + "/mapping.json");
  EXPECT_EQ(JsonNumber(json, "dilated_1_missed_collision_pct"), 0.0) << json;
  EXPECT_GT(JsonNumber(json, "dilated_1_false_collision_pct"), 0.0) << json;
  EXPECT_LT(JsonNumber(json, "dilated_1_mcc"), 1.0) << json;
  EXPECT_LT(JsonNumber(json, "dilated_2_mcc"), JsonNumber(json, "dilated_1_mcc")) << json;
  EXPECT_GT(JsonNumber(json, "eroded_1_missed_collision_pct"), 0.0) << json;
  // Unknown counts as occupied: hiding the free space no keyframe saw can only add false ones.
  EXPECT_EQ(JsonNumber(json, "unobservable_unknown_missed_collision_pct"), 0.0) << json;
  // The error attribution is off by default; with it, setting every wrong voxel of one kind right
  // removes every outcome of that kind, and the distance classes add up to all of them.
  EXPECT_TRUE(std::isnan(JsonNumber(json, "blocked_all_voxels"))) << json;
  r = RunTool("mav-eval", "mapping --method sparse-mesh --no-figure --error-attribution --json " +
                              set_ + "/attribution.json --data " + set_);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Error attribution, sparse-mesh"), std::string::npos) << r.output;
  const std::string attribution = ReadFile(set_ + "/attribution.json");
  EXPECT_EQ(JsonNumber(attribution, "blocked_all_fixed_false_collision_pct"), 0.0);
  EXPECT_EQ(JsonNumber(attribution, "free_all_fixed_missed_collision_pct"), 0.0);
  double by_distance = 0, by_height = 0;
  for (const char* c : {"blocked_at_1", "blocked_at_2", "blocked_at_3", "blocked_beyond_3"}) {
    by_distance += JsonNumber(attribution, std::string(c) + "_voxels");
  }
  for (const char* q : {"bottom", "second", "third", "top"}) {
    by_height += JsonNumber(attribution, std::string("blocked_") + q + "_quarter_voxels");
  }
  const double all = JsonNumber(attribution, "blocked_all_voxels");
  EXPECT_GT(all, 0.0) << attribution;
  EXPECT_EQ(by_distance, all) << attribution;
  EXPECT_EQ(by_height, all) << attribution;
  const std::string grid = ReadFile(set_ + "/eval/sparse_mesh.mavocc");
  ASSERT_GT(grid.size(), 80u);
  EXPECT_EQ(grid.substr(0, 8), std::string("MAVOCC\n\x1a"));
  EXPECT_NE(r.output.find("sparse_mesh.mavocc"), std::string::npos) << r.output;
  for (const char* flag : {"--weak-surface-min-views 0", "--weak-surface-min-views x"}) {
    r = RunTool("mav-eval",
                std::string("mapping --method sparse-mesh ") + flag + " --data " + set_);
    EXPECT_EQ(r.exit_code, 2) << flag << ": " << r.output;
    const std::string name = std::string(flag).substr(2, std::string(flag).find(' ') - 2);
    EXPECT_NE(r.output.find(name), std::string::npos) << r.output;
  }
  r = RunTool("mav-eval", "mapping --method sparse-mesh --stereo-uniqueness 1.5 --data " + set_);
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("sparse.stereo_uniqueness_ratio: must be in (0, 1], got 1.5"),
            std::string::npos)
      << r.output;
}

}  // namespace
