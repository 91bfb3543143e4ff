#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "euroc_format.h"
#include "mav/common/file.h"
#include "mav/common/parse.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/stereo_pair.h"
#include "text.h"

namespace mav::dataset {
namespace {

struct CameraRows {
  std::vector<int64_t> times;
  std::vector<std::string> files;
};

Result<CameraRows> ReadCameraCsv(const std::string& path) {
  CameraRows rows;
  int64_t previous = 0;
  bool first = true;
  const std::vector<std::string>& columns = internal::CameraColumns();
  MAV_RETURN_IF_ERROR(internal::ForEachRow(
      path, ',', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        MAV_ASSIGN_OR_RETURN(const int64_t t,
                             internal::ParseColumnInt64(f[0], path, line, columns[0]));
        MAV_RETURN_IF_ERROR(internal::CheckIncreasing(t, &previous, &first, path, line));
        const std::string_view file = Trim(f[1]);
        if (file.empty() || file.find('/') != std::string_view::npos || file == "." ||
            file == "..") {
          return Status::InvalidArgument(internal::Where(path, line, columns[1]) + ": '" +
                                         std::string(file) + "' is not a plain file name");
        }
        rows.times.push_back(t);
        rows.files.emplace_back(file);
        return Status::Ok();
      }));
  return rows;
}

Result<std::vector<ImuSample>> ReadImuCsv(const std::string& path) {
  std::vector<ImuSample> samples;
  int64_t previous = 0;
  bool first = true;
  const std::vector<std::string>& columns = internal::ImuColumns();
  MAV_RETURN_IF_ERROR(internal::ForEachRow(
      path, ',', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        ImuSample s;
        MAV_ASSIGN_OR_RETURN(s.t_ns, internal::ParseColumnInt64(f[0], path, line, columns[0]));
        MAV_RETURN_IF_ERROR(internal::CheckIncreasing(s.t_ns, &previous, &first, path, line));
        for (int i = 0; i < 3; ++i) {
          MAV_ASSIGN_OR_RETURN(s.gyro[i],
                               internal::ParseColumnDouble(f[1 + i], path, line, columns[1 + i]));
          MAV_ASSIGN_OR_RETURN(s.accel[i],
                               internal::ParseColumnDouble(f[4 + i], path, line, columns[4 + i]));
        }
        samples.push_back(s);
        return Status::Ok();
      }));
  return samples;
}

Result<std::vector<GroundTruthState>> ReadGroundTruthCsv(const std::string& path) {
  std::vector<GroundTruthState> states;
  int64_t previous = 0;
  bool first = true;
  const std::vector<std::string>& columns = internal::GroundTruthColumns();
  MAV_RETURN_IF_ERROR(internal::ForEachRow(
      path, ',', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        GroundTruthState g;
        MAV_ASSIGN_OR_RETURN(g.t_ns, internal::ParseColumnInt64(f[0], path, line, columns[0]));
        MAV_RETURN_IF_ERROR(internal::CheckIncreasing(g.t_ns, &previous, &first, path, line));
        double v[16];
        for (int i = 0; i < 16; ++i) {
          MAV_ASSIGN_OR_RETURN(v[i],
                               internal::ParseColumnDouble(f[1 + i], path, line, columns[1 + i]));
        }
        const Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
        const double norm = q.norm();
        if (!(norm > 0.5 && norm < 1.5)) {
          return Status::InvalidArgument(internal::Where(path, line, columns[4]) +
                                         ": quaternion norm " + internal::FormatDouble(norm) +
                                         " is not close to 1");
        }
        g.T_world_body = geometry::SE3(q, Eigen::Vector3d(v[0], v[1], v[2]));
        g.v_world = Eigen::Vector3d(v[7], v[8], v[9]);
        g.gyro_bias = Eigen::Vector3d(v[10], v[11], v[12]);
        g.accel_bias = Eigen::Vector3d(v[13], v[14], v[15]);
        states.push_back(g);
        return Status::Ok();
      }));
  return states;
}

bool IsIdentity(const geometry::SE3& T) {
  return T.Translation() == Eigen::Vector3d::Zero() &&
         T.Rotation().coeffs() == Eigen::Quaterniond::Identity().coeffs();
}

Status ReadImage(const std::string& path, const camera::PinholeRadTan& cam, cv::Mat* image) {
  // Read the bytes ourselves so that a missing file (NotFound) and an undecodable one (DataLoss)
  // are told apart; cv::imread returns an empty Mat for both.
  MAV_ASSIGN_OR_RETURN(const std::string bytes, ReadFileToString(path));
  cv::Mat decoded;
  try {
    const cv::Mat raw(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data()));
    if (!bytes.empty()) decoded = cv::imdecode(raw, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return Status::DataLoss(path + ": cannot decode image: " + e.what());
  }
  if (decoded.empty())
    return Status::DataLoss(path + ": cannot decode image (corrupt or truncated)");
  if (decoded.type() != CV_8UC1) {
    return Status::InvalidArgument(path + ": expected an 8-bit grey image, got " +
                                   std::to_string(decoded.channels()) + " channel(s) of depth " +
                                   std::to_string(decoded.depth()));
  }
  if (decoded.cols != cam.width || decoded.rows != cam.height) {
    return Status::InvalidArgument(path + ": image is " + std::to_string(decoded.cols) + "x" +
                                   std::to_string(decoded.rows) + ", expected " +
                                   std::to_string(cam.width) + "x" + std::to_string(cam.height) +
                                   " (sensor.yaml resolution)");
  }
  *image = std::move(decoded);
  return Status::Ok();
}

}  // namespace

