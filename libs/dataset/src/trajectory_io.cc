#include "mav/dataset/trajectory_io.h"

#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "mav/common/file.h"
#include "mav/common/parse.h"
#include "mav/common/text.h"
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
    const int64_t seconds = std::stoll(std::string(whole));
    // Ten digits reach 9999999999 s; int64 nanoseconds end at 9223372036.85 s.
    if (seconds > std::numeric_limits<int64_t>::max() / kNsPerSecond - 1) {
      return Status::InvalidArgument(what + ": " + QuoteForError(s) +
                                     " s is out of range (int64 nanoseconds end at 9.2e9 s)");
    }
    int64_t ns = seconds * kNsPerSecond;
    if (!frac.empty()) {
      std::string padded(frac);
      padded.append(9 - padded.size(), '0');
      ns += std::stoll(padded);
    }
    return negative ? -ns : ns;
  }
  MAV_ASSIGN_OR_RETURN(const double seconds, ParseDouble(s, what));
  if (!(std::abs(seconds) < 9.2e9)) {
    return Status::InvalidArgument(what + ": " + QuoteForError(s) +
                                   " s is out of range (int64 nanoseconds end at 9.2e9 s)");
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

Result<std::vector<StampedPose>> ReadTumTrajectory(const std::string& path,
                                                   const ReadOptions& options) {
  MAV_ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path));
  return ParseTumTrajectory(text, path, options);
}

Result<std::vector<StampedPose>> ParseTumTrajectory(std::string_view text, const std::string& name,
                                                    const ReadOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("options: " + why);
  std::vector<StampedPose> poses;
  const std::vector<std::string>& columns = TumColumns();
  internal::StampSequence stamps(name, options);
  MAV_RETURN_IF_ERROR(internal::ForEachRow(
      text, name, ' ', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        StampedPose pose;
        MAV_ASSIGN_OR_RETURN(pose.t_ns,
                             ParseSeconds(f[0], internal::Where(name, line, columns[0])));
        bool keep = true;
        MAV_RETURN_IF_ERROR(stamps.Next(pose.t_ns, line, &keep));
        double v[7];
        for (int i = 0; i < 7; ++i) {
          MAV_ASSIGN_OR_RETURN(v[i],
                               internal::ParseColumnDouble(f[1 + i], name, line, columns[1 + i]));
        }
        const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
        if (!(q.norm() > 1e-6)) {
          return Status::InvalidArgument(internal::Where(name, line, "qw") +
                                         ": quaternion has zero norm");
        }
        pose.T_world_body = geometry::SE3(q, Eigen::Vector3d(v[0], v[1], v[2]));
        if (keep) poses.push_back(pose);
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

namespace {

// The matrices and the line each came from (comments and blank lines are skipped).
Status ParseKittiRows(std::string_view text, const std::string& name,
                      std::vector<KittiMatrix>* matrices, std::vector<int>* lines) {
  const std::vector<std::string>& columns = KittiColumns();
  return internal::ForEachRow(
      text, name, ' ', columns, [&](int line, const std::vector<std::string_view>& f) -> Status {
        KittiMatrix m;
        for (int i = 0; i < 12; ++i) {
          MAV_ASSIGN_OR_RETURN(m(i / 4, i % 4),
                               internal::ParseColumnDouble(f[i], name, line, columns[i]));
        }
        matrices->push_back(m);
        lines->push_back(line);
        return Status::Ok();
      });
}

}  // namespace

Result<std::vector<KittiMatrix>> ReadKittiMatrices(const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path));
  return ParseKittiMatrices(text, path);
}

Result<std::vector<KittiMatrix>> ParseKittiMatrices(std::string_view text,
                                                    const std::string& name) {
  std::vector<KittiMatrix> matrices;
  std::vector<int> lines;
  MAV_RETURN_IF_ERROR(ParseKittiRows(text, name, &matrices, &lines));
  return matrices;
}

Status WriteKittiTrajectory(const std::string& path, const std::vector<geometry::SE3>& poses) {
  std::vector<KittiMatrix> matrices;
  matrices.reserve(poses.size());
  for (const geometry::SE3& pose : poses) matrices.push_back(pose.Matrix3x4());
  return WriteKittiMatrices(path, matrices);
}

Result<std::vector<geometry::SE3>> ReadKittiTrajectory(const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path));
  return ParseKittiTrajectory(text, path);
}

Result<std::vector<geometry::SE3>> ParseKittiTrajectory(std::string_view text,
                                                        const std::string& name) {
  std::vector<KittiMatrix> matrices;
  std::vector<int> lines;
  MAV_RETURN_IF_ERROR(ParseKittiRows(text, name, &matrices, &lines));
  std::vector<geometry::SE3> poses;
  poses.reserve(matrices.size());
  for (size_t i = 0; i < matrices.size(); ++i) {
    const Eigen::Matrix3d r = matrices[i].leftCols<3>();
    const double orthogonality = (r * r.transpose() - Eigen::Matrix3d::Identity()).norm();
    if (!(orthogonality < 1e-6) || !(r.determinant() > 0)) {
      return Status::InvalidArgument(name + ":" + std::to_string(lines[i]) +
                                     ": rotation block is not a rotation (|R R^T - I| = " +
                                     internal::FormatDouble(orthogonality) + ")");
    }
    poses.emplace_back(r, Eigen::Vector3d(matrices[i].col(3)));
  }
  return poses;
}

}  // namespace mav::dataset
