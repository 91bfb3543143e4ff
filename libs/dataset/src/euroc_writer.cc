#include <algorithm>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "euroc_format.h"
#include "mav/common/file.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/png.h"
#include "text.h"

namespace mav::dataset {
namespace {

Status CheckImage(const cv::Mat& image, const char* name, const camera::PinholeRadTan& cam) {
  if (image.empty()) return Status::InvalidArgument(std::string(name) + ": empty image");
  if (image.type() != CV_8UC1) {
    return Status::InvalidArgument(
        std::string(name) + ": expected an 8-bit grey image (CV_8UC1), got type " +
        std::to_string(image.type()) + " with " + std::to_string(image.channels()) + " channel(s)");
  }
  if (image.cols != cam.width || image.rows != cam.height) {
    return Status::InvalidArgument(std::string(name) + ": image is " + std::to_string(image.cols) +
                                   "x" + std::to_string(image.rows) + ", calibration says " +
                                   std::to_string(cam.width) + "x" + std::to_string(cam.height));
  }
  return Status::Ok();
}

Result<std::string> EncodeImage(const cv::Mat& image, const char* name) {
  Result<std::string> png = EncodePng(image);
  if (!png.ok()) return png.status().WithContext(name);
  return png;
}

}  // namespace

Result<std::unique_ptr<EurocWriter>> EurocWriter::Create(
    const std::string& root, const camera::StereoCalibration& calibration,
    const ImuNoise& imu_noise, double camera_rate_hz, double imu_rate_hz) {
  std::string why;
  if (!calibration.IsValid(&why)) return Status::InvalidArgument("calibration: " + why);
  if (!(camera_rate_hz > 0) || camera_rate_hz > 1e6) {
    return Status::InvalidArgument("camera_rate_hz: must be in (0, 1e6], got " +
                                   internal::FormatDouble(camera_rate_hz));
  }
  if (!(imu_rate_hz > 0) || imu_rate_hz > 1e6) {
    return Status::InvalidArgument("imu_rate_hz: must be in (0, 1e6], got " +
                                   internal::FormatDouble(imu_rate_hz));
  }
  std::unique_ptr<EurocWriter> writer(new EurocWriter());
  writer->root_ = root;
  writer->mav0_ = root + "/mav0";
  writer->calibration_ = calibration;
  writer->imu_noise_ = imu_noise;
  writer->camera_rate_hz_ = camera_rate_hz;
  writer->imu_rate_hz_ = imu_rate_hz;
  for (const char* dir : {"/cam0/data", "/cam1/data", "/imu0"}) {
    MAV_RETURN_IF_ERROR(MakeDirectories(writer->mav0_ + dir));
  }
  return writer;
}

EurocWriter::~EurocWriter() = default;

int64_t EurocWriter::frames_written() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int64_t>(frame_times_.size());
}

Status EurocWriter::WriteStereo(int64_t t_ns, const cv::Mat& left, const cv::Mat& right) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return Status::FailedPrecondition("WriteStereo after Close()");
  }
  if (t_ns < 0) return Status::InvalidArgument("t_ns: must be >= 0, got " + std::to_string(t_ns));
  MAV_RETURN_IF_ERROR(CheckImage(left, "left", calibration_.cam0));
  MAV_RETURN_IF_ERROR(CheckImage(right, "right", calibration_.cam1));
  MAV_ASSIGN_OR_RETURN(const std::string left_png, EncodeImage(left, "left"));
  MAV_ASSIGN_OR_RETURN(const std::string right_png, EncodeImage(right, "right"));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (std::find(frame_times_.begin(), frame_times_.end(), t_ns) != frame_times_.end()) {
      return Status::InvalidArgument("t_ns: frame " + std::to_string(t_ns) + " already written");
    }
    frame_times_.push_back(t_ns);
  }
  const std::string name = "/data/" + std::to_string(t_ns) + ".png";
  Status status = WriteStringToFileAtomic(mav0_ + "/cam0" + name, left_png);
  if (status.ok()) status = WriteStringToFileAtomic(mav0_ + "/cam1" + name, right_png);
  if (!status.ok()) {
    std::lock_guard<std::mutex> lock(mutex_);
    frame_times_.erase(std::find(frame_times_.begin(), frame_times_.end(), t_ns));
  }
  return status;
}

Status EurocWriter::WriteImu(const std::vector<ImuSample>& samples) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (closed_) return Status::FailedPrecondition("WriteImu after Close()");
  int64_t previous = imu_.empty() ? 0 : imu_.back().t_ns;
  for (size_t i = 0; i < samples.size(); ++i) {
    if ((!imu_.empty() || i > 0) && samples[i].t_ns <= previous) {
      return Status::InvalidArgument("imu sample " + std::to_string(i) + ": t_ns " +
                                     std::to_string(samples[i].t_ns) +
                                     " is not after the previous sample");
    }
    previous = samples[i].t_ns;
  }
  imu_.insert(imu_.end(), samples.begin(), samples.end());
  return Status::Ok();
}

