// Renderer tests: geometric accuracy of the rendered images (a known checkerboard), texture
// stability, and determinism of the scenario's images.

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mav/camera/rectifier.h"
#include "mav/camera/stereo.h"
#include "mav/sim/renderer.h"
#include "mav/sim/scenario.h"
#include "mav/sim/world.h"

namespace mav::sim {
namespace {

constexpr double kSquare = 0.09;              // metres
constexpr int kSquaresX = 10, kSquaresY = 8;  // inner corners 9 x 7
const cv::Size kPattern(kSquaresX - 1, kSquaresY - 1);

struct CheckerScene {
  std::shared_ptr<World> world;
  Eigen::Matrix3d R_world_board;
  Eigen::Vector3d board_center;
  std::vector<Eigen::Vector3d> corners_world;
};

// A checkerboard 2.2 m in front of a camera at the world origin looking along +z, tilted by
// 20 degrees about the vertical and 10 about the horizontal axis, on a white frame.
CheckerScene MakeCheckerScene() {
  CheckerScene s;
  s.world = std::make_shared<World>();
  Material checker;
  checker.pattern = TexturePattern::kChecker;
  checker.checker_square_m = static_cast<float>(kSquare);
  const int checker_id = s.world->AddMaterial(checker);
  Material white;
  white.pattern = TexturePattern::kUniform;
  white.albedo = 0.9f;
  const int white_id = s.world->AddMaterial(white);
  Material grey;
  grey.pattern = TexturePattern::kNoise;
  grey.albedo = 0.35f;
  grey.contrast = 0.05f;
  const int grey_id = s.world->AddMaterial(grey);

  // Board normal (local z) points back at the camera.
  const Eigen::Matrix3d flip = Eigen::Vector3d(1, -1, -1).asDiagonal();
  s.R_world_board = Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                    Eigen::AngleAxisd(0.17, Eigen::Vector3d::UnitX()).toRotationMatrix() * flip;
  s.board_center = Eigen::Vector3d(0.1, 0.05, 2.3);
  s.world->AddRectangle(s.board_center, s.R_world_board,
                        Eigen::Vector2d(kSquaresX * kSquare / 2, kSquaresY * kSquare / 2),
                        checker_id);
  s.world->AddRectangle(s.board_center - 0.01 * s.R_world_board.col(2), s.R_world_board,
                        Eigen::Vector2d(0.65, 0.55), white_id);
  s.world->AddAlignedBox(Eigen::Vector3d(-10, -10, 6), Eigen::Vector3d(10, 10, 6.5), grey_id);
  s.world->BuildTextures(7);
  for (int j = 1; j < kSquaresY; ++j) {
    for (int i = 1; i < kSquaresX; ++i) {
      const Eigen::Vector3d local((i - kSquaresX / 2.0) * kSquare, (j - kSquaresY / 2.0) * kSquare,
                                  0);
      s.corners_world.push_back(s.board_center + s.R_world_board * local);
    }
  }
  return s;
}

cv::Mat Render(const CameraRenderer& renderer, const geometry::SE3& T_world_cam) {
  std::vector<float> radiance;
  renderer.RenderRadiance(T_world_cam, &radiance);
  cv::Mat image;
  FormImage(radiance, renderer.width(), renderer.height(), 1.0, 0.0, 0, &image);
  return image;
}

std::vector<cv::Point2f> FindCorners(const cv::Mat& image) {
  std::vector<cv::Point2f> corners;
  if (!cv::findChessboardCorners(image, kPattern, corners,
                                 cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE)) {
    return {};
  }
  cv::cornerSubPix(image, corners, cv::Size(6, 6), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
  return corners;
}

// Index of the detection nearest to `uv` and its distance.
std::pair<int, double> Nearest(const std::vector<cv::Point2f>& found, const Eigen::Vector2d& uv) {
  int best = -1;
  double best_d = 1e9;
  for (size_t k = 0; k < found.size(); ++k) {
    const double d = std::hypot(found[k].x - uv.x(), found[k].y - uv.y());
    if (d < best_d) {
      best_d = d;
      best = static_cast<int>(k);
    }
  }
  return {best, best_d};
}

TEST(RenderTest, CheckerCornersProjectExactlyAndRectifiedDisparityMatchesDepth) {
  const CheckerScene scene = MakeCheckerScene();
  const camera::StereoCalibration calib = camera::EurocStereoCalibration();
  // cam0 at the world origin: T_world_body = T_body_cam0^-1.
  const geometry::SE3 T_world_body = calib.T_body_cam0.Inverse();
  const geometry::SE3 T_world_cam[2] = {T_world_body * calib.T_body_cam0,
                                        T_world_body * calib.T_body_cam1};
  const camera::PinholeRadTan cams[2] = {calib.cam0, calib.cam1};
  cv::Mat raw[2];
  for (int c = 0; c < 2; ++c) {
    CameraRenderer renderer(scene.world, cams[c]);
    raw[c] = Render(renderer, T_world_cam[c]);
    const std::vector<cv::Point2f> found = FindCorners(raw[c]);
    ASSERT_EQ(found.size(), scene.corners_world.size()) << "camera " << c;
    double max_err = 0;
    std::vector<int> used(found.size(), 0);
    for (const Eigen::Vector3d& p_world : scene.corners_world) {
      const std::optional<Eigen::Vector2d> uv = cams[c].Project(T_world_cam[c].Inverse() * p_world);
      ASSERT_TRUE(uv.has_value());
      const auto [k, d] = Nearest(found, *uv);
      ++used[k];
      max_err = std::max(max_err, d);
    }
    EXPECT_LT(max_err, 0.5) << "camera " << c;
    std::printf("camera %d: max corner error %.3f px\n", c, max_err);
    EXPECT_EQ(*std::max_element(used.begin(), used.end()), 1) << "ambiguous corner matches";
    RecordProperty(c == 0 ? "max_err_cam0_px" : "max_err_cam1_px", std::to_string(max_err));
  }

  Result<camera::StereoRectifier> rectifier = camera::StereoRectifier::Create(calib);
  ASSERT_TRUE(rectifier.ok()) << rectifier.status().ToString();
  cv::Mat rect[2];
  ASSERT_TRUE(rectifier->Rectify(raw[0], raw[1], &rect[0], &rect[1]).ok());
  const std::vector<cv::Point2f> left = FindCorners(rect[0]);
  const std::vector<cv::Point2f> right = FindCorners(rect[1]);
  ASSERT_EQ(left.size(), scene.corners_world.size());
  ASSERT_EQ(right.size(), scene.corners_world.size());
  const camera::RectifiedStereo& rs = rectifier->rectified();
  double max_disp_err = 0, max_row_err = 0;
  for (const Eigen::Vector3d& p_world : scene.corners_world) {
    const Eigen::Vector3d p_rect0 =
        rectifier->R_rect0_cam0() * (T_world_cam[0].Inverse() * p_world);
    const Eigen::Vector2d uv_l = *rs.ProjectLeft(p_rect0);
    const Eigen::Vector2d uv_r = *rs.ProjectRight(p_rect0);
    const auto [kl, dl] = Nearest(left, uv_l);
    const auto [kr, dr] = Nearest(right, uv_r);
    ASSERT_LT(dl, 1.0);
    ASSERT_LT(dr, 1.0);
    const double disparity = left[kl].x - right[kr].x;
    max_disp_err = std::max(max_disp_err, std::abs(disparity - rs.fx * rs.baseline / p_rect0.z()));
    max_row_err = std::max(max_row_err, static_cast<double>(std::abs(left[kl].y - right[kr].y)));
  }
  EXPECT_LT(max_disp_err, 0.25);
  EXPECT_LT(max_row_err, 0.25);
  RecordProperty("max_disparity_err_px", std::to_string(max_disp_err));
  std::printf("max disparity error %.3f px, max row error %.3f px\n", max_disp_err, max_row_err);
}

TEST(RenderTest, TextureIsStableUnderTinyMotion) {
  // Looking at a textured wall and floor from 1.5-4 m: a 1 mm sideways move changes the image
  // by a small fraction of a grey level on average, and nowhere by a jump (no shimmer).
  auto world = std::make_shared<World>();
  Material noise;
  noise.pattern = TexturePattern::kSpeckle;
  noise.contrast = 0.25f;
  const int m = world->AddMaterial(noise);
  Material bricks;
  bricks.pattern = TexturePattern::kBricks;
  const int b = world->AddMaterial(bricks);
  world->AddAlignedBox(Eigen::Vector3d(-5, -5, 4), Eigen::Vector3d(5, 5, 4.2), m);    // ahead
  world->AddAlignedBox(Eigen::Vector3d(-5, 1.0, -5), Eigen::Vector3d(5, 1.2, 5), b);  // below
  world->BuildTextures(3);
  CameraRenderer renderer(world, camera::EurocCam0());
  // Slightly rotated so that the texture is seen obliquely and not texel-aligned.
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.2, Eigen::Vector3d(0.3, 1, 0.1).normalized()));
  auto pose = [&](double dx) { return geometry::SE3(q, Eigen::Vector3d(0.01 + dx, 0.02, 0.0)); };
  const cv::Mat ia = Render(renderer, pose(0));
  auto mean_diff = [&](double dx, cv::Mat* diff) {
    cv::absdiff(ia, Render(renderer, pose(dx)), *diff);
    return cv::mean(*diff)[0];
  };
  cv::Mat diff1, diff2;
  const double mean1 = mean_diff(0.001, &diff1);
  const double mean2 = mean_diff(0.002, &diff2);
  std::printf("mean |diff| 1 mm: %.3f DN, 2 mm: %.3f DN\n", mean1, mean2);
  // A filtered texture changes smoothly: the change grows linearly with the motion (aliasing
  // would make even a tiny motion flip texels at random, giving a ratio near 1).
  EXPECT_LT(mean1, 1.0);
  EXPECT_LT(mean1 / mean2, 0.7);
  // Texture gradients are limited by the filtering; only geometric edges can jump.
  EXPECT_LT(cv::countNonZero(diff1 > 8), 0.002 * diff1.total());
  // The images are textured (the test would pass trivially on a blank image).
  cv::Scalar mu, sigma;
  cv::meanStdDev(ia, mu, sigma);
  EXPECT_GT(sigma[0], 8.0);
}

TEST(RenderTest, ScenarioImagesAreDeterministicAndSeedDependent) {
  ScenarioOptions o;
  o.preset = "room-hard";
  o.frames = 40;
  o.seed = 5;
  Result<Scenario> s1 = Scenario::Create(o);
  ASSERT_TRUE(s1.ok()) << s1.status().ToString();
  Result<Scenario> s2 = Scenario::Create(o);
  ASSERT_TRUE(s2.ok());
  cv::Mat l1, r1, l2, r2;
  s1->RenderStereo(17, &l1, &r1);
  s2->RenderStereo(17, &l2, &r2);
  ASSERT_EQ(l1.type(), CV_8UC1);
  EXPECT_EQ(l1.cols, 752);
  EXPECT_EQ(l1.rows, 480);
  EXPECT_EQ(cv::norm(l1, l2, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r1, r2, cv::NORM_INF), 0);
  // Same scenario, different frame: different noise and pose.
  cv::Mat l3, r3;
  s1->RenderStereo(18, &l3, &r3);
  EXPECT_GT(cv::norm(l1, l3, cv::NORM_L1), 0);

  o.seed = 6;
  Result<Scenario> s3 = Scenario::Create(o);
  ASSERT_TRUE(s3.ok());
  cv::Mat l4, r4;
  s3->RenderStereo(17, &l4, &r4);
  EXPECT_GT(cv::norm(l1, l4, cv::NORM_L1), 0);
}

// FNV-1a (64 bit) of the pair's bytes, left then right.
uint64_t HashPair(const cv::Mat& left, const cv::Mat& right) {
  uint64_t hash = 1469598103934665603ull;
  for (const cv::Mat* image : {&left, &right}) {
    const uint8_t* p = image->ptr<uint8_t>();
    for (size_t i = 0; i < image->total(); ++i) hash = (hash ^ p[i]) * 1099511628211ull;
  }
  return hash;
}

// The images of before issue 26, pinned: a faster renderer must produce these bytes, or change
// this test with the reason and the measured difference. One mid-flight stereo pair per preset
// (40 frames, seed 1, frame 23: motion-blurred on the blurred presets), hashed. The reference
// rendering (std::atan2 for the cylinders' texture angle) gives them bit for bit; the default
// one (the renderer's own atan2, 3e-7 rad from std::atan2) differs by at most 1 DN on a few
// pixels, bounded here, and is pinned too. The bytes are the GCC build's (the services' and
// the benchmarks'): the clang sanitizer tree's floating point differs (other hashes on all four
// presets): skipped there.
TEST(RenderTest, RenderedPairsArePinnedPerPreset) {
#if defined(__clang__)
  GTEST_SKIP() << "clang build: the pinned bytes are the GCC build's";
#endif
  struct Pinned {
    const char* preset;
    uint64_t reference, fast;
  };
  const Pinned pinned[] = {
      {"room-easy", 0x80277828573373ffull, 0x80277828573373ffull},
      {"room-medium", 0x64b7ada33fd590b6ull, 0x64b7ada33fd590b6ull},
      {"room-hard", 0xa7d43e8419496983ull, 0xa7d43e8419496983ull},
      {"plant", 0xff848806c288da72ull, 0xb39359b6c429b314ull},  // 2 + 2 pixels, 1 DN
  };
  for (const Pinned& p : pinned) {
    ScenarioOptions o;
    o.preset = p.preset;
    o.frames = 40;
    o.seed = 1;
    cv::Mat left[2], right[2];
    for (const bool exact : {true, false}) {
      o.exact_cylinder_angles = exact;
      Result<Scenario> s = Scenario::Create(o);
      ASSERT_TRUE(s.ok()) << s.status().ToString();
      s->RenderStereo(23, &left[exact], &right[exact]);
      ASSERT_TRUE(left[exact].isContinuous() && right[exact].isContinuous());
    }
    const uint64_t reference = HashPair(left[1], right[1]), fast = HashPair(left[0], right[0]);
    EXPECT_EQ(reference, p.reference)
        << p.preset << ": the reference pair changed (hash 0x" << std::hex << reference << ")";
    EXPECT_EQ(fast, p.fast) << p.preset << ": the pair changed (hash 0x" << std::hex << fast << ")";
    for (int c = 0; c < 2; ++c) {
      const cv::Mat& a = c == 0 ? left[0] : right[0];
      const cv::Mat& b = c == 0 ? left[1] : right[1];
      const double differing = cv::countNonZero(a != b);
      std::printf("%s camera %d: %.0f pixels differ from the reference, at most %.0f DN\n",
                  p.preset, c, differing, cv::norm(a, b, cv::NORM_INF));
      EXPECT_LE(cv::norm(a, b, cv::NORM_INF), 1) << p.preset;
      EXPECT_LE(differing, 1e-3 * static_cast<double>(a.total())) << p.preset;
    }
  }
}

TEST(RenderTest, LaneAtan2IsWithinThreeTenthsOfAMicroradianOfStdAtan2) {
  // Every direction (1e6 angles over the circle, the axes and diagonals exactly) at radii from
  // millimetres to kilometres.
  double worst = 0;
  for (const float radius : {1e-3f, 0.016f, 1.2f, 7.0f, 1e3f}) {
    for (int k = 0; k < 1000000; ++k) {
      const double a = -M_PI + 2 * M_PI * k / 1000000;
      const float x = static_cast<float>(radius * std::cos(a));
      const float y = static_cast<float>(radius * std::sin(a));
      worst = std::max(worst, std::abs(static_cast<double>(internal::LaneAtan2(y, x)) -
                                       std::atan2(static_cast<double>(y), x)));
    }
    for (const auto& [x, y] : {std::pair{1.0f, 0.0f},
                               {0.0f, 1.0f},
                               {-1.0f, 0.0f},
                               {0.0f, -1.0f},
                               {1.0f, 1.0f},
                               {-1.0f, 1.0f},
                               {-1.0f, -1.0f},
                               {1.0f, -1.0f}}) {
      worst = std::max(worst,
                       std::abs(static_cast<double>(internal::LaneAtan2(radius * y, radius * x)) -
                                std::atan2(static_cast<double>(y), x)));
    }
  }
  std::printf("worst |LaneAtan2 - atan2| %.3g rad\n", worst);
  EXPECT_LT(worst, 3e-7);
}

TEST(RenderTest, NoiseDependsOnSeedOnly) {
  // Same radiance, different noise keys: different images with the configured spread.
  std::vector<float> radiance(752 * 480, 0.4f);
  cv::Mat a, b, c;
  FormImage(radiance, 752, 480, 1.0, 3.0, 11, &a);
  FormImage(radiance, 752, 480, 1.0, 3.0, 11, &b);
  FormImage(radiance, 752, 480, 1.0, 3.0, 12, &c);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0);
  cv::Scalar mu, sigma;
  cv::meanStdDev(a, mu, sigma);
  EXPECT_NEAR(mu[0], 0.4 * 255, 0.1);
  EXPECT_NEAR(sigma[0], std::sqrt(9.0 + 1.0 / 12), 0.1);  // noise + quantisation
}

