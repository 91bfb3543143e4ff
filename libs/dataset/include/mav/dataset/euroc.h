#pragma once
// The EuRoC MAV data set's "ASL" directory layout (Burri et al., "The EuRoC micro aerial vehicle
// datasets", IJRR 2016), read and written exactly:
//
//   <root>/mav0/cam0/data.csv          "#timestamp [ns],filename", rows "<t_ns>,<t_ns>.png"
//   <root>/mav0/cam0/data/<t_ns>.png   8-bit grey images (cam1 the same)
//   <root>/mav0/cam0/sensor.yaml       intrinsics [fu, fv, cu, cv], radial-tangential distortion
//                                      [k1, k2, p1, p2], resolution, rate_hz, T_BS (4x4 row-major)
//   <root>/mav0/imu0/data.csv          t_ns, gyro x y z [rad/s], accel x y z [m/s^2] (gyro first)
//   <root>/mav0/imu0/sensor.yaml       rate_hz and the four noise densities
//   <root>/mav0/state_groundtruth_estimate0/data.csv   17 columns: t_ns, p xyz, q wxyz (w first),
//                                      v xyz, gyro bias xyz, accel bias xyz (optional on reading)
//
// Frames: B ("body") is the IMU frame; T_BS in a camera's sensor.yaml is T_body_cam. If imu0's
// T_BS is not the identity, the reader re-expresses the cameras in the IMU frame.
//
// Exactness: every number is written in the shortest decimal form that parses back to the same
// double (std::to_chars), so timestamps, IMU samples, translations, velocities, biases, intrinsics
// and distortion round-trip bit for bit, and images are lossless PNG. Ground-truth quaternions
// round-trip bit for bit too (geometry::SE3 keeps a quaternion that is unit to rounding as it is).
// T_BS goes through a rotation matrix and back, which costs a few ulps. See docs/datasets.md.
//
// This header does not include OpenCV; callers of ReadStereo() that want a StereoPair include
// "mav/dataset/stereo_pair.h".

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "mav/camera/pinhole.h"
#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/dataset/read_options.h"
#include "mav/dataset/types.h"
#include "mav/geometry/se3.h"

namespace cv {
class Mat;
}

namespace mav::dataset {

struct StereoPair;  // mav/dataset/stereo_pair.h

// One camera's sensor.yaml.
struct CameraSensor {
  camera::PinholeRadTan intrinsics;  // width/height from `resolution`
  geometry::SE3 T_body_cam;          // T_BS
  double rate_hz = 20.0;
  std::string comment;
};

// imu0/sensor.yaml.
struct ImuSensor {
  ImuNoise noise;
  geometry::SE3 T_body_imu;  // T_BS, identity in EuRoC
  double rate_hz = 200.0;
  std::string comment;
};

// Parse / write one sensor.yaml. A leading "%YAML:1.0" directive (OpenCV's style, which yaml-cpp
// rejects) is stripped. Errors: NotFound (file), InvalidArgument "path: field 'intrinsics': ...".
Result<CameraSensor> ReadCameraSensorYaml(const std::string& path);
Result<ImuSensor> ReadImuSensorYaml(const std::string& path);
// The same from text in memory (an upload, a fuzzer); `name` stands for the path in messages.
Result<CameraSensor> ParseCameraSensorYaml(std::string_view text, const std::string& name);
Result<ImuSensor> ParseImuSensorYaml(std::string_view text, const std::string& name);

// The rows of a camera's data.csv: stamps strictly increasing (two images with one stamp could not
// be told apart), file names plain (no '/', not "." or "..").
struct CameraCsv {
  std::vector<int64_t> t_ns;
  std::vector<std::string> files;  // relative to cam*/data
};

// The CSV readers EurocReader::Open uses, on text in memory; `name` stands for the path in
// messages ("name:line: column 'p_RS_R_x [m]': ..."). Every number must be finite and within
// +-1e9 (no measurement is larger; it keeps sums and squares of them finite). Time stamps must not
// go backwards; a repeated stamp in imu0 or ground truth is handled as `options` says (default:
// first row kept, later ones dropped with a warning naming name:line; read_options.h).
Result<CameraCsv> ParseCameraCsv(std::string_view text, const std::string& name);
Result<std::vector<ImuSample>> ParseImuCsv(std::string_view text, const std::string& name,
                                           const ReadOptions& options = {});
Result<std::vector<GroundTruthState>> ParseGroundTruthCsv(std::string_view text,
                                                          const std::string& name,
                                                          const ReadOptions& options = {});
Status WriteCameraSensorYaml(const std::string& path, const CameraSensor& sensor);
Status WriteImuSensorYaml(const std::string& path, const ImuSensor& sensor);

// Writes one EuRoC directory. WriteStereo() may be called from several threads at once and in any
// order of time (PNG encoding happens outside the lock); Close() sorts and writes every CSV and
// sensor.yaml atomically (temporary file + rename), so an interrupted run never leaves a
// half-written CSV. Destroying an unclosed writer writes nothing more.
class EurocWriter {
 public:
  // Creates <root>/mav0/{cam0,cam1}/data and imu0. InvalidArgument if the calibration or a rate is
  // invalid (field named), IoError if the directories cannot be made.
  static Result<std::unique_ptr<EurocWriter>> Create(const std::string& root,
                                                     const camera::StereoCalibration& calibration,
                                                     const ImuNoise& imu_noise,
                                                     double camera_rate_hz = 20.0,
                                                     double imu_rate_hz = 200.0);

