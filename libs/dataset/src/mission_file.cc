// yaml-cpp throws; every call into it is inside ParseMissionYaml's try block, and errors leave as
// Status.
#include "mav/dataset/mission_file.h"

#include <cmath>
#include <set>

#include <yaml-cpp/yaml.h>

#include "mav/common/file.h"
#include "yaml_fields.h"

namespace mav::dataset {
namespace {

using Fields = internal::YamlFields;

constexpr size_t kMaxGoals = 1000;
constexpr double kMaxAltitudeM = 100.0;
constexpr double kMaxCameraPitchDeg = 60.0;
constexpr double kMaxHoverS = 3600.0;

// The limits of mission_file.h, one place for the reader and IsValid.
std::string CameraPitchError(double pitch_deg) {
  if (pitch_deg >= 0.0 && pitch_deg <= kMaxCameraPitchDeg) return "";
  return std::to_string(pitch_deg) + " degrees; must be in [0, 60]";
}

std::string AltitudeError(double altitude_m) {
  if (altitude_m > 0.0 && altitude_m <= kMaxAltitudeM) return "";
  return std::to_string(altitude_m) + " m; must be in (0, 100]";
}
std::string HoverError(double hover_s) {
  if (hover_s >= 0.0 && hover_s <= kMaxHoverS) return "";
  return std::to_string(hover_s) + " s; must be in [0, 3600]";
}

// "LINE: " + the field's message; ParseMissionYaml puts the file in front ("f.yaml:LINE: ...").
// A node yaml-cpp made up for a missing key has no position: then the enclosing node's line.
Status AtLine(const YAML::Node& node, const YAML::Node& enclosing, const Status& status) {
  if (status.ok()) return status;
  const YAML::Mark mark = node && node.Mark().line >= 0 ? node.Mark() : enclosing.Mark();
  return Status::InvalidArgument(std::to_string(mark.line + 1) + ": " + status.message());
}

Status ParseGoal(const Fields& f, const YAML::Node& n, const std::string& path, double hover_s,
                 MissionGoal* goal) {
  goal->line = n.Mark().line + 1;
  goal->hover_s = hover_s;
  if (n.IsSequence()) return f.Vector(n, path, &goal->position);
  if (!n.IsMap()) return Fields::Bad(path, "expected [x, y, z] or {position, hover_s, yaw_rad}");
  MAV_RETURN_IF_ERROR(f.CheckKeys(n, path, {"position", "hover_s", "yaw_rad"}));
  if (!n["position"]) return Fields::Bad(path + ".position", "missing");
  MAV_RETURN_IF_ERROR(f.Vector(n, path, "position", &goal->position));
  MAV_RETURN_IF_ERROR(f.Double(n, path, "hover_s", &goal->hover_s));
  if (const std::string e = HoverError(goal->hover_s); !e.empty()) {
    return Fields::Bad(path + ".hover_s", e);
  }
  if (n["yaw_rad"]) {
    double yaw = 0.0;
    MAV_RETURN_IF_ERROR(f.Double(n, path, "yaw_rad", &yaw));
    goal->yaw_rad = yaw;
  }
  return Status::Ok();
}

// Fields::CheckKeys on the top-level mapping, with the line of the first key it refuses.
Status CheckTopLevelKeys(const Fields& f, const YAML::Node& root) {
  const std::set<std::string> known = {"world", "start", "altitude",        "hover_s",
                                       "goals", "land",  "camera_pitch_deg"};
  Status status = f.CheckKeys(root, "", known);
  if (status.ok()) return status;
  for (const auto& kv : root) {
    if (!known.count(kv.first.as<std::string>())) return AtLine(kv.first, root, status);
  }
  return AtLine(root, root, status);
}

Status Parse(const YAML::Node& root, MissionSpec* mission) {
  const Fields f;
  MAV_RETURN_IF_ERROR(CheckTopLevelKeys(f, root));
  const YAML::Node world = root["world"];
  if (!world) return AtLine(world, root, Fields::Bad("world", "missing (a simulator preset)"));
  if (!world.IsScalar() || world.Scalar().empty()) {
    return AtLine(world, root, Fields::Bad("world", "expected a preset name"));
  }
  mission->world = world.Scalar();
  MAV_RETURN_IF_ERROR(AtLine(root["start"], root, f.Vector(root, "", "start", &mission->start)));
  MAV_RETURN_IF_ERROR(
      AtLine(root["altitude"], root, f.Double(root, "", "altitude", &mission->altitude_m)));
  if (const std::string e = AltitudeError(mission->altitude_m); !e.empty()) {
    return AtLine(root["altitude"], root, Fields::Bad("altitude", e));
  }
  if (root["camera_pitch_deg"]) {
    double pitch = 0;
    MAV_RETURN_IF_ERROR(
        AtLine(root["camera_pitch_deg"], root, f.Double(root, "", "camera_pitch_deg", &pitch)));
    if (const std::string e = CameraPitchError(pitch); !e.empty()) {
      return AtLine(root["camera_pitch_deg"], root, Fields::Bad("camera_pitch_deg", e));
    }
    mission->camera_pitch_deg = pitch;
  }
  double hover_s = MissionGoal().hover_s;
  MAV_RETURN_IF_ERROR(AtLine(root["hover_s"], root, f.Double(root, "", "hover_s", &hover_s)));
  if (const std::string e = HoverError(hover_s); !e.empty()) {
    return AtLine(root["hover_s"], root, Fields::Bad("hover_s", e));
  }
  if (const YAML::Node land = root["land"]) {
    if (!land.IsScalar() || (land.Scalar() != "true" && land.Scalar() != "false")) {
      return AtLine(land, root, Fields::Bad("land", "expected true or false"));
    }
    mission->land = land.Scalar() == "true";
  }
  const YAML::Node goals = root["goals"];
  if (!goals) return AtLine(goals, root, Fields::Bad("goals", "missing (at least one goal)"));
  if (!goals.IsSequence() || goals.size() == 0) {
    return AtLine(goals, root, Fields::Bad("goals", "expected a non-empty list"));
  }
  if (goals.size() > kMaxGoals) {
    return AtLine(goals, root,
                  Fields::Bad("goals", std::to_string(goals.size()) + " goals; at most " +
                                           std::to_string(kMaxGoals)));
  }
  mission->goals.resize(goals.size());
  for (size_t i = 0; i < goals.size(); ++i) {
    const std::string path = "goals[" + std::to_string(i) + "]";
    MAV_RETURN_IF_ERROR(
        AtLine(goals[i], goals, ParseGoal(f, goals[i], path, hover_s, &mission->goals[i])));
  }
  return Status::Ok();
}

}  // namespace

bool MissionSpec::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (world.empty()) return fail("world: empty (a simulator preset)");
  if (!start.allFinite()) return fail("start: not finite");
  if (const std::string e = AltitudeError(altitude_m); !e.empty()) return fail("altitude: " + e);
  if (camera_pitch_deg.has_value()) {
    if (const std::string e = CameraPitchError(*camera_pitch_deg); !e.empty()) {
      return fail("camera_pitch_deg: " + e);
    }
  }
  if (goals.empty()) return fail("goals: none (at least one)");
  if (goals.size() > kMaxGoals) return fail("goals: more than " + std::to_string(kMaxGoals));
  for (size_t i = 0; i < goals.size(); ++i) {
    const std::string path = "goals[" + std::to_string(i) + "]";
    const MissionGoal& g = goals[i];
    if (!g.position.allFinite()) return fail(path + ".position: not finite");
    if (const std::string e = HoverError(g.hover_s); !e.empty()) {
      return fail(path + ".hover_s: " + e);
    }
    if (g.yaw_rad.has_value() && !std::isfinite(*g.yaw_rad)) {
      return fail(path + ".yaw_rad: not finite");
    }
  }
  return true;
}

Result<MissionSpec> ParseMissionYaml(const std::string& text, const std::string& source) {
  MissionSpec mission;
  mission.source = source;
  Status status;
  try {
    const YAML::Node root = YAML::Load(text);
    if (!root.IsMap()) return Status::InvalidArgument(source + ": expected a YAML mapping");
    status = Parse(root, &mission);
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument(source + ": not valid YAML: " + QuoteForError(e.what(), 200));
  }
  if (!status.ok()) return Status::InvalidArgument(source + ":" + status.message());
  // The reader checked every field where it read it (with its line); this is the contract.
  if (std::string why; !mission.IsValid(&why)) return Status::InvalidArgument(source + ": " + why);
  return mission;
}

Result<MissionSpec> ReadMissionFile(const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path));
  return ParseMissionYaml(text, path);
}

}  // namespace mav::dataset