// A small cluttered scene: walls and floor (boxes), a tilted box, cylinders (upright and
// tilted) and a decal, all textured.
std::shared_ptr<World> MakeClutterWorld() {
  auto world = std::make_shared<World>();
  Material noise;
  noise.pattern = TexturePattern::kSpeckle;
  const int m = world->AddMaterial(noise);
  Material bricks;
  bricks.pattern = TexturePattern::kBricks;
  const int b = world->AddMaterial(bricks);
  Material blobs;
  blobs.pattern = TexturePattern::kBlobs;
  const int p = world->AddMaterial(blobs);
  world->AddAlignedBox(Eigen::Vector3d(-5, -5, 4), Eigen::Vector3d(5, 5, 4.2), m);    // ahead
  world->AddAlignedBox(Eigen::Vector3d(-5, 1.0, -5), Eigen::Vector3d(5, 1.2, 5), b);  // floor
  world->AddBox(
      Eigen::Vector3d(-0.8, 0.3, 2.5),
      Eigen::AngleAxisd(0.6, Eigen::Vector3d(0.2, 1, 0.3).normalized()).toRotationMatrix(),
      Eigen::Vector3d(0.3, 0.4, 0.2), p);
  world->AddCylinder(Eigen::Vector3d(0.7, 1.0, 2.0), Eigen::Vector3d(0.7, -1.0, 2.0), 0.15, m);
  world->AddCylinder(Eigen::Vector3d(-1.5, 0.8, 3.0), Eigen::Vector3d(1.5, -0.2, 3.5), 0.04, b);
  world->AddRectangle(Eigen::Vector3d(0.2, -0.5, 3.99),
                      Eigen::Vector3d(1, -1, -1).asDiagonal() * Eigen::Matrix3d::Identity(),
                      Eigen::Vector2d(0.4, 0.3), p);
  world->BuildTextures(4);
  return world;
}

