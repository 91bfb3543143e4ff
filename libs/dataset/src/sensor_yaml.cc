// sensor.yaml of EuRoC's cam0/cam1/imu0 folders. yaml-cpp throws; every call into it is wrapped so
// that failures come back as Status values naming the file and the field.

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "mav/common/file.h"
#include "mav/common/parse.h"
#include "mav/common/text.h"
#include "mav/dataset/euroc.h"
#include "text.h"

namespace mav::dataset {
namespace {

// yaml-cpp rejects OpenCV's "%YAML:1.0" directive (no blank after the colon); drop such lines.
std::string StripYamlDirective(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  std::istringstream in{std::string(text)};
  std::string line;
  bool first = true;
  while (std::getline(in, line)) {
    if (line.rfind("%YAML", 0) == 0) continue;
    if (!first) out += '\n';
    out += line;
    first = false;
  }
  return out;
}

std::string FieldWhat(const std::string& path, const std::string& field) {
  return path + ": field '" + field + "'";
}

Result<YAML::Node> LoadYaml(std::string_view text, const std::string& path) {
  try {
    YAML::Node root = YAML::Load(StripYamlDirective(text));
    if (!root.IsMap()) return Status::InvalidArgument(path + ": expected a YAML mapping");
    return root;
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument(path + ": not valid YAML: " + e.what());
  }
}

// `field` is the key; `name` (default: the key) is how errors call it, e.g. "T_BS.data".
Result<std::string> GetScalar(const YAML::Node& map, const std::string& key,
                              const std::string& path, std::string field = "") {
  if (field.empty()) field = key;
  try {
    const YAML::Node node = map[key];
    if (!node) return Status::InvalidArgument(FieldWhat(path, field) + ": missing");
    if (!node.IsScalar()) return Status::InvalidArgument(FieldWhat(path, field) + ": not a scalar");
    return node.Scalar();
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument(FieldWhat(path, field) + ": " + e.what());
  }
}

Result<double> GetDouble(const YAML::Node& map, const std::string& key, const std::string& path,
                         std::string field = "") {
  if (field.empty()) field = key;
  MAV_ASSIGN_OR_RETURN(const std::string text, GetScalar(map, key, path, field));
  return ParseDouble(text, FieldWhat(path, field));
}

Result<std::vector<double>> GetDoubles(const YAML::Node& map, const std::string& key,
                                       size_t expected, const std::string& path,
                                       std::string field = "") {
  if (field.empty()) field = key;
  std::vector<double> values;
  try {
    const YAML::Node node = map[key];
    if (!node) return Status::InvalidArgument(FieldWhat(path, field) + ": missing");
    if (!node.IsSequence()) {
      return Status::InvalidArgument(FieldWhat(path, field) + ": expected a list of " +
                                     std::to_string(expected) + " numbers");
    }
    if (node.size() != expected) {
      return Status::InvalidArgument(FieldWhat(path, field) + ": expected " +
                                     std::to_string(expected) + " numbers, got " +
                                     std::to_string(node.size()));
    }
    for (size_t i = 0; i < node.size(); ++i) {
      if (!node[i].IsScalar()) {
        return Status::InvalidArgument(FieldWhat(path, field) + ": entry " + std::to_string(i) +
                                       " is not a number");
      }
      MAV_ASSIGN_OR_RETURN(
          const double v,
          ParseDouble(node[i].Scalar(), FieldWhat(path, field + "[" + std::to_string(i) + "]")));
      values.push_back(v);
    }
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument(FieldWhat(path, field) + ": " + e.what());
  }
  return values;
}

Status CheckSensorType(const YAML::Node& map, const std::string& expected,
                       const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const std::string type, GetScalar(map, "sensor_type", path));
  if (type != expected) {
    return Status::InvalidArgument(FieldWhat(path, "sensor_type") + ": " + QuoteForError(type) +
                                   ", expected '" + expected + "'");
  }
  return Status::Ok();
}

std::string GetComment(const YAML::Node& map) {
  try {
    const YAML::Node node = map["comment"];
    if (node && node.IsScalar()) return node.Scalar();
  } catch (const YAML::Exception&) {
  }
  return "";
}

Result<geometry::SE3> GetTransform(const YAML::Node& map, const std::string& path) {
  const std::string what = FieldWhat(path, "T_BS");
  YAML::Node t_bs;
  try {
    t_bs = map["T_BS"];
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument(what + ": " + e.what());
  }
  if (!t_bs) return Status::InvalidArgument(what + ": missing");
  if (!t_bs.IsMap()) return Status::InvalidArgument(what + ": expected {cols, rows, data}");
  const std::string& sub = what;
  MAV_ASSIGN_OR_RETURN(const double rows, GetDouble(t_bs, "rows", path, "T_BS.rows"));
  MAV_ASSIGN_OR_RETURN(const double cols, GetDouble(t_bs, "cols", path, "T_BS.cols"));
  if (rows != 4 || cols != 4) return Status::InvalidArgument(sub + ": expected a 4x4 matrix");
  MAV_ASSIGN_OR_RETURN(const std::vector<double> data,
                       GetDoubles(t_bs, "data", 16, path, "T_BS.data"));
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = data[4 * r + c];
  }
  if (m(3, 0) != 0 || m(3, 1) != 0 || m(3, 2) != 0 || m(3, 3) != 1) {
    return Status::InvalidArgument(sub + ": last row must be [0, 0, 0, 1]");
  }
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  // EuRoC prints its rotations with ~12 significant digits; anything far from a rotation is an
  // error rather than something to silently project.
  const double orthogonality = (r * r.transpose() - Eigen::Matrix3d::Identity()).norm();
  if (!(orthogonality < 1e-6) || !(r.determinant() > 0)) {
    return Status::InvalidArgument(sub + ": rotation block is not a rotation (|R R^T - I| = " +
                                   internal::FormatDouble(orthogonality) + ")");
  }
  return geometry::SE3(r, m.topRightCorner<3, 1>());
}

