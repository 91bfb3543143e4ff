#include "mav/dataset/euroc.h"

#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "mav/camera/stereo.h"
#include "mav/dataset/png.h"
#include "mav/dataset/stereo_pair.h"
#include "test_util.h"
#include "tests/common/build_paths.h"

namespace mav::dataset {
namespace {

using testing::ReadFile;
using testing::TempDir;
using testing::WriteFile;

namespace fs = std::filesystem;

constexpr int64_t kT0 = 1403715273262142976;

// What we wrote ourselves never repeats a stamp: read it back strictly.
ReadOptions Strict() {
  ReadOptions options;
  options.repeated_stamps = RepeatedStamps::kReject;
  return options;
}

// Deterministic, textured-looking test image.
cv::Mat MakeImage(int width, int height, uint32_t seed) {
  cv::Mat image(height, width, CV_8UC1);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> noise(0, 255);
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      image.at<uint8_t>(r, c) = static_cast<uint8_t>(((r / 8 + c / 8) % 2) * 128 + noise(rng) / 2);
    }
  }
  return image;
}

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() &&
         std::equal(a.begin<uint8_t>(), a.end<uint8_t>(), b.begin<uint8_t>());
}

// A unit quaternion that geometry::SE3's renormalisation leaves bit-identical, so that a pose
// round trip can be asserted exactly (see the caveat in euroc.h).
Eigen::Quaterniond FixedPointQuaternion(std::mt19937* rng) {
  std::normal_distribution<double> n;
  while (true) {
    Eigen::Quaterniond q = Eigen::Quaterniond(n(*rng), n(*rng), n(*rng), n(*rng)).normalized();
    if (q.normalized().coeffs() == q.coeffs()) return q;
  }
}

std::vector<ImuSample> MakeImu(int count, std::mt19937* rng) {
  std::normal_distribution<double> n;
  std::vector<ImuSample> samples(count);
  for (int i = 0; i < count; ++i) {
    samples[i].t_ns = kT0 + i * 5'000'000 + (i % 3);  // not a perfectly regular clock
    samples[i].gyro = Eigen::Vector3d(n(*rng), n(*rng), n(*rng)) * 0.3;
    samples[i].accel = Eigen::Vector3d(n(*rng), n(*rng), 9.81 + n(*rng));
  }
  return samples;
}

std::vector<GroundTruthState> MakeGroundTruth(int count, bool fixed_point, std::mt19937* rng) {
  std::normal_distribution<double> n;
  std::vector<GroundTruthState> states(count);
  for (int i = 0; i < count; ++i) {
    GroundTruthState& g = states[i];
    g.t_ns = kT0 + i * 5'000'000;
    const Eigen::Quaterniond q =
        fixed_point ? FixedPointQuaternion(rng)
                    : Eigen::Quaterniond(n(*rng), n(*rng), n(*rng), n(*rng)).normalized();
    g.T_world_body = geometry::SE3(q, Eigen::Vector3d(n(*rng), n(*rng), n(*rng)) * 3.0);
    g.v_world = Eigen::Vector3d(n(*rng), n(*rng), n(*rng));
    g.gyro_bias = Eigen::Vector3d(n(*rng), n(*rng), n(*rng)) * 1e-3;
    g.accel_bias = Eigen::Vector3d(n(*rng), n(*rng), n(*rng)) * 1e-2;
  }
  return states;
}

void ExpectCameraEqual(const camera::PinholeRadTan& a, const camera::PinholeRadTan& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.fx, b.fx);
  EXPECT_EQ(a.fy, b.fy);
  EXPECT_EQ(a.cx, b.cx);
  EXPECT_EQ(a.cy, b.cy);
  EXPECT_EQ(a.k1, b.k1);
  EXPECT_EQ(a.k2, b.k2);
  EXPECT_EQ(a.p1, b.p1);
  EXPECT_EQ(a.p2, b.p2);
}

struct Written {
  camera::StereoCalibration calibration;
  ImuNoise noise;
  std::vector<int64_t> times;
  std::vector<cv::Mat> left, right;
  std::vector<ImuSample> imu;
  std::vector<GroundTruthState> ground_truth;
};