TEST(RenderTest, RangeMatchesExactRayCasting) {
  // The renderer's culled, vectorised float intersections against World::CastRay (double
  // precision, every primitive): the same nearest surface and distance for (almost) every pixel.
  std::shared_ptr<World> world = MakeClutterWorld();
  const camera::PinholeRadTan cam = camera::EurocCam0();
  CameraRenderer renderer(world, cam);
  const geometry::SE3 T_world_cam(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.15, Eigen::Vector3d(0.3, 1, 0.1).normalized())),
      Eigen::Vector3d(0.05, 0.1, -0.2));
  std::vector<float> radiance, range;
  renderer.RenderRadiance(T_world_cam, &radiance, &range);
  int checked = 0, bad = 0;
  for (int v = 0; v < cam.height; v += 3) {
    for (int u = 0; u < cam.width; u += 3) {
      const std::optional<Eigen::Vector3d> ray = cam.Unproject(Eigen::Vector2d(u, v));
      ASSERT_TRUE(ray.has_value());
      const Eigen::Vector3d dir = T_world_cam.Rotation() * ray->normalized();
      const std::optional<RayHit> hit = world->CastRay(T_world_cam.Translation(), dir);
      const float r = range[static_cast<size_t>(v) * cam.width + u];
      ++checked;
      if (!hit) {
        bad += std::isinf(r) ? 0 : 1;
      } else if (!(std::abs(r - hit->t) < 1e-3 * hit->t + 1e-4)) {
        ++bad;  // only where float and double disagree about an edge
      }
    }
  }
  EXPECT_GT(checked, 30000);
  EXPECT_LT(bad, 0.001 * checked) << bad << " of " << checked;
}

