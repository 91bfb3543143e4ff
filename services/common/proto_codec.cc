#include "services/common/proto_codec.h"

namespace mav::services {

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

}  // namespace mav::services
