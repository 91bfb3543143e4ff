#include "services/common/proto_codec.h"

#include <cmath>
#include <cstring>
#include <sstream>
#include <tuple>

namespace mav::service_common {

std::string Number(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

void ToProto(const RuntimeStats& stats, v1::RuntimeStats* out) {
  out->set_count(stats.count);
  out->set_mean_ms(stats.mean_ms);
  out->set_median_ms(stats.median_ms);
  out->set_p95_ms(stats.p95_ms);
  out->set_p99_ms(stats.p99_ms);
  out->set_max_ms(stats.max_ms);
}

void ToProto(const geometry::SE3& pose, v1::Pose* out) {
  const Eigen::Vector3d& t = pose.Translation();
  out->mutable_position()->set_x(t.x());
  out->mutable_position()->set_y(t.y());
  out->mutable_position()->set_z(t.z());
  const Eigen::Quaterniond& q = pose.Rotation();
  out->mutable_orientation()->set_w(q.w());
  out->mutable_orientation()->set_x(q.x());
  out->mutable_orientation()->set_y(q.y());
  out->mutable_orientation()->set_z(q.z());
}

void ToProto(const camera::PinholeRadTan& camera, v1::CameraIntrinsics* out) {
  out->set_width(static_cast<uint32_t>(camera.width));
  out->set_height(static_cast<uint32_t>(camera.height));
  out->set_fx(camera.fx);
  out->set_fy(camera.fy);
  out->set_cx(camera.cx);
  out->set_cy(camera.cy);
  out->set_k1(camera.k1);
  out->set_k2(camera.k2);
  out->set_p1(camera.p1);
  out->set_p2(camera.p2);
}

Result<geometry::SE3> PoseFromProto(const v1::Pose& pose, const std::string& field) {
  const v1::Vector3& p = pose.position();
  if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z())) {
    return Status::InvalidArgument(field + ".position: not finite");
  }
  const v1::Quaternion& q = pose.orientation();
  const double norm = std::sqrt(q.w() * q.w() + q.x() * q.x() + q.y() * q.y() + q.z() * q.z());
  if (!std::isfinite(norm) || std::abs(norm - 1.0) > 1e-3) {
    return Status::InvalidArgument(field + ".orientation: norm " + Number(norm) +
                                   ", expected a unit quaternion (w first)");
  }
  // SE3 normalizes a quaternion only when it is not unit to rounding: a unit one passes bit for
  // bit (a pose through the services is the pose sent).
  return geometry::SE3(Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z()),
                       Eigen::Vector3d(p.x(), p.y(), p.z()));
}

Result<camera::PinholeRadTan> CameraFromProto(const v1::CameraCalibration& camera,
                                              const std::string& field) {
  if (!camera.has_intrinsics()) return Status::InvalidArgument(field + ".intrinsics: not set");
  const v1::CameraIntrinsics& k = camera.intrinsics();
  camera::PinholeRadTan out;
  out.width = static_cast<int>(k.width());
  out.height = static_cast<int>(k.height());
  out.fx = k.fx();
  out.fy = k.fy();
  out.cx = k.cx();
  out.cy = k.cy();
  out.k1 = k.k1();
  out.k2 = k.k2();
  out.p1 = k.p1();
  out.p2 = k.p2();
  if (k.width() == 0 || k.height() == 0 || k.width() > 65536 || k.height() > 65536) {
    return Status::InvalidArgument(field + ".intrinsics.width: image size " +
                                   std::to_string(k.width()) + "x" + std::to_string(k.height()) +
                                   " is not in [1, 65536]");
  }
  if (!(k.fx() > 0) || !(k.fy() > 0) || !std::isfinite(k.fx()) || !std::isfinite(k.fy())) {
    return Status::InvalidArgument(field +
                                   ".intrinsics.fx: focal lengths must be > 0 and finite, "
                                   "got fx=" +
                                   Number(k.fx()) + " fy=" + Number(k.fy()));
  }
  std::string why;
  if (!out.IsValid(&why)) return Status::InvalidArgument(field + ".intrinsics: " + why);
  return out;
}