// Writes a small data set with frames handed to two threads in scrambled order.
Written WriteDataSet(const std::string& root, bool fixed_point_quaternions, uint32_t seed) {
  std::mt19937 rng(seed);
  Written w;
  w.calibration = camera::EurocStereoCalibration();
  w.noise.gyroscope_noise_density = 1.234567890123e-4;
  w.noise.accelerometer_random_walk = 0.1 + 0.2;  // 0.30000000000000004
  auto writer = EurocWriter::Create(root, w.calibration, w.noise, 20.0, 200.0);
  EXPECT_TRUE(writer.ok()) << writer.status().ToString();
  const int kFrames = 6;
  for (int i = 0; i < kFrames; ++i) {
    w.times.push_back(kT0 + i * 50'000'000 + 7 * i);
    w.left.push_back(MakeImage(752, 480, seed * 100 + 2 * i));
    w.right.push_back(MakeImage(752, 480, seed * 100 + 2 * i + 1));
  }
  std::vector<std::thread> threads;
  threads.reserve(2);
  for (int t = 0; t < 2; ++t) {
    threads.emplace_back([&, t] {
      for (int i = kFrames - 1 - t; i >= 0; i -= 2) {
        const Status s = (*writer)->WriteStereo(w.times[i], w.left[i], w.right[i]);
        EXPECT_TRUE(s.ok()) << s.ToString();
      }
    });
  }
  for (std::thread& t : threads) t.join();
  w.imu = MakeImu(40, &rng);
  w.ground_truth = MakeGroundTruth(25, fixed_point_quaternions, &rng);
  // In two chunks, to exercise appending.
  EXPECT_TRUE((*writer)->WriteImu({w.imu.begin(), w.imu.begin() + 10}).ok());
  EXPECT_TRUE((*writer)->WriteImu({w.imu.begin() + 10, w.imu.end()}).ok());
  EXPECT_TRUE((*writer)->WriteGroundTruth(w.ground_truth).ok());
  const Status closed = (*writer)->Close();
  EXPECT_TRUE(closed.ok()) << closed.ToString();
  return w;
}

TEST(EurocRoundTrip, EverythingReadsBackExactly) {
  TempDir dir;
  const Written w = WriteDataSet(dir.path(), /*fixed_point_quaternions=*/true, 3);
  auto reader = EurocReader::Open(dir.path(), Strict());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();

  ExpectCameraEqual(reader->calibration().cam0, w.calibration.cam0);
  ExpectCameraEqual(reader->calibration().cam1, w.calibration.cam1);
  // T_BS goes through a 4x4 matrix: a few ulps (documented), translation exact.
  for (int c = 0; c < 2; ++c) {
    const geometry::SE3& a =
        c == 0 ? reader->calibration().T_body_cam0 : reader->calibration().T_body_cam1;
    const geometry::SE3& b = c == 0 ? w.calibration.T_body_cam0 : w.calibration.T_body_cam1;
    EXPECT_EQ(a.Translation(), b.Translation());
    EXPECT_LT((a.Matrix() - b.Matrix()).cwiseAbs().maxCoeff(), 1e-15);
  }
  EXPECT_EQ(reader->imu_noise().gyroscope_noise_density, w.noise.gyroscope_noise_density);
  EXPECT_EQ(reader->imu_noise().gyroscope_random_walk, w.noise.gyroscope_random_walk);
  EXPECT_EQ(reader->imu_noise().accelerometer_noise_density, w.noise.accelerometer_noise_density);
  EXPECT_EQ(reader->imu_noise().accelerometer_random_walk, w.noise.accelerometer_random_walk);
  EXPECT_EQ(reader->camera_rate_hz(), 20.0);
  EXPECT_EQ(reader->imu_rate_hz(), 200.0);

  ASSERT_EQ(reader->num_frames(), static_cast<int64_t>(w.times.size()));
  EXPECT_EQ(reader->skipped_frames(), 0);
  EXPECT_EQ(reader->frame_times(), w.times);
  for (int64_t i = 0; i < reader->num_frames(); ++i) {
    auto pair = reader->ReadStereo(i);
    ASSERT_TRUE(pair.ok()) << pair.status().ToString();
    EXPECT_EQ(pair->t_ns, w.times[i]);
    EXPECT_TRUE(SameImage(pair->left, w.left[i])) << "frame " << i;
    EXPECT_TRUE(SameImage(pair->right, w.right[i])) << "frame " << i;
  }

  ASSERT_EQ(reader->imu().size(), w.imu.size());
  for (size_t i = 0; i < w.imu.size(); ++i) {
    EXPECT_EQ(reader->imu()[i].t_ns, w.imu[i].t_ns);
    EXPECT_EQ(reader->imu()[i].gyro, w.imu[i].gyro);
    EXPECT_EQ(reader->imu()[i].accel, w.imu[i].accel);
  }
  ASSERT_TRUE(reader->has_ground_truth());
  ASSERT_EQ(reader->ground_truth().size(), w.ground_truth.size());
  for (size_t i = 0; i < w.ground_truth.size(); ++i) {
    const GroundTruthState& a = reader->ground_truth()[i];
    const GroundTruthState& b = w.ground_truth[i];
    EXPECT_EQ(a.t_ns, b.t_ns);
    EXPECT_EQ(a.T_world_body.Translation(), b.T_world_body.Translation());
    EXPECT_EQ(a.T_world_body.Rotation().coeffs(), b.T_world_body.Rotation().coeffs());
    EXPECT_EQ(a.v_world, b.v_world);
    EXPECT_EQ(a.gyro_bias, b.gyro_bias);
    EXPECT_EQ(a.accel_bias, b.accel_bias);
  }
}