Result<EurocReader> EurocReader::Open(const std::string& root) {
  if (!PathExists(root)) return Status::NotFound(root + ": no such directory");
  if (!IsDirectory(root)) return Status::InvalidArgument(root + ": not a directory");
  EurocReader reader;
  if (IsDirectory(root + "/mav0")) {
    reader.mav0_ = root + "/mav0";
  } else if (IsDirectory(root + "/cam0")) {
    reader.mav0_ = root;
  } else {
    return Status::NotFound(root + "/mav0: no such directory (not an EuRoC ASL data set)");
  }
  const std::string& m = reader.mav0_;
  for (const char* dir : {"/cam0", "/cam1", "/imu0"}) {
    if (!IsDirectory(m + dir)) return Status::NotFound(m + dir + ": no such directory");
  }

  MAV_ASSIGN_OR_RETURN(const CameraSensor cam0, ReadCameraSensorYaml(m + "/cam0/sensor.yaml"));
  MAV_ASSIGN_OR_RETURN(const CameraSensor cam1, ReadCameraSensorYaml(m + "/cam1/sensor.yaml"));
  MAV_ASSIGN_OR_RETURN(const ImuSensor imu, ReadImuSensorYaml(m + "/imu0/sensor.yaml"));
  reader.calibration_.cam0 = cam0.intrinsics;
  reader.calibration_.cam1 = cam1.intrinsics;
  if (IsIdentity(imu.T_body_imu)) {
    reader.calibration_.T_body_cam0 = cam0.T_body_cam;
    reader.calibration_.T_body_cam1 = cam1.T_body_cam;
  } else {
    // Our body frame is the IMU frame: T_imu_cam = T_B_imu^-1 * T_B_cam.
    const geometry::SE3 T_imu_body = imu.T_body_imu.Inverse();
    reader.calibration_.T_body_cam0 = T_imu_body * cam0.T_body_cam;
    reader.calibration_.T_body_cam1 = T_imu_body * cam1.T_body_cam;
  }
  std::string why;
  if (!reader.calibration_.IsValid(&why)) {
    return Status::InvalidArgument(m + "/cam{0,1}/sensor.yaml: stereo calibration: " + why);
  }
  reader.imu_noise_ = imu.noise;
  reader.camera_rate_hz_ = cam0.rate_hz;
  reader.imu_rate_hz_ = imu.rate_hz;

  MAV_ASSIGN_OR_RETURN(const CameraRows left, ReadCameraCsv(m + "/cam0/data.csv"));
  MAV_ASSIGN_OR_RETURN(const CameraRows right, ReadCameraCsv(m + "/cam1/data.csv"));
  // Both lists are strictly increasing: pair them by a merge.
  size_t i = 0, j = 0;
  while (i < left.times.size() && j < right.times.size()) {
    if (left.times[i] == right.times[j]) {
      reader.frame_times_.push_back(left.times[i]);
      reader.left_files_.push_back(left.files[i]);
      reader.right_files_.push_back(right.files[j]);
      ++i;
      ++j;
    } else if (left.times[i] < right.times[j]) {
      ++i;
      ++reader.skipped_frames_;
    } else {
      ++j;
      ++reader.skipped_frames_;
    }
  }
  reader.skipped_frames_ +=
      static_cast<int64_t>((left.times.size() - i) + (right.times.size() - j));

  MAV_ASSIGN_OR_RETURN(reader.imu_, ReadImuCsv(m + "/imu0/data.csv"));
  const std::string gt_path = m + "/" + internal::kGroundTruthFolder + "/data.csv";
  if (PathExists(gt_path)) {
    MAV_ASSIGN_OR_RETURN(reader.ground_truth_, ReadGroundTruthCsv(gt_path));
  }
  return reader;
}

std::string EurocReader::LeftImagePath(int64_t index) const {
  MAV_CHECK(index >= 0 && index < num_frames()) << "frame index " << index;
  return mav0_ + "/cam0/data/" + left_files_[index];
}

std::string EurocReader::RightImagePath(int64_t index) const {
  MAV_CHECK(index >= 0 && index < num_frames()) << "frame index " << index;
  return mav0_ + "/cam1/data/" + right_files_[index];
}

Status EurocReader::ReadStereo(int64_t index, cv::Mat* left, cv::Mat* right) const {
  if (index < 0 || index >= num_frames()) {
    return Status::OutOfRange("frame index " + std::to_string(index) + " outside [0, " +
                              std::to_string(num_frames()) + ")");
  }
  MAV_RETURN_IF_ERROR(ReadImage(LeftImagePath(index), calibration_.cam0, left));
  return ReadImage(RightImagePath(index), calibration_.cam1, right);
}

Result<StereoPair> EurocReader::ReadStereo(int64_t index) const {
  StereoPair pair;
  MAV_RETURN_IF_ERROR(ReadStereo(index, &pair.left, &pair.right));
  pair.t_ns = frame_times_[index];
  return pair;
}

}  // namespace mav::dataset