  // Encodes both images as PNG (<t_ns>.png). InvalidArgument naming "left"/"right" if an image is
  // not CV_8UC1 or not the calibrated size, or if t_ns was already written; FailedPrecondition
  // after Close(). Thread-safe.
  Status WriteStereo(int64_t t_ns, const cv::Mat& left, const cv::Mat& right);
  // Appends samples; timestamps must increase strictly across all calls.
  Status WriteImu(const std::vector<ImuSample>& samples);
  Status WriteGroundTruth(const std::vector<GroundTruthState>& states);
  // Writes the CSVs and sensor.yaml files. Ground truth is written only if any was given.
  Status Close();

  const std::string& root() const { return root_; }
  int64_t frames_written() const;

  ~EurocWriter();

 private:
  EurocWriter() = default;

  std::string root_;
  std::string mav0_;
  camera::StereoCalibration calibration_;
  ImuNoise imu_noise_;
  double camera_rate_hz_ = 20.0;
  double imu_rate_hz_ = 200.0;

  mutable std::mutex mutex_;
  std::vector<int64_t> frame_times_;  // guarded by mutex_
  std::vector<ImuSample> imu_;
  std::vector<GroundTruthState> ground_truth_;
  bool closed_ = false;
};

// Reads one EuRoC directory (real or generated). `root` may be the directory holding mav0/ or
// mav0/ itself. Everything but the images is loaded by Open(); images are read on demand.
// All const methods are safe to call from several threads at once.
class EurocReader {
 public:
  // Errors: NotFound naming the missing path; InvalidArgument "path:line: column 'name': ..." for
  // a malformed row, "path:line: expected N columns, got M", "path:line: timestamp ... is not
  // after ..." for time going backwards; InvalidArgument naming the sensor.yaml field.
  // A repeated stamp in imu0 or the ground truth: see `options` (default: warn, keep the first;
  // pass RepeatedStamps::kReject for data we generated ourselves). Ground truth is optional
  // (has_ground_truth()). A set without stereo frames opens (see CheckHasFrames()).
  static Result<EurocReader> Open(const std::string& root, const ReadOptions& options = {});

  // Stereo frames: timestamps present in both cam0 and cam1 (paired by exact timestamp).
  int64_t num_frames() const { return static_cast<int64_t>(frame_times_.size()); }
  const std::vector<int64_t>& frame_times() const { return frame_times_; }
  // cam0 or cam1 rows without a partner of the same timestamp (skipped, as EuRoC has a few).
  int64_t skipped_frames() const { return skipped_frames_; }
  // Rows of cam0/data.csv and cam1/data.csv.
  int64_t cam0_rows() const { return cam0_rows_; }
  int64_t cam1_rows() const { return cam1_rows_; }
  // OK if num_frames() > 0, else FailedPrecondition saying why, naming the directory:
  // "<mav0>: no stereo frames: cam0/data.csv has no rows" or "... cam0/data.csv (5 rows) and
  // cam1/data.csv (5 rows) share no timestamp".
  Status CheckHasFrames() const;

  // Reads frame `index` (0 <= index < num_frames(), OutOfRange otherwise). NotFound if a PNG is
  // missing, DataLoss if it cannot be decoded, InvalidArgument naming the file and the expected
  // size if its size or type differs from sensor.yaml. Thread-safe.
  Status ReadStereo(int64_t index, cv::Mat* left, cv::Mat* right) const;
  Result<StereoPair> ReadStereo(int64_t index) const;
  std::string LeftImagePath(int64_t index) const;
  std::string RightImagePath(int64_t index) const;

  const std::vector<ImuSample>& imu() const { return imu_; }
  bool has_ground_truth() const { return !ground_truth_.empty(); }
  const std::vector<GroundTruthState>& ground_truth() const { return ground_truth_; }

  const camera::StereoCalibration& calibration() const { return calibration_; }
  const ImuNoise& imu_noise() const { return imu_noise_; }
  double camera_rate_hz() const { return camera_rate_hz_; }
  double imu_rate_hz() const { return imu_rate_hz_; }
  // The mav0 directory.
  const std::string& mav0() const { return mav0_; }

 private:
  EurocReader() = default;

  std::string mav0_;
  camera::StereoCalibration calibration_;
  ImuNoise imu_noise_;
  double camera_rate_hz_ = 20.0;
  double imu_rate_hz_ = 200.0;
  std::vector<int64_t> frame_times_;
  std::vector<std::string> left_files_;   // relative to cam0/data
  std::vector<std::string> right_files_;  // relative to cam1/data
  int64_t skipped_frames_ = 0;
  int64_t cam0_rows_ = 0;
  int64_t cam1_rows_ = 0;
  std::vector<ImuSample> imu_;
  std::vector<GroundTruthState> ground_truth_;
};

}  // namespace mav::dataset