Status EurocWriter::WriteGroundTruth(const std::vector<GroundTruthState>& states) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (closed_) return Status::FailedPrecondition("WriteGroundTruth after Close()");
  int64_t previous = ground_truth_.empty() ? 0 : ground_truth_.back().t_ns;
  for (size_t i = 0; i < states.size(); ++i) {
    if ((!ground_truth_.empty() || i > 0) && states[i].t_ns <= previous) {
      return Status::InvalidArgument("ground truth state " + std::to_string(i) + ": t_ns " +
                                     std::to_string(states[i].t_ns) +
                                     " is not after the previous state");
    }
    previous = states[i].t_ns;
  }
  ground_truth_.insert(ground_truth_.end(), states.begin(), states.end());
  return Status::Ok();
}

Status EurocWriter::Close() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (closed_) return Status::FailedPrecondition("Close() called twice");
  closed_ = true;

  std::vector<int64_t> times = frame_times_;
  std::sort(times.begin(), times.end());
  std::string cam_csv = internal::JoinHeader(internal::CameraColumns(), ",");
  for (int64_t t : times) {
    const std::string s = std::to_string(t);
    cam_csv.append(s).append(",").append(s).append(".png\n");
  }
  for (const char* cam : {"/cam0", "/cam1"}) {
    MAV_RETURN_IF_ERROR(WriteStringToFileAtomic(mav0_ + cam + "/data.csv", cam_csv));
  }

  std::string imu_csv = internal::JoinHeader(internal::ImuColumns(), ",");
  for (const ImuSample& s : imu_) {
    imu_csv += std::to_string(s.t_ns);
    for (int i = 0; i < 3; ++i) {
      imu_csv += ',';
      internal::AppendDouble(&imu_csv, s.gyro[i]);
    }
    for (int i = 0; i < 3; ++i) {
      imu_csv += ',';
      internal::AppendDouble(&imu_csv, s.accel[i]);
    }
    imu_csv += '\n';
  }
  MAV_RETURN_IF_ERROR(WriteStringToFileAtomic(mav0_ + "/imu0/data.csv", imu_csv));

  if (!ground_truth_.empty()) {
    const std::string dir = mav0_ + "/" + internal::kGroundTruthFolder;
    MAV_RETURN_IF_ERROR(MakeDirectories(dir));
    std::string csv = internal::JoinHeader(internal::GroundTruthColumns(), ", ");
    for (const GroundTruthState& g : ground_truth_) {
      const Eigen::Vector3d& p = g.T_world_body.Translation();
      const Eigen::Quaterniond& q = g.T_world_body.Rotation();
      const double values[16] = {p.x(),
                                 p.y(),
                                 p.z(),
                                 q.w(),
                                 q.x(),
                                 q.y(),
                                 q.z(),
                                 g.v_world.x(),
                                 g.v_world.y(),
                                 g.v_world.z(),
                                 g.gyro_bias.x(),
                                 g.gyro_bias.y(),
                                 g.gyro_bias.z(),
                                 g.accel_bias.x(),
                                 g.accel_bias.y(),
                                 g.accel_bias.z()};
      csv += std::to_string(g.t_ns);
      for (double v : values) {
        csv += ',';
        internal::AppendDouble(&csv, v);
      }
      csv += '\n';
    }
    MAV_RETURN_IF_ERROR(WriteStringToFileAtomic(dir + "/data.csv", csv));
  }

  CameraSensor cam0{calibration_.cam0, calibration_.T_body_cam0, camera_rate_hz_,
                    "VI-Sensor cam0 (simulated MT9V034)"};
  CameraSensor cam1{calibration_.cam1, calibration_.T_body_cam1, camera_rate_hz_,
                    "VI-Sensor cam1 (simulated MT9V034)"};
  MAV_RETURN_IF_ERROR(WriteCameraSensorYaml(mav0_ + "/cam0/sensor.yaml", cam0));
  MAV_RETURN_IF_ERROR(WriteCameraSensorYaml(mav0_ + "/cam1/sensor.yaml", cam1));
  ImuSensor imu{imu_noise_, geometry::SE3::Identity(), imu_rate_hz_,
                "VI-Sensor IMU (simulated ADIS16448)"};
  return WriteImuSensorYaml(mav0_ + "/imu0/sensor.yaml", imu);
}

}  // namespace mav::dataset