TEST(EurocRoundTrip, ArbitraryQuaternionsWithinOneUlpAndRewriteIsStable) {
  TempDir dir;
  const Written w = WriteDataSet(dir.path() + "/a", /*fixed_point_quaternions=*/false, 5);
  auto reader = EurocReader::Open(dir.path() + "/a", Strict());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  for (size_t i = 0; i < w.ground_truth.size(); ++i) {
    const Eigen::Vector4d d = reader->ground_truth()[i].T_world_body.Rotation().coeffs() -
                              w.ground_truth[i].T_world_body.Rotation().coeffs();
    EXPECT_LE(d.cwiseAbs().maxCoeff(), 2.3e-16) << "state " << i;
    EXPECT_EQ(reader->ground_truth()[i].T_world_body.Translation(),
              w.ground_truth[i].T_world_body.Translation());
  }
  // Rewriting what was read reproduces every CSV and sensor.yaml except for quaternion last bits.
  auto writer = EurocWriter::Create(dir.path() + "/b", reader->calibration(), reader->imu_noise());
  ASSERT_TRUE(writer.ok());
  ASSERT_TRUE((*writer)->WriteImu(reader->imu()).ok());
  for (int64_t i = 0; i < reader->num_frames(); ++i) {
    auto pair = reader->ReadStereo(i);
    ASSERT_TRUE(pair.ok());
    ASSERT_TRUE((*writer)->WriteStereo(pair->t_ns, pair->left, pair->right).ok());
  }
  ASSERT_TRUE((*writer)->Close().ok());
  for (const char* file : {"/mav0/imu0/data.csv", "/mav0/cam0/data.csv", "/mav0/cam1/data.csv",
                           "/mav0/imu0/sensor.yaml"}) {
    EXPECT_EQ(ReadFile(dir.path() + "/a" + file), ReadFile(dir.path() + "/b" + file)) << file;
  }
  EXPECT_FALSE(fs::exists(dir.path() + "/b/mav0/state_groundtruth_estimate0"));
}

