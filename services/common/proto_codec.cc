#include "services/common/proto_codec.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <tuple>
#include <utility>
#include <vector>

namespace mav::service_common {

std::string Number(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

namespace {

Status NotFinite(const std::string& field) {
  return Status::InvalidArgument(field + ": not finite");
}

// Exactly 6 finite coefficients (a quintic, ascending powers).
Status Coefficients(const google::protobuf::RepeatedField<double>& c, const std::string& field,
                    geometry::Vector6d* out) {
  if (c.size() != 6) {
    return Status::InvalidArgument(field + ": " + std::to_string(c.size()) +
                                   " coefficients, expected 6 (a quintic, ascending powers)");
  }
  for (int k = 0; k < 6; ++k) {
    if (!std::isfinite(c[k])) return NotFinite(field + "[" + std::to_string(k) + "]");
    (*out)[k] = c[k];
  }
  return Status::Ok();
}

Result<geometry::PolynomialSegment> SegmentFromProto(const v1::PolynomialSegment& in,
                                                     geometry::YawPolicy policy,
                                                     const std::string& field) {
  geometry::PolynomialSegment out;
  if (!std::isfinite(in.duration_s()) || in.duration_s() <= 0) {
    return Status::InvalidArgument(field + ".duration_s: must be > 0 and finite, got " +
                                   Number(in.duration_s()));
  }
  out.duration_s = in.duration_s();
  const std::pair<const google::protobuf::RepeatedField<double>*, const char*> axes[] = {
      {&in.x(), ".x"}, {&in.y(), ".y"}, {&in.z(), ".z"}};
  for (int a = 0; a < 3; ++a) {
    geometry::Vector6d c;
    MAV_RETURN_IF_ERROR(Coefficients(*axes[a].first, field + axes[a].second, &c));
    out.coefficients.row(a) = c.transpose();
  }
  if (in.yaw_size() != 0) {
    geometry::Vector6d c;
    MAV_RETURN_IF_ERROR(Coefficients(in.yaw(), field + ".yaw", &c));
    out.yaw = c;
  } else if (policy == geometry::YawPolicy::kSegment) {
    return Status::InvalidArgument(field + ".yaw: YAW_POLICY_SEGMENT needs 6 yaw coefficients");
  }
  return out;
}

}  // namespace

Result<Eigen::Vector3d> VectorFromProto(const v1::Vector3& v, const std::string& field) {
  if (!std::isfinite(v.x())) return NotFinite(field + ".x");
  if (!std::isfinite(v.y())) return NotFinite(field + ".y");
  if (!std::isfinite(v.z())) return NotFinite(field + ".z");
  return Eigen::Vector3d(v.x(), v.y(), v.z());
}

void ToProto(const Eigen::Vector3d& v, v1::Vector3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

Result<Eigen::AlignedBox3d> BoxFromProto(const v1::Box& box, const std::string& field) {
  MAV_ASSIGN_OR_RETURN(const Eigen::Vector3d min, VectorFromProto(box.min(), field + ".min"));
  MAV_ASSIGN_OR_RETURN(const Eigen::Vector3d max, VectorFromProto(box.max(), field + ".max"));
  for (int i = 0; i < 3; ++i) {
    if (min[i] > max[i]) {
      const std::string axis(1, "xyz"[i]);
      return Status::InvalidArgument(field + ": min." + axis + " " + Number(min[i]) + " > max." +
                                     axis + " " + Number(max[i]));
    }
  }
  return Eigen::AlignedBox3d(min, max);
}

void ToProto(const Eigen::AlignedBox3d& box, v1::Box* out) {
  ToProto(Eigen::Vector3d(box.min()), out->mutable_min());
  ToProto(Eigen::Vector3d(box.max()), out->mutable_max());
}

Result<geometry::PolynomialTrajectory> TrajectoryFromProto(const v1::PolynomialTrajectory& proto,
                                                           const std::string& field) {
  if (proto.segments_size() == 0) return Status::InvalidArgument(field + ".segments: no segments");
  if (proto.segments_size() > kMaxTrajectorySegments) {
    return Status::InvalidArgument(field + ".segments: " + std::to_string(proto.segments_size()) +
                                   " segments, at most " + std::to_string(kMaxTrajectorySegments));
  }
  MAV_ASSIGN_OR_RETURN(const geometry::YawPolicy policy,
                       kYawPolicyCodec.FromProto(proto.yaw_policy(), field + ".yaw_policy"));
  if (!std::isfinite(proto.start_yaw_rad())) return NotFinite(field + ".start_yaw_rad");
  std::vector<geometry::PolynomialSegment> segments;
  segments.reserve(static_cast<size_t>(proto.segments_size()));
  double total_s = 0;
  for (int i = 0; i < proto.segments_size(); ++i) {
    MAV_ASSIGN_OR_RETURN(geometry::PolynomialSegment segment,
                         SegmentFromProto(proto.segments(i), policy,
                                          field + ".segments[" + std::to_string(i) + "]"));
    total_s += segment.duration_s;
    segments.push_back(std::move(segment));
  }
  if (proto.duration_s() != 0 &&
      !(std::abs(proto.duration_s() - total_s) <= 1e-6 * std::max(1.0, total_s))) {
    return Status::InvalidArgument(field + ".duration_s: " + Number(proto.duration_s()) +
                                   " s is not the sum of the segment durations, " +
                                   Number(total_s) + " s");
  }
  // Everything the library refuses was refused above; its messages name "segments[i]..." on.
  Result<geometry::PolynomialTrajectory> trajectory =
      geometry::PolynomialTrajectory::Create(std::move(segments), policy, proto.start_yaw_rad());
  if (!trajectory.ok()) return Status::InvalidArgument(field + "." + trajectory.status().message());
  return trajectory;
}

void ToProto(const geometry::PolynomialTrajectory& trajectory, v1::PolynomialTrajectory* out) {
  for (const geometry::PolynomialSegment& s : trajectory.segments()) {
    v1::PolynomialSegment* segment = out->add_segments();
    segment->set_duration_s(s.duration_s);
    for (int k = 0; k < 6; ++k) {
      segment->add_x(s.coefficients(0, k));
      segment->add_y(s.coefficients(1, k));
      segment->add_z(s.coefficients(2, k));
      if (s.yaw.has_value()) segment->add_yaw((*s.yaw)[k]);
    }
  }
  out->set_yaw_policy(kYawPolicyCodec.ToProto(trajectory.yaw_policy()));
  out->set_start_yaw_rad(trajectory.start_yaw_rad());
  out->set_duration_s(trajectory.duration_s());
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