TEST(RenderTest, ReprojectionBlurApproximatesSubFrameIntegration) {
  // A fast rotation (about 12 px of image motion over the shutter) of a static scene: the
  // reprojection blur of one render matches the mean of 24 sub-frame renders closely, except
  // at occlusion boundaries; it is much closer to it than the sharp image is.
  std::shared_ptr<World> world = MakeClutterWorld();
  CameraRenderer renderer(world, camera::EurocCam0());
  auto pose = [](double s) {
    const Eigen::Quaterniond q(
        Eigen::AngleAxisd(0.1 + 0.026 * s, Eigen::Vector3d(0.3, 1, 0.1).normalized()));
    return geometry::SE3(q, Eigen::Vector3d(0.05 + 0.01 * s, 0.1, -0.2));
  };
  std::vector<float> sharp, range, blurred, exact;
  renderer.RenderRadiance(pose(0), &sharp, &range);
  renderer.BlurByReprojection(sharp, range, pose(0), pose(-0.5), pose(0.5), 16, &blurred);
  std::vector<geometry::SE3> poses;
  poses.reserve(24);
  for (int k = 0; k < 24; ++k) poses.push_back(pose((k + 0.5) / 24 - 0.5));
  renderer.RenderIntegrated(poses, &exact);
  double err_blur = 0, err_sharp = 0;
  std::vector<float> abs_err(exact.size());
  for (size_t i = 0; i < exact.size(); ++i) {
    abs_err[i] = std::abs(blurred[i] - exact[i]);
    err_blur += abs_err[i];
    err_sharp += std::abs(sharp[i] - exact[i]);
  }
  err_blur /= exact.size();
  err_sharp /= exact.size();
  const size_t p95_index = abs_err.size() * 95 / 100;
  std::nth_element(abs_err.begin(), abs_err.begin() + static_cast<std::ptrdiff_t>(p95_index),
                   abs_err.end());
  const float p95 = abs_err[p95_index];
  std::printf("mean |blur - exact| %.4f, |sharp - exact| %.4f, p95 %.4f\n", err_blur, err_sharp,
              p95);
  EXPECT_LT(err_blur, 0.25 * err_sharp);
  EXPECT_LT(p95, 0.02f);  // 5 DN at gain 1
}

