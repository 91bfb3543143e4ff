#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "euroc_format.h"
#include "mav/common/file.h"
#include "mav/common/parse.h"
#include "mav/common/text.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/png.h"
#include "mav/dataset/stereo_pair.h"
#include "text.h"

namespace mav::dataset {
namespace {

// A bad file name in cam*/data.csv: the image would be read from outside cam*/data.
Status CheckPlainFileName(std::string_view file, const std::string& name, int line,
                          const std::string& column) {
  if (file.empty() || file.find('/') != std::string_view::npos || file == "." || file == "..") {
    return Status::InvalidArgument(internal::Where(name, line, column) + ": " +
                                   QuoteForError(file) + " is not a plain file name");
  }
  return Status::Ok();
}

}  // namespace

Result<CameraCsv> ParseCameraCsv(std::string_view text, const std::string& name) {
  CameraCsv rows;
  // Two images with one stamp cannot be told apart: camera rows stay strictly increasing.
  ReadOptions strict;
  strict.repeated_stamps = RepeatedStamps::kReject;
  internal::StampSequence stamps(name, strict);
  const std::vector<std::string>& columns = internal::CameraColumns();
  MAV_RETURN_IF_ERROR(internal::ForEachRow(
      text, name, ',', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        MAV_ASSIGN_OR_RETURN(const int64_t t,
                             internal::ParseColumnInt64(f[0], name, line, columns[0]));
        bool keep = true;
        MAV_RETURN_IF_ERROR(stamps.Next(t, line, &keep));
        const std::string_view file = Trim(f[1]);
        MAV_RETURN_IF_ERROR(CheckPlainFileName(file, name, line, columns[1]));
        rows.t_ns.push_back(t);
        rows.files.emplace_back(file);
        return Status::Ok();
      }));
  return rows;
}

Result<std::vector<ImuSample>> ParseImuCsv(std::string_view text, const std::string& name,
                                           const ReadOptions& options) {
  std::vector<ImuSample> samples;
  internal::StampSequence stamps(name, options);
  const std::vector<std::string>& columns = internal::ImuColumns();
  MAV_RETURN_IF_ERROR(internal::ForEachRow(
      text, name, ',', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        ImuSample s;
        MAV_ASSIGN_OR_RETURN(s.t_ns, internal::ParseColumnInt64(f[0], name, line, columns[0]));
        bool keep = true;
        MAV_RETURN_IF_ERROR(stamps.Next(s.t_ns, line, &keep));
        // A dropped row is still parsed: a malformed row is an error wherever it is.
        for (int i = 0; i < 3; ++i) {
          MAV_ASSIGN_OR_RETURN(s.gyro[i],
                               internal::ParseColumnDouble(f[1 + i], name, line, columns[1 + i]));
          MAV_ASSIGN_OR_RETURN(s.accel[i],
                               internal::ParseColumnDouble(f[4 + i], name, line, columns[4 + i]));
        }
        if (keep) samples.push_back(s);
        return Status::Ok();
      }));
  return samples;
}

Result<std::vector<GroundTruthState>> ParseGroundTruthCsv(std::string_view text,
                                                          const std::string& name,
                                                          const ReadOptions& options) {
  std::vector<GroundTruthState> states;
  internal::StampSequence stamps(name, options);
  const std::vector<std::string>& columns = internal::GroundTruthColumns();
  MAV_RETURN_IF_ERROR(internal::ForEachRow(
      text, name, ',', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        GroundTruthState g;
        MAV_ASSIGN_OR_RETURN(g.t_ns, internal::ParseColumnInt64(f[0], name, line, columns[0]));
        bool keep = true;
        MAV_RETURN_IF_ERROR(stamps.Next(g.t_ns, line, &keep));
        double v[16];
        for (int i = 0; i < 16; ++i) {
          MAV_ASSIGN_OR_RETURN(v[i],
                               internal::ParseColumnDouble(f[1 + i], name, line, columns[1 + i]));
        }
        const Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
        const double norm = q.norm();
        if (!(norm > 0.5 && norm < 1.5)) {
          return Status::InvalidArgument(internal::Where(name, line, columns[4]) +
                                         ": quaternion norm " + internal::FormatDouble(norm) +
                                         " is not close to 1");
        }
        g.T_world_body = geometry::SE3(q, Eigen::Vector3d(v[0], v[1], v[2]));
        g.v_world = Eigen::Vector3d(v[7], v[8], v[9]);
        g.gyro_bias = Eigen::Vector3d(v[10], v[11], v[12]);
        g.accel_bias = Eigen::Vector3d(v[13], v[14], v[15]);
        if (keep) states.push_back(g);
        return Status::Ok();
      }));
  return states;
}

