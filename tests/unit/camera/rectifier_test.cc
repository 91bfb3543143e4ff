#include "mav/camera/rectifier.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

namespace mav::camera {
namespace {

// Draws a smooth Gaussian spot centred at `uv` (sub-pixel) into an 8-bit image.
cv::Mat SpotImage(const PinholeRadTan& cam, const Eigen::Vector2d& uv) {
  cv::Mat img(cam.height, cam.width, CV_8UC1, cv::Scalar(0));
  const double sigma = 2.0;
  for (int v = 0; v < cam.height; ++v) {
    for (int u = 0; u < cam.width; ++u) {
      const double d2 = (u - uv.x()) * (u - uv.x()) + (v - uv.y()) * (v - uv.y());
      if (d2 > 100) continue;
      img.at<uint8_t>(v, u) =
          cv::saturate_cast<uint8_t>(250.0 * std::exp(-d2 / (2 * sigma * sigma)));
    }
  }
  return img;
}

Eigen::Vector2d Centroid(const cv::Mat& img) {
  const cv::Moments m = cv::moments(img);
  return {m.m10 / m.m00, m.m01 / m.m00};
}

TEST(StereoRectifierTest, RectifiedPairIsRowAlignedWithEurocBaseline) {
  const StereoCalibration calib = EurocStereoCalibration();
  const auto rectifier = StereoRectifier::Create(calib);
  ASSERT_TRUE(rectifier.ok()) << rectifier.status().ToString();
  const RectifiedStereo& rect = rectifier->rectified();
  EXPECT_NEAR(rect.baseline, calib.Baseline(), 1e-9);
  EXPECT_GT(rect.fx, 300);

  // A 3D point seen by both raw cameras must land on the same rectified row, with the
  // disparity fx * b / Z of its depth in the rectified frame.
  const Eigen::Vector3d p_cam0(0.3, -0.2, 2.0);
  const Eigen::Vector3d p_cam1 = calib.T_cam0_cam1().Inverse() * p_cam0;
  const Eigen::Vector3d p_rect0 = rectifier->R_rect0_cam0() * p_cam0;
  const Eigen::Vector3d p_rect1 = rectifier->R_rect1_cam1() * p_cam1;
  const Eigen::Vector2d l = *rect.ProjectLeft(p_rect0);
  const Eigen::Vector2d r = *rect.ProjectLeft(p_rect1);
  EXPECT_NEAR(l.y(), r.y(), 1e-6);
  EXPECT_NEAR(l.x() - r.x(), rect.DisparityFromDepth(p_rect0.z()), 1e-6);
  EXPECT_NEAR((*rect.ProjectRight(p_rect0) - r).norm(), 0.0, 1e-6);
}

TEST(StereoRectifierTest, RemappedImagesPutTheSpotWhereTheModelSays) {
  const StereoCalibration calib = EurocStereoCalibration();
  const auto rectifier = StereoRectifier::Create(calib);
  ASSERT_TRUE(rectifier.ok());
  const Eigen::Vector3d p_cam0(-0.4, 0.25, 3.0);
  const Eigen::Vector3d p_cam1 = calib.T_cam0_cam1().Inverse() * p_cam0;
  const cv::Mat raw_left = SpotImage(calib.cam0, *calib.cam0.Project(p_cam0));
  const cv::Mat raw_right = SpotImage(calib.cam1, *calib.cam1.Project(p_cam1));
  cv::Mat rect_left, rect_right;
  ASSERT_TRUE(rectifier->Rectify(raw_left, raw_right, &rect_left, &rect_right).ok());
  const RectifiedStereo& rect = rectifier->rectified();
  const Eigen::Vector2d expected_l = *rect.ProjectLeft(rectifier->R_rect0_cam0() * p_cam0);
  const Eigen::Vector2d expected_r = *rect.ProjectLeft(rectifier->R_rect1_cam1() * p_cam1);
  // The spot is slightly warped by the remap, so its centroid is good to ~0.1 px.
  EXPECT_LT((Centroid(rect_left) - expected_l).norm(), 0.15);
  EXPECT_LT((Centroid(rect_right) - expected_r).norm(), 0.15);
}

TEST(StereoRectifierTest, BadInputIsRejectedWithTheFieldNamed) {
  StereoCalibration calib = EurocStereoCalibration();
  calib.cam1.fy = 0;
  auto bad = StereoRectifier::Create(calib);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("cam1"), std::string::npos);

  StereoRectifier::Options options;
  options.alpha = 2.0;
  bad = StereoRectifier::Create(EurocStereoCalibration(), options);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("alpha"), std::string::npos);

  const auto rectifier = StereoRectifier::Create(EurocStereoCalibration());
  ASSERT_TRUE(rectifier.ok());
  cv::Mat small(100, 100, CV_8UC1, cv::Scalar(0)), out_l, out_r;
  const Status s = rectifier->Rectify(small, small, &out_l, &out_r);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("100x100"), std::string::npos);
  EXPECT_EQ(rectifier->Rectify(cv::Mat(), cv::Mat(), &out_l, &out_r).code(),
            StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mav::camera