Result<RigCalibration> CalibrationFromProto(const v1::StereoCalibration& proto,
                                            const std::string& field) {
  if (!proto.has_left()) return Status::InvalidArgument(field + ".left: not set");
  if (!proto.has_right()) return Status::InvalidArgument(field + ".right: not set");
  RigCalibration out;
  out.rectified = proto.rectified();
  MAV_ASSIGN_OR_RETURN(out.calibration.cam0, CameraFromProto(proto.left(), field + ".left"));
  MAV_ASSIGN_OR_RETURN(out.calibration.cam1, CameraFromProto(proto.right(), field + ".right"));
  if (!proto.left().has_t_body_cam()) {
    return Status::InvalidArgument(field + ".left.t_body_cam: not set");
  }
  if (!proto.right().has_t_body_cam()) {
    return Status::InvalidArgument(field + ".right.t_body_cam: not set");
  }
  MAV_ASSIGN_OR_RETURN(out.calibration.T_body_cam0,
                       PoseFromProto(proto.left().t_body_cam(), field + ".left.t_body_cam"));
  MAV_ASSIGN_OR_RETURN(out.calibration.T_body_cam1,
                       PoseFromProto(proto.right().t_body_cam(), field + ".right.t_body_cam"));
  if (out.calibration.cam0.width != out.calibration.cam1.width ||
      out.calibration.cam0.height != out.calibration.cam1.height) {
    return Status::InvalidArgument(field +
                                   ".right.intrinsics.width: the right image size differs "
                                   "from the left one");
  }
  if (out.rectified &&
      (out.calibration.cam0.HasDistortion() || out.calibration.cam1.HasDistortion())) {
    return Status::InvalidArgument(field + ".rectified: true but the cameras have distortion");
  }
  std::string why;
  if (!out.calibration.IsValid(&why)) return Status::InvalidArgument(field + ": " + why);
  return out;
}

Result<dataset::StereoPair> StereoFromProto(const v1::StereoPair& pair, const std::string& field) {
  dataset::StereoPair out;
  out.t_ns = pair.t_ns();
  out.rectified = pair.rectified();
  for (const auto& [name, image, mat] :
       {std::tuple<const char*, const v1::Image*, cv::Mat*>{"left", &pair.left(), &out.left},
        std::tuple<const char*, const v1::Image*, cv::Mat*>{"right", &pair.right(), &out.right}}) {
    const std::string f = field + "." + name;
    if (image->width() == 0 || image->height() == 0) {
      return Status::InvalidArgument(f + ": empty image (" + std::to_string(image->width()) + "x" +
                                     std::to_string(image->height()) + ")");
    }
    if (image->width() > 65536 || image->height() > 65536) {
      return Status::InvalidArgument(f + ": " + std::to_string(image->width()) + "x" +
                                     std::to_string(image->height()) + " is too large");
    }
    if (image->encoding() != v1::IMAGE_ENCODING_MONO8) {
      return Status::InvalidArgument(f + ".encoding: must be IMAGE_ENCODING_MONO8, got " +
                                     std::to_string(static_cast<int>(image->encoding())));
    }
    const uint64_t expected = static_cast<uint64_t>(image->width()) * image->height();
    if (image->data().size() != expected) {
      return Status::InvalidArgument(f + ".data: " + std::to_string(image->data().size()) +
                                     " bytes, expected width*height = " + std::to_string(expected));
    }
    *mat = cv::Mat(static_cast<int>(image->height()), static_cast<int>(image->width()), CV_8UC1);
    std::memcpy(mat->data, image->data().data(), expected);
  }
  if (out.left.size() != out.right.size()) {
    return Status::InvalidArgument(field + ".right: " + std::to_string(out.right.cols) + "x" +
                                   std::to_string(out.right.rows) + ", differs from the left " +
                                   std::to_string(out.left.cols) + "x" +
                                   std::to_string(out.left.rows));
  }
  return out;
}

}  // namespace mav::service_common