namespace {

bool IsIdentity(const geometry::SE3& T) {
  return T.Translation() == Eigen::Vector3d::Zero() &&
         T.Rotation().coeffs() == Eigen::Quaterniond::Identity().coeffs();
}

Status ReadImage(const std::string& path, const camera::PinholeRadTan& cam, cv::Mat* image) {
  // NotFound for a missing file, DataLoss for an undecodable one, InvalidArgument for one that
  // is not 8-bit grey; every message starts with the path.
  MAV_ASSIGN_OR_RETURN(cv::Mat decoded, ReadPngFile(path, PngDecode::kGreyOnly));
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

Result<EurocReader> EurocReader::Open(const std::string& root, const ReadOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("options: " + why);
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
  if (!reader.calibration_.IsValid(&why)) {
    return Status::InvalidArgument(m + "/cam{0,1}/sensor.yaml: stereo calibration: " + why);
  }
  reader.imu_noise_ = imu.noise;
  reader.camera_rate_hz_ = cam0.rate_hz;
  reader.imu_rate_hz_ = imu.rate_hz;

  const std::string left_path = m + "/cam0/data.csv", right_path = m + "/cam1/data.csv";
  MAV_ASSIGN_OR_RETURN(const std::string left_text, ReadFileToString(left_path));
  MAV_ASSIGN_OR_RETURN(const CameraCsv left, ParseCameraCsv(left_text, left_path));
  MAV_ASSIGN_OR_RETURN(const std::string right_text, ReadFileToString(right_path));
  MAV_ASSIGN_OR_RETURN(const CameraCsv right, ParseCameraCsv(right_text, right_path));
  reader.cam0_rows_ = static_cast<int64_t>(left.t_ns.size());
  reader.cam1_rows_ = static_cast<int64_t>(right.t_ns.size());
  // Both lists are strictly increasing: pair them by a merge.
  size_t i = 0, j = 0;
  while (i < left.t_ns.size() && j < right.t_ns.size()) {
    if (left.t_ns[i] == right.t_ns[j]) {
      reader.frame_times_.push_back(left.t_ns[i]);
      reader.left_files_.push_back(left.files[i]);
      reader.right_files_.push_back(right.files[j]);
      ++i;
      ++j;
    } else if (left.t_ns[i] < right.t_ns[j]) {
      ++i;
      ++reader.skipped_frames_;
    } else {
      ++j;
      ++reader.skipped_frames_;
    }
  }
  reader.skipped_frames_ += static_cast<int64_t>((left.t_ns.size() - i) + (right.t_ns.size() - j));

  const std::string imu_path = m + "/imu0/data.csv";
  MAV_ASSIGN_OR_RETURN(const std::string imu_text, ReadFileToString(imu_path));
  MAV_ASSIGN_OR_RETURN(reader.imu_, ParseImuCsv(imu_text, imu_path, options));
  const std::string gt_path = m + "/" + internal::kGroundTruthFolder + "/data.csv";
  if (PathExists(gt_path)) {
    MAV_ASSIGN_OR_RETURN(const std::string gt_text, ReadFileToString(gt_path));
    MAV_ASSIGN_OR_RETURN(reader.ground_truth_, ParseGroundTruthCsv(gt_text, gt_path, options));
  }
  return reader;
}

Status EurocReader::CheckHasFrames() const {
  if (num_frames() > 0) return Status::Ok();
  std::string why;
  if (cam0_rows_ == 0 && cam1_rows_ == 0) {
    why = "cam0/data.csv and cam1/data.csv have no rows";
  } else if (cam0_rows_ == 0 || cam1_rows_ == 0) {
    why = std::string(cam0_rows_ == 0 ? "cam0" : "cam1") + "/data.csv has no rows (" +
          (cam0_rows_ == 0 ? "cam1" : "cam0") + " has " +
          std::to_string(std::max(cam0_rows_, cam1_rows_)) + ")";
  } else {
    why = "cam0/data.csv (" + std::to_string(cam0_rows_) + " rows) and cam1/data.csv (" +
          std::to_string(cam1_rows_) + " rows) share no timestamp";
  }
  return Status::FailedPrecondition(mav0_ + ": no stereo frames: " + why);
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
