#include "services/common/proto_codec.h"

#include <cmath>
#include <sstream>

namespace mav::services {
namespace {

std::string Number(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

}  // namespace

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
  const Eigen::Quaterniond rotation(q.w() / norm, q.x() / norm, q.y() / norm, q.z() / norm);
  return geometry::SE3(rotation, Eigen::Vector3d(p.x(), p.y(), p.z()));
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

}  // namespace mav::services
