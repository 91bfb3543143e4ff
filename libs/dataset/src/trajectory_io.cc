#include "mav/dataset/trajectory_io.h"

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "mav/common/file.h"
#include "mav/common/parse.h"
#include "mav/common/time.h"
#include "text.h"

namespace mav::dataset {
namespace {

const std::vector<std::string>& TumColumns() {
  static const std::vector<std::string> kColumns = {"timestamp", "tx", "ty", "tz",
                                                    "qx",        "qy", "qz", "qw"};
  return kColumns;
}

const std::vector<std::string>& KittiColumns() {
  static const std::vector<std::string> kColumns = {"r00", "r01", "r02", "tx",  "r10", "r11",
                                                    "r12", "ty",  "r20", "r21", "r22", "tz"};
  return kColumns;
}

// "<seconds>.<nine digits>" from integer nanoseconds, so no rounding can happen.
std::string FormatSeconds(int64_t t_ns) {
  const bool negative = t_ns < 0;
  // Work in unsigned to survive INT64_MIN.
  const uint64_t magnitude =
      negative ? 0 - static_cast<uint64_t>(t_ns) : static_cast<uint64_t>(t_ns);
  char buffer[48];
  std::snprintf(buffer, sizeof(buffer), "%s%llu.%09llu", negative ? "-" : "",
                static_cast<unsigned long long>(magnitude / 1'000'000'000ULL),
                static_cast<unsigned long long>(magnitude % 1'000'000'000ULL));
  return buffer;
}

// Exact for "[-]digits[.digits]" with up to nine decimals; other forms (exponents, more decimals)
// go through a double and are rounded to the nearest nanosecond.
Result<int64_t> ParseSeconds(std::string_view text, const std::string& what) {
  std::string_view s = Trim(text);
  bool negative = false;
  std::string_view digits = s;
  if (!digits.empty() && (digits.front() == '-' || digits.front() == '+')) {
    negative = digits.front() == '-';
    digits.remove_prefix(1);
  }
  const size_t dot = digits.find('.');
  const std::string_view whole = digits.substr(0, dot);
  const std::string_view frac =
      dot == std::string_view::npos ? std::string_view() : digits.substr(dot + 1);
  const auto all_digits = [](std::string_view v) {
    for (char c : v) {
      if (c < '0' || c > '9') return false;
    }
    return true;
  };
  if (!whole.empty() && whole.size() <= 10 && frac.size() <= 9 && all_digits(whole) &&
      all_digits(frac)) {
    int64_t ns = std::stoll(std::string(whole)) * kNsPerSecond;
    if (!frac.empty()) {
      std::string padded(frac);
      padded.append(9 - padded.size(), '0');
      ns += std::stoll(padded);
    }
    return negative ? -ns : ns;
  }
  MAV_ASSIGN_OR_RETURN(const double seconds, ParseDouble(s, what));
  if (!(std::abs(seconds) < 9.2e9)) {
    return Status::InvalidArgument(what + ": " + std::string(s) + " s is out of range");
  }
  return SecondsToNs(seconds);
}

Status WriteText(const std::string& path, const std::string& text) {
  return WriteStringToFileAtomic(path, text);
}

}  // namespace

Status WriteTumTrajectory(const std::string& path, const std::vector<StampedPose>& poses) {
  std::string out = "# timestamp tx ty tz qx qy qz qw\n";
  for (const StampedPose& pose : poses) {
    const Eigen::Vector3d& t = pose.T_world_body.Translation();
    const Eigen::Quaterniond& q = pose.T_world_body.Rotation();
    out += FormatSeconds(pose.t_ns);
    for (double v : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) {
      out += ' ';
      internal::AppendDouble(&out, v);
    }
    out += '\n';
  }
  return WriteText(path, out);
}

Result<std::vector<StampedPose>> ReadTumTrajectory(const std::string& path) {
  std::vector<StampedPose> poses;
  const std::vector<std::string>& columns = TumColumns();
  int64_t previous = 0;
  bool first = true;
  MAV_RETURN_IF_ERROR(internal::ForEachRow(
      path, ' ', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        StampedPose pose;
        MAV_ASSIGN_OR_RETURN(pose.t_ns,
                             ParseSeconds(f[0], internal::Where(path, line, columns[0])));
        MAV_RETURN_IF_ERROR(internal::CheckIncreasing(pose.t_ns, &previous, &first, path, line));
        double v[7];
        for (int i = 0; i < 7; ++i) {
          MAV_ASSIGN_OR_RETURN(v[i],
                               internal::ParseColumnDouble(f[1 + i], path, line, columns[1 + i]));
        }
        const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
        if (!(q.norm() > 1e-6)) {
          return Status::InvalidArgument(internal::Where(path, line, "qw") +
                                         ": quaternion has zero norm");
        }
        pose.T_world_body = geometry::SE3(q, Eigen::Vector3d(v[0], v[1], v[2]));
        poses.push_back(pose);
        return Status::Ok();
      }));
  return poses;
}

Status WriteKittiMatrices(const std::string& path, const std::vector<KittiMatrix>& matrices) {
  std::string out;
  for (const KittiMatrix& m : matrices) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        if (r > 0 || c > 0) out += ' ';
        internal::AppendDouble(&out, m(r, c));
      }
    }
    out += '\n';
  }
  return WriteText(path, out);
}

Result<std::vector<KittiMatrix>> ReadKittiMatrices(const std::string& path) {
  std::vector<KittiMatrix> matrices;
  const std::vector<std::string>& columns = KittiColumns();
  MAV_RETURN_IF_ERROR(internal::ForEachRow(
      path, ' ', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        KittiMatrix m;
        for (int i = 0; i < 12; ++i) {
          MAV_ASSIGN_OR_RETURN(m(i / 4, i % 4),
                               internal::ParseColumnDouble(f[i], path, line, columns[i]));
        }
        matrices.push_back(m);
        return Status::Ok();
      }));
  return matrices;
}

Status WriteKittiTrajectory(const std::string& path, const std::vector<geometry::SE3>& poses) {
  std::vector<KittiMatrix> matrices;
  matrices.reserve(poses.size());
  for (const geometry::SE3& pose : poses) matrices.push_back(pose.Matrix3x4());
  return WriteKittiMatrices(path, matrices);
}

Result<std::vector<geometry::SE3>> ReadKittiTrajectory(const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const std::vector<KittiMatrix> matrices, ReadKittiMatrices(path));
  std::vector<geometry::SE3> poses;
  poses.reserve(matrices.size());
  for (size_t i = 0; i < matrices.size(); ++i) {
    const Eigen::Matrix3d r = matrices[i].leftCols<3>();
    const double orthogonality = (r * r.transpose() - Eigen::Matrix3d::Identity()).norm();
    if (!(orthogonality < 1e-6) || !(r.determinant() > 0)) {
      return Status::InvalidArgument(path + ":" + std::to_string(i + 1) +
                                     ": rotation block is not a rotation (|R R^T - I| = " +
                                     internal::FormatDouble(orthogonality) + ")");
    }
    poses.emplace_back(r, Eigen::Vector3d(matrices[i].col(3)));
  }
  return poses;
}

}  // namespace mav::dataset
