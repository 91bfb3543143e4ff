// Mission files (mav/dataset/mission_file.h): the issue's example parses as written, every
// refusal names the file, the line and the field, and nothing a file says is echoed unbounded.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "mav/dataset/mission_file.h"
#include "test_util.h"

namespace mav::dataset {
namespace {

using ::testing::HasSubstr;

// The example of the mission issue (issue 23), line for line.
constexpr char kExample[] = R"(world: room-easy        # simulator preset
start: [0.0, 0.0, 0.0]  # on the ground
altitude: 1.2           # take-off height, m
goals:                  # visited in order, 2 s hover at each
  - [2.0, 1.5, 1.2]
  - [-2.5, 2.0, 1.5]
land: true
)";

// The message of a refused text, or "" when it parsed.
std::string Refusal(const std::string& text) {
  const Result<MissionSpec> mission = ParseMissionYaml(text, "m.yaml");
  if (mission.ok()) return "";
  EXPECT_EQ(mission.status().code(), StatusCode::kInvalidArgument) << mission.status().ToString();
  return mission.status().message();
}

TEST(MissionFileTest, TheIssueExampleParsesAsWritten) {
  const Result<MissionSpec> mission = ParseMissionYaml(kExample, "room.yaml");
  ASSERT_TRUE(mission.ok()) << mission.status().ToString();
  EXPECT_EQ(mission->world, "room-easy");
  EXPECT_EQ(mission->start, Eigen::Vector3d::Zero());
  EXPECT_DOUBLE_EQ(mission->altitude_m, 1.2);
  EXPECT_TRUE(mission->land);
  EXPECT_EQ(mission->source, "room.yaml");
  ASSERT_EQ(mission->goals.size(), 2u);
  EXPECT_EQ(mission->goals[0].position, Eigen::Vector3d(2.0, 1.5, 1.2));
  EXPECT_EQ(mission->goals[1].position, Eigen::Vector3d(-2.5, 2.0, 1.5));
  for (const MissionGoal& g : mission->goals) {
    EXPECT_DOUBLE_EQ(g.hover_s, 2.0);
    EXPECT_FALSE(g.yaw_rad.has_value());
  }
  EXPECT_EQ(mission->goals[0].line, 5);
  EXPECT_EQ(mission->goals[1].line, 6);
  std::string why;
  EXPECT_TRUE(mission->IsValid(&why)) << why;
}

TEST(MissionFileTest, DefaultsAndGoalsWithTheirOwnHoverAndYaw) {
  const Result<MissionSpec> mission = ParseMissionYaml(R"(world: plant
hover_s: 5
goals:
  - [1, 2, 3]
  - {position: [4, 5, 6], hover_s: 0, yaw_rad: 1.5}
land: false
camera_pitch_deg: 25
)",
                                                       "p.yaml");
  ASSERT_TRUE(mission.ok()) << mission.status().ToString();
  EXPECT_DOUBLE_EQ(mission->altitude_m, MissionSpec().altitude_m);
  EXPECT_FALSE(mission->land);
  ASSERT_TRUE(mission->camera_pitch_deg.has_value());
  EXPECT_DOUBLE_EQ(*mission->camera_pitch_deg, 25.0);
  EXPECT_FALSE(ParseMissionYaml(kExample, "room.yaml")->camera_pitch_deg.has_value());
  ASSERT_EQ(mission->goals.size(), 2u);
  EXPECT_DOUBLE_EQ(mission->goals[0].hover_s, 5.0);  // the file's default
  EXPECT_DOUBLE_EQ(mission->goals[1].hover_s, 0.0);  // its own
  ASSERT_TRUE(mission->goals[1].yaw_rad.has_value());
  EXPECT_DOUBLE_EQ(*mission->goals[1].yaw_rad, 1.5);
}