TEST(EurocWriter, RejectsBadImagesNamingTheField) {
  TempDir dir;
  auto writer = EurocWriter::Create(dir.path(), camera::EurocStereoCalibration(), ImuNoise());
  ASSERT_TRUE(writer.ok());
  const cv::Mat good = MakeImage(752, 480, 1);
  const cv::Mat colour(480, 752, CV_8UC3, cv::Scalar(1, 2, 3));
  const cv::Mat small = MakeImage(640, 480, 2);
  Status s = (*writer)->WriteStereo(kT0, colour, good);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("left"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("CV_8UC1"), std::string::npos) << s.message();
  s = (*writer)->WriteStereo(kT0, good, small);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("right"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("752x480"), std::string::npos) << s.message();
  s = (*writer)->WriteStereo(kT0, cv::Mat(), good);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE((*writer)->WriteStereo(kT0, good, good).ok());
  s = (*writer)->WriteStereo(kT0, good, good);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << "duplicate timestamp";
  std::mt19937 rng(1);
  std::vector<ImuSample> imu = MakeImu(3, &rng);
  std::swap(imu[1], imu[2]);
  EXPECT_EQ((*writer)->WriteImu(imu).code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE((*writer)->Close().ok());
  EXPECT_EQ((*writer)->WriteStereo(kT0 + 1, good, good).code(), StatusCode::kFailedPrecondition);

  camera::StereoCalibration bad = camera::EurocStereoCalibration();
  bad.cam1.fx = -1;
  auto bad_writer = EurocWriter::Create(dir.path() + "/x", bad, ImuNoise());
  ASSERT_FALSE(bad_writer.ok());
  EXPECT_NE(bad_writer.status().message().find("cam1"), std::string::npos);
  auto bad_rate =
      EurocWriter::Create(dir.path() + "/y", camera::EurocStereoCalibration(), ImuNoise(), 0.0);
  ASSERT_FALSE(bad_rate.ok());
  EXPECT_NE(bad_rate.status().message().find("camera_rate_hz"), std::string::npos);
}

// A copy of tests/data/euroc_tiny (hand-made in the real data set's style: "%YAML:1.0" headers,
// EuRoC's spacing, cam1 missing one frame) with images generated here.
class EurocFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = dir_.path() + "/seq";
    fs::copy(mav::testing::SourceDir() + "/tests/data/euroc_tiny", root_,
             fs::copy_options::recursive);
    for (int cam = 0; cam < 2; ++cam) {
      const std::string folder = root_ + "/mav0/cam" + std::to_string(cam);
      fs::create_directories(folder + "/data");
      const std::string csv = ReadFile(folder + "/data.csv");
      size_t pos = 0;
      while ((pos = csv.find('\n', pos)) != std::string::npos && pos + 1 < csv.size()) {
        const std::string t = csv.substr(pos + 1, 19);
        const cv::Mat image =
            MakeImage(752, 480, static_cast<uint32_t>(std::stoll(t) % 1000) + cam);
        ASSERT_TRUE(WritePngFile(folder + "/data/" + t + ".png", image).ok());
        ++pos;
      }
    }
  }
  std::string Path(const std::string& rel) const { return root_ + "/mav0/" + rel; }
  // Replaces the line `line` (1-based) of a file.
  void ReplaceLine(const std::string& rel, int line, const std::string& text) {
    std::string contents = ReadFile(Path(rel));
    size_t begin = 0;
    for (int i = 1; i < line; ++i) begin = contents.find('\n', begin) + 1;
    const size_t end = contents.find('\n', begin);
    contents.replace(begin, end - begin, text);
    WriteFile(Path(rel), contents);
  }
  Status OpenStatus() const { return EurocReader::Open(root_).status(); }

  TempDir dir_;
  std::string root_;
};