TEST(RenderTest, WideKernelsGiveTheFourLaneBits) {
  // The AVX2 (8 lanes) and AVX-512 (16) kernels against the SSE2 ones (4 lanes): the same bits
  // for the radiance, the range, the blur and the 8-bit image, over motions from still to fast
  // enough that the blur's segments leave the image (the clamped path, and wide groups that
  // split into groups of 4), on the EuRoC camera and on one whose width is not a multiple of 16
  // (the row tails).
  std::shared_ptr<World> world = MakeClutterWorld();
  camera::PinholeRadTan odd = camera::EurocCam0();
  odd.width = 749;
  odd.height = 477;
  CameraRenderer probe(world, odd);
  if (probe.simd_lanes() == 4) GTEST_SKIP() << "this CPU has neither AVX2 nor AVX-512";
  for (const int lanes : {8, 16}) {
    for (const camera::PinholeRadTan& cam : {camera::EurocCam0(), odd}) {
      CameraRenderer wide(world, cam), narrow(world, cam);
      wide.SetSimdLanes(lanes);
      if (wide.simd_lanes() != lanes) continue;  // no AVX-512 here
      narrow.SetSimdLanes(4);
      ASSERT_EQ(narrow.simd_lanes(), 4);
      for (const double speed : {0.0, 0.3, 1.0, 4.0}) {
        SCOPED_TRACE(testing::Message()
                     << lanes << " lanes, width " << cam.width << ", speed " << speed);
        auto pose = [&](double s) {
          const Eigen::Quaterniond q(Eigen::AngleAxisd(
              0.1 + 0.026 * speed * s, Eigen::Vector3d(0.3, 1, 0.1 + 0.2 * speed).normalized()));
          return geometry::SE3(q, Eigen::Vector3d(0.05 + 0.05 * speed * s, 0.1, -0.2));
        };
        std::vector<float> sharp_w, range_w, sharp_n, range_n, blur_w, blur_n;
        wide.RenderRadiance(pose(0), &sharp_w, &range_w);
        narrow.RenderRadiance(pose(0), &sharp_n, &range_n);
        const size_t bytes = sharp_w.size() * sizeof(float);
        EXPECT_EQ(std::memcmp(sharp_w.data(), sharp_n.data(), bytes), 0) << "radiance";
        EXPECT_EQ(std::memcmp(range_w.data(), range_n.data(), bytes), 0) << "range";
        wide.BlurByReprojection(sharp_n, range_n, pose(0), pose(-0.5), pose(0.5), 16, &blur_w);
        narrow.BlurByReprojection(sharp_n, range_n, pose(0), pose(-0.5), pose(0.5), 16, &blur_n);
        EXPECT_EQ(std::memcmp(blur_w.data(), blur_n.data(), bytes), 0) << "blur";
        cv::Mat image_w, image_n;
        FormImage(blur_n, cam.width, cam.height, 1.1, 2.0, 5, &image_w, lanes);
        FormImage(blur_n, cam.width, cam.height, 1.1, 2.0, 5, &image_n, 4);
        EXPECT_EQ(cv::norm(image_w, image_n, cv::NORM_INF), 0) << "image";
      }
    }
  }
}

TEST(RenderTest, UnknownPresetIsInvalidArgumentNamingPreset) {
  ScenarioOptions o;
  o.preset = "rom-easy";
  Result<Scenario> s = Scenario::Create(o);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.status().message().find("preset"), std::string::npos);
  EXPECT_NE(s.status().message().find("rom-easy"), std::string::npos);
  EXPECT_NE(s.status().message().find("room-hard"), std::string::npos);
}

TEST(RenderTest, BadFrameCountIsInvalidArgumentNamingFrames) {
  for (int64_t frames : {int64_t{-1}, int64_t{1} << 40}) {
    ScenarioOptions o;
    o.frames = frames;
    Result<Scenario> s = Scenario::Create(o);
    ASSERT_FALSE(s.ok());
    EXPECT_EQ(s.status().code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(s.status().message().rfind("frames:", 0), 0u) << s.status().message();
  }
}

}  // namespace
}  // namespace mav::sim