TEST(MissionFileTest, RefusalsNameTheFileTheLineAndTheField) {
  // A short goal on line 6.
  std::string text = kExample;
  text.replace(text.find("[-2.5, 2.0, 1.5]"), 16, "[-2.5, 2.0]");
  EXPECT_THAT(Refusal(text), HasSubstr("m.yaml:6: goals[1]: expected a list of 3 numbers"));
  // A misspelt key on line 3 is never ignored.
  text = kExample;
  text.replace(text.find("altitude:"), 9, "altitud:");
  EXPECT_THAT(Refusal(text), HasSubstr("m.yaml:3: altitud: unknown key"));
  // Out of range, on its own line.
  text = kExample;
  text.replace(text.find("1.2  "), 3, "-1 ");
  EXPECT_THAT(Refusal(text), HasSubstr("m.yaml:3: altitude: -1.000000 m; must be in (0, 100]"));
  EXPECT_THAT(Refusal("world: room-easy\ngoals:\n  - {position: [1, 2, 3], hover_s: -2}\n"),
              HasSubstr("m.yaml:3: goals[0].hover_s: -2.000000 s; must be in [0, 3600]"));
  EXPECT_THAT(Refusal("world: room-easy\ngoals:\n  - {hover_s: 2}\n"),
              HasSubstr("m.yaml:3: goals[0].position: missing"));
  EXPECT_THAT(Refusal("world: room-easy\ngoals:\n  - [1, nan, 3]\n"),
              HasSubstr("m.yaml:3: goals[0]"));
  EXPECT_THAT(Refusal("world: room-easy\ngoals: []\n"), HasSubstr("goals: expected a non-empty"));
  EXPECT_THAT(Refusal("goals:\n  - [1, 2, 3]\n"), HasSubstr("m.yaml:1: world: missing"));
  EXPECT_THAT(Refusal("world: room-easy\n"), HasSubstr("goals: missing"));
  EXPECT_THAT(Refusal("world: plant\ngoals: [[1, 2, 3]]\ncamera_pitch_deg: 75\n"),
              HasSubstr("m.yaml:3: camera_pitch_deg: 75.000000 degrees; must be in [0, 60]"));
  EXPECT_THAT(Refusal("world: plant\ncamera_pitch_deg: down\ngoals: [[1, 2, 3]]\n"),
              HasSubstr("m.yaml:2: camera_pitch_deg"));
  EXPECT_THAT(Refusal("world: room-easy\ngoals: [[1, 2, 3]]\nland: maybe\n"),
              HasSubstr("m.yaml:3: land: expected true or false"));
  EXPECT_THAT(Refusal("- just\n- a list\n"), HasSubstr("m.yaml: expected a YAML mapping"));
  EXPECT_THAT(Refusal("world: [unclosed\n"), HasSubstr("m.yaml: not valid YAML"));
}

TEST(MissionFileTest, WhatAFileSaysIsNeverEchoedWhole) {
  const std::string key(1000, 'k');  // yaml-cpp refuses implicit keys over 1024
  const std::string message = Refusal("world: room-easy\n" + key + ": 1\ngoals: [[1, 2, 3]]\n");
  EXPECT_THAT(message, HasSubstr("unknown key"));
  EXPECT_LT(message.size(), 400u) << message.substr(0, 400);
}

TEST(MissionFileTest, IsValidNamesTheField) {
  MissionSpec mission;
  std::string why;
  EXPECT_FALSE(mission.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("world"));
  mission.world = "room-easy";
  EXPECT_FALSE(mission.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("goals: none"));
  mission.goals.push_back(MissionGoal{});
  EXPECT_TRUE(mission.IsValid(&why)) << why;
  mission.goals.push_back(MissionGoal{});
  mission.goals[1].yaw_rad = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(mission.IsValid(&why));
  EXPECT_EQ(why, "goals[1].yaw_rad: not finite");
  mission.goals[1].yaw_rad.reset();
  mission.altitude_m = 101;
  EXPECT_FALSE(mission.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("altitude"));
  mission.altitude_m = 1;
  mission.camera_pitch_deg = -1;
  EXPECT_FALSE(mission.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("camera_pitch_deg"));
}

TEST(MissionFileTest, ReadsAFileAndNamesAMissingOne) {
  testing::TempDir dir;
  const std::string path = dir.path() + "/room.yaml";
  testing::WriteFile(path, kExample);
  const Result<MissionSpec> mission = ReadMissionFile(path);
  ASSERT_TRUE(mission.ok()) << mission.status().ToString();
  EXPECT_EQ(mission->source, path);
  const Result<MissionSpec> missing = ReadMissionFile(dir.path() + "/none.yaml");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound) << missing.status().ToString();
  EXPECT_THAT(missing.status().message(), HasSubstr("none.yaml"));
}

}  // namespace
}  // namespace mav::dataset