TEST_F(EurocFixture, ReadsRealLookingSequence) {
  auto reader = EurocReader::Open(root_);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  EXPECT_EQ(reader->num_frames(), 3);
  EXPECT_EQ(reader->skipped_frames(), 1);  // 1403715273312143104 exists in cam0 only
  EXPECT_EQ(reader->frame_times()[1], 1403715273362142976);
  const camera::StereoCalibration& calib = reader->calibration();
  EXPECT_EQ(calib.cam0.fx, 458.654);
  EXPECT_EQ(calib.cam1.cy, 255.238);
  EXPECT_EQ(calib.cam1.p2, -3.55590700e-05);
  EXPECT_EQ(calib.T_body_cam0.Translation(),
            Eigen::Vector3d(-0.0216401454975, -0.064676986768, 0.00981073058949));
  EXPECT_NEAR(calib.Baseline(), 0.110, 0.001);
  EXPECT_EQ(reader->imu_noise().gyroscope_noise_density, 1.6968e-04);
  EXPECT_EQ(reader->imu_noise().accelerometer_random_walk, 3.0e-3);
  ASSERT_EQ(reader->imu().size(), 5u);
  EXPECT_EQ(reader->imu()[0].gyro.x(), -0.0872664625997164);
  EXPECT_EQ(reader->imu()[4].accel.z(), -3.0395833333333333);
  ASSERT_EQ(reader->ground_truth().size(), 3u);
  EXPECT_EQ(reader->ground_truth()[2].T_world_body.Translation().y(), 2.142330);
  EXPECT_NEAR(reader->ground_truth()[0].T_world_body.Rotation().w(), 0.060514, 1e-5);
  EXPECT_EQ(reader->ground_truth()[1].accel_bias.z(), 0.069136);

  auto pair = reader->ReadStereo(1);
  ASSERT_TRUE(pair.ok()) << pair.status().ToString();
  EXPECT_TRUE(SameImage(pair->left, MakeImage(752, 480, 1403715273362142976 % 1000)));
  EXPECT_TRUE(SameImage(pair->right, MakeImage(752, 480, 1403715273362142976 % 1000 + 1)));
  EXPECT_EQ(reader->ReadStereo(3).status().code(), StatusCode::kOutOfRange);
  EXPECT_EQ(reader->ReadStereo(-1).status().code(), StatusCode::kOutOfRange);

  // Opening mav0 itself works too.
  EXPECT_TRUE(EurocReader::Open(root_ + "/mav0").ok());
}

TEST_F(EurocFixture, ParallelReadsAgree) {
  auto reader = EurocReader::Open(root_);
  ASSERT_TRUE(reader.ok());
  std::vector<cv::Mat> images(8);
  std::vector<std::thread> threads;
  threads.reserve(8);
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&, t] {
      cv::Mat right;
      EXPECT_TRUE(reader->ReadStereo(t % 3, &images[t], &right).ok());
    });
  }
  for (std::thread& t : threads) t.join();
  for (int t = 3; t < 8; ++t) EXPECT_TRUE(SameImage(images[t], images[t % 3]));
}

TEST_F(EurocFixture, WindowsLineEndingsAreAccepted) {
  std::string csv = ReadFile(Path("imu0/data.csv"));
  std::string crlf;
  for (char c : csv) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  WriteFile(Path("imu0/data.csv"), crlf);
  auto reader = EurocReader::Open(root_);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  EXPECT_EQ(reader->imu().size(), 5u);
}

TEST_F(EurocFixture, GroundTruthIsOptional) {
  fs::remove_all(Path("state_groundtruth_estimate0"));
  auto reader = EurocReader::Open(root_);
  ASSERT_TRUE(reader.ok());
  EXPECT_FALSE(reader->has_ground_truth());
}

TEST(EurocReaderErrors, MissingDirectory) {
  const Status s = EurocReader::Open("/nonexistent/euroc/seq").status();
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_NE(s.message().find("/nonexistent/euroc/seq"), std::string::npos);
  TempDir empty;
  const Status s2 = EurocReader::Open(empty.path()).status();
  EXPECT_EQ(s2.code(), StatusCode::kNotFound);
  EXPECT_NE(s2.message().find("mav0"), std::string::npos) << s2.message();
}

TEST_F(EurocFixture, MissingDataCsv) {
  fs::remove(Path("cam1/data.csv"));
  const Status s = OpenStatus();
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_NE(s.message().find("cam1/data.csv"), std::string::npos) << s.message();
}