std::string QuoteIfNeeded(const std::string& text) {
  bool plain = !text.empty() && text.front() != ' ' && text.back() != ' ';
  for (char c : text) {
    if (std::string_view(":#'\"[]{},&*!|>%@`\\\n\t").find(c) != std::string_view::npos) {
      plain = false;
    }
  }
  if (plain) return text;
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out + "\"";
}

std::string FormatList(const std::vector<double>& values) {
  std::string out = "[";
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0) out += ", ";
    internal::AppendDouble(&out, values[i]);
  }
  return out + "]";
}

std::string FormatTransform(const geometry::SE3& T) {
  const Eigen::Matrix4d m = T.Matrix();
  std::string out = "T_BS:\n  cols: 4\n  rows: 4\n  data: [";
  for (int r = 0; r < 4; ++r) {
    if (r > 0) out += ",\n         ";
    for (int c = 0; c < 4; ++c) {
      if (c > 0) out += ", ";
      internal::AppendDouble(&out, m(r, c));
    }
  }
  return out + "]\n";
}

}  // namespace

Result<CameraSensor> ReadCameraSensorYaml(const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path));
  return ParseCameraSensorYaml(text, path);
}

Result<ImuSensor> ReadImuSensorYaml(const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path));
  return ParseImuSensorYaml(text, path);
}

Result<CameraSensor> ParseCameraSensorYaml(std::string_view text, const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const YAML::Node root, LoadYaml(text, path));
  MAV_RETURN_IF_ERROR(CheckSensorType(root, "camera", path));
  CameraSensor sensor;
  sensor.comment = GetComment(root);
  MAV_ASSIGN_OR_RETURN(sensor.T_body_cam, GetTransform(root, path));
  MAV_ASSIGN_OR_RETURN(sensor.rate_hz, GetDouble(root, "rate_hz", path));
  if (!(sensor.rate_hz > 0)) {
    return Status::InvalidArgument(FieldWhat(path, "rate_hz") + ": must be positive");
  }
  MAV_ASSIGN_OR_RETURN(const std::vector<double> resolution,
                       GetDoubles(root, "resolution", 2, path));
  for (double v : resolution) {
    if (!(v >= 1 && v <= 100000) || v != std::floor(v)) {
      return Status::InvalidArgument(FieldWhat(path, "resolution") +
                                     ": expected two positive integers [width, height]");
    }
  }
  MAV_ASSIGN_OR_RETURN(const std::string model, GetScalar(root, "camera_model", path));
  if (model != "pinhole") {
    return Status::InvalidArgument(FieldWhat(path, "camera_model") + ": " + QuoteForError(model) +
                                   " is not supported (expected 'pinhole')");
  }
  MAV_ASSIGN_OR_RETURN(const std::vector<double> k, GetDoubles(root, "intrinsics", 4, path));
  MAV_ASSIGN_OR_RETURN(const std::string distortion, GetScalar(root, "distortion_model", path));
  if (distortion != "radial-tangential" && distortion != "radtan" && distortion != "plumb_bob") {
    return Status::InvalidArgument(FieldWhat(path, "distortion_model") + ": " +
                                   QuoteForError(distortion) +
                                   " is not supported (expected 'radial-tangential')");
  }
  MAV_ASSIGN_OR_RETURN(const std::vector<double> d,
                       GetDoubles(root, "distortion_coefficients", 4, path));
  camera::PinholeRadTan& cam = sensor.intrinsics;
  cam.width = static_cast<int>(resolution[0]);
  cam.height = static_cast<int>(resolution[1]);
  cam.fx = k[0];
  cam.fy = k[1];
  cam.cx = k[2];
  cam.cy = k[3];
  cam.k1 = d[0];
  cam.k2 = d[1];
  cam.p1 = d[2];
  cam.p2 = d[3];
  std::string why;
  if (!cam.IsValid(&why)) return Status::InvalidArgument(path + ": " + why);
  return sensor;
}