TEST_F(EurocFixture, MissingSensorYaml) {
  fs::remove(Path("imu0/sensor.yaml"));
  const Status s = OpenStatus();
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_NE(s.message().find("imu0/sensor.yaml"), std::string::npos) << s.message();
}

TEST_F(EurocFixture, MalformedCsvRowNamesFileLineAndColumn) {
  ReplaceLine("imu0/data.csv", 4,
              "1403715273277142784,-0.0907571211347,0.1452863201000000,abc,9.23,0.22,-3.04");
  const Status s = OpenStatus();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("imu0/data.csv:4: column 'w_RS_S_z [rad s^-1]'"), std::string::npos)
      << s.message();
  EXPECT_NE(s.message().find("'abc'"), std::string::npos) << s.message();
}

TEST_F(EurocFixture, MalformedTimestampNamesColumn) {
  ReplaceLine("state_groundtruth_estimate0/data.csv", 3,
              "14037152732671429x2,0.878658,2.142400,0.947250,0.060526,-0.828455,-0.058967,"
              "-0.553644,0.009336,-0.014010,-0.002454,-0.002229,0.020700,0.076350,-0.012492,"
              "0.547666,0.069136");
  const Status s = OpenStatus();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("state_groundtruth_estimate0/data.csv:3: column '#timestamp'"),
            std::string::npos)
      << s.message();
}

TEST_F(EurocFixture, WrongColumnCount) {
  ReplaceLine("imu0/data.csv", 3, "1403715273267142912,-0.08936,0.14319,0.07118,9.16,0.22");
  const Status s = OpenStatus();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("imu0/data.csv:3: expected 7 columns, got 6"), std::string::npos)
      << s.message();
}

TEST_F(EurocFixture, NonMonotonicTimestamps) {
  ReplaceLine("cam0/data.csv", 4, "1403715273262142976,1403715273262142976.png");
  const Status s = OpenStatus();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("cam0/data.csv:4: timestamp"), std::string::npos) << s.message();
}

TEST_F(EurocFixture, CorruptPng) {
  auto reader = EurocReader::Open(root_);
  ASSERT_TRUE(reader.ok());
  const std::string path = reader->RightImagePath(2);
  std::string bytes = ReadFile(path);
  WriteFile(path, bytes.substr(0, 40));  // truncated
  const Status s = reader->ReadStereo(2).status();
  EXPECT_EQ(s.code(), StatusCode::kDataLoss);
  EXPECT_NE(s.message().find(path), std::string::npos) << s.message();
  WriteFile(path, "not a png at all");
  EXPECT_EQ(reader->ReadStereo(2).status().code(), StatusCode::kDataLoss);
  WriteFile(path, "");
  EXPECT_EQ(reader->ReadStereo(2).status().code(), StatusCode::kDataLoss);
}

TEST_F(EurocFixture, MissingPng) {
  auto reader = EurocReader::Open(root_);
  ASSERT_TRUE(reader.ok());
  const std::string path = reader->LeftImagePath(0);
  fs::remove(path);
  const Status s = reader->ReadStereo(0).status();
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_NE(s.message().find(path), std::string::npos) << s.message();
}

TEST_F(EurocFixture, WrongImageSize) {
  auto reader = EurocReader::Open(root_);
  ASSERT_TRUE(reader.ok());
  const std::string path = reader->LeftImagePath(1);
  ASSERT_TRUE(WritePngFile(path, MakeImage(320, 240, 9)).ok());
  Status s = reader->ReadStereo(1).status();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find(path), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("expected 752x480"), std::string::npos) << s.message();
  ASSERT_TRUE(WritePngFile(path, cv::Mat(480, 752, CV_8UC3, cv::Scalar(0, 0, 0))).ok());
  s = reader->ReadStereo(1).status();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("grey"), std::string::npos) << s.message();
}

struct YamlCase {
  const char* file;
  const char* from;  // text replaced in the fixture file
  const char* to;
  const char* expected;  // substring of the error
};

TEST_F(EurocFixture, BadSensorYamlNamesTheField) {
  const YamlCase cases[] = {
      {"cam0/sensor.yaml", "intrinsics: [458.654, 457.296, 367.215, 248.375]",
       "intrinsics: [458.654, 457.296, 367.215]", "field 'intrinsics': expected 4 numbers, got 3"},
      {"cam0/sensor.yaml", "intrinsics: [458.654, 457.296,", "intrinsics: [458.654, fx,",
       "field 'intrinsics[1]'"},
      {"cam0/sensor.yaml", "intrinsics: [458.654,", "intrinsics: [-458.654,", "intrinsics"},
      {"cam1/sensor.yaml", "rate_hz: 20", "rate_hz: fast", "field 'rate_hz'"},
      {"cam1/sensor.yaml", "resolution: [752, 480]", "resolution: [752.5, 480]",
       "field 'resolution'"},
      {"cam1/sensor.yaml", "camera_model: pinhole", "camera_model: omni", "field 'camera_model'"},
      {"cam1/sensor.yaml", "radial-tangential", "equidistant", "field 'distortion_model'"},
      {"cam0/sensor.yaml", "sensor_type: camera", "sensor_type: imu", "field 'sensor_type'"},
      {"cam0/sensor.yaml", "  data: [0.0148655429818,", "  data: [0.5,", "field 'T_BS'"},
      {"cam0/sensor.yaml", "         0.0, 0.0, 0.0, 1.0]", "         0.0, 0.0, 0.0]",
       "field 'T_BS.data': expected 16 numbers, got 15"},
      {"imu0/sensor.yaml", "gyroscope_random_walk: 1.9393e-05", "gyroscope_random_walk: -1",
       "field 'gyroscope_random_walk'"},
      {"imu0/sensor.yaml", "accelerometer_noise_density: 2.0000e-3", "",
       "field 'accelerometer_noise_density': missing"},
      {"imu0/sensor.yaml", "rate_hz: 200", "rate_hz: [200", "not valid YAML"},
      {"cam1/sensor.yaml", "resolution: [752, 480]", "resolution: [640, 480]",
       "resolution differs"},
  };
  for (const YamlCase& c : cases) {
    const std::string original = ReadFile(Path(c.file));
    const size_t pos = original.find(c.from);
    ASSERT_NE(pos, std::string::npos) << c.from;
    std::string changed = original;
    changed.replace(pos, std::string(c.from).size(), c.to);
    WriteFile(Path(c.file), changed);
    const Status s = OpenStatus();
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << c.to;
    EXPECT_NE(s.message().find(c.expected), std::string::npos)
        << "expected '" << c.expected << "' in: " << s.message();
    if (std::string(c.expected).find("field") != std::string::npos) {
      EXPECT_NE(s.message().find(c.file), std::string::npos) << s.message();
    }
    WriteFile(Path(c.file), original);
  }
  EXPECT_TRUE(OpenStatus().ok());
}

TEST(SensorYaml, RoundTripAndYamlDirective) {
  TempDir dir;
  CameraSensor sensor;
  sensor.intrinsics = camera::EurocCam1();
  sensor.T_body_cam = camera::EurocStereoCalibration().T_body_cam1;
  sensor.rate_hz = 19.5;
  sensor.comment = "a: comment with \"quotes\" # and hash";
  const std::string path = dir.path() + "/sensor.yaml";
  ASSERT_TRUE(WriteCameraSensorYaml(path, sensor).ok());
  WriteFile(path, "%YAML:1.0\n" + ReadFile(path));
  auto read = ReadCameraSensorYaml(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ExpectCameraEqual(read->intrinsics, sensor.intrinsics);
  EXPECT_EQ(read->rate_hz, 19.5);
  EXPECT_EQ(read->comment, sensor.comment);
  EXPECT_EQ(read->T_body_cam.Translation(), sensor.T_body_cam.Translation());
  EXPECT_LT((read->T_body_cam.Matrix() - sensor.T_body_cam.Matrix()).cwiseAbs().maxCoeff(), 1e-15);
}

}  // namespace
}  // namespace mav::dataset