Result<ImuSensor> ParseImuSensorYaml(std::string_view text, const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const YAML::Node root, LoadYaml(text, path));
  MAV_RETURN_IF_ERROR(CheckSensorType(root, "imu", path));
  ImuSensor sensor;
  sensor.comment = GetComment(root);
  MAV_ASSIGN_OR_RETURN(sensor.T_body_imu, GetTransform(root, path));
  MAV_ASSIGN_OR_RETURN(sensor.rate_hz, GetDouble(root, "rate_hz", path));
  if (!(sensor.rate_hz > 0)) {
    return Status::InvalidArgument(FieldWhat(path, "rate_hz") + ": must be positive");
  }
  ImuNoise& n = sensor.noise;
  const std::pair<const char*, double*> fields[] = {
      {"gyroscope_noise_density", &n.gyroscope_noise_density},
      {"gyroscope_random_walk", &n.gyroscope_random_walk},
      {"accelerometer_noise_density", &n.accelerometer_noise_density},
      {"accelerometer_random_walk", &n.accelerometer_random_walk},
  };
  for (const auto& [name, value] : fields) {
    MAV_ASSIGN_OR_RETURN(*value, GetDouble(root, name, path));
    if (!(*value >= 0) || std::isinf(*value)) {
      return Status::InvalidArgument(FieldWhat(path, name) + ": must be finite and >= 0");
    }
  }
  return sensor;
}

Status WriteCameraSensorYaml(const std::string& path, const CameraSensor& sensor) {
  const camera::PinholeRadTan& cam = sensor.intrinsics;
  std::string out;
  out += "# General sensor definitions.\n";
  out += "sensor_type: camera\n";
  out += "comment: " + QuoteIfNeeded(sensor.comment.empty() ? "camera" : sensor.comment) + "\n\n";
  out += "# Sensor extrinsics wrt. the body-frame.\n";
  out += FormatTransform(sensor.T_body_cam);
  out += "\n# Camera specific definitions.\n";
  out += "rate_hz: " + internal::FormatDouble(sensor.rate_hz) + "\n";
  out += "resolution: [" + std::to_string(cam.width) + ", " + std::to_string(cam.height) + "]\n";
  out += "camera_model: pinhole\n";
  out += "intrinsics: " + FormatList({cam.fx, cam.fy, cam.cx, cam.cy}) + " #fu, fv, cu, cv\n";
  out += "distortion_model: radial-tangential\n";
  out += "distortion_coefficients: " + FormatList({cam.k1, cam.k2, cam.p1, cam.p2}) + "\n";
  return WriteStringToFileAtomic(path, out);
}

Status WriteImuSensorYaml(const std::string& path, const ImuSensor& sensor) {
  const ImuNoise& n = sensor.noise;
  std::string out;
  out += "# General sensor definitions.\n";
  out += "sensor_type: imu\n";
  out += "comment: " + QuoteIfNeeded(sensor.comment.empty() ? "imu" : sensor.comment) + "\n\n";
  out += "# Sensor extrinsics wrt. the body-frame.\n";
  out += FormatTransform(sensor.T_body_imu);
  out += "rate_hz: " + internal::FormatDouble(sensor.rate_hz) + "\n\n";
  out += "# inertial sensor noise model parameters (static)\n";
  out += "gyroscope_noise_density: " + internal::FormatDouble(n.gyroscope_noise_density) +
         "     # [ rad / s / sqrt(Hz) ]   ( gyro \"white noise\" )\n";
  out += "gyroscope_random_walk: " + internal::FormatDouble(n.gyroscope_random_walk) +
         "       # [ rad / s^2 / sqrt(Hz) ] ( gyro bias diffusion )\n";
  out += "accelerometer_noise_density: " + internal::FormatDouble(n.accelerometer_noise_density) +
         "  # [ m / s^2 / sqrt(Hz) ]  ( accel \"white noise\" )\n";
  out += "accelerometer_random_walk: " + internal::FormatDouble(n.accelerometer_random_walk) +
         "    # [ m / s^3 / sqrt(Hz) ]  ( accel bias diffusion )\n";
  return WriteStringToFileAtomic(path, out);
}

}  // namespace mav::dataset
