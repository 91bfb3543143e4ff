#include "clients/plot/mapping_figure.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mav/dataset/png.h"

namespace mav::plot {
namespace {

using dataset::OccupancyGrid;
using dataset::VoxelState;

// A perspective view of the scene from above and the side, looking at its centre.
struct View3d {
  Eigen::Matrix3d R_cam_world;
  Eigen::Vector3d t_cam_world;
  double f = 0, cx = 0, cy = 0;

  std::optional<cv::Point2f> Project(const Eigen::Vector3d& p, double* depth = nullptr) const {
    const Eigen::Vector3d c = R_cam_world * p + t_cam_world;
    if (c.z() < 0.1) return std::nullopt;
    if (depth) *depth = c.z();
    return cv::Point2f(static_cast<float>(f * c.x() / c.z() + cx),
                       static_cast<float>(f * c.y() / c.z() + cy));
  }
};

View3d MakeView(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int width, int height) {
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double radius = 0.5 * (hi - lo).norm();
  const Eigen::Vector3d dir = Eigen::Vector3d(-0.55, -1.0, 1.25).normalized();
  const Eigen::Vector3d eye = centre + dir * radius * 2.1;
  const Eigen::Vector3d z = (centre - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  View3d v;
  v.R_cam_world.row(0) = x.transpose();
  v.R_cam_world.row(1) = y.transpose();
  v.R_cam_world.row(2) = z.transpose();
  v.t_cam_world = -v.R_cam_world * eye;
  v.f = 0.95 * std::min(width, height) * 2.1 / 2.0 / 1.05;
  v.cx = width / 2.0;
  v.cy = height / 2.0 + 0.04 * height;
  return v;
}

// Blue (low) to red (high), like the paper's occupancy picture.
cv::Scalar HeightColour(double z, double z_lo, double z_hi) {
  const double t = std::clamp((z - z_lo) / std::max(z_hi - z_lo, 1e-6), 0.0, 1.0);
  cv::Mat1b in(1, 1, static_cast<uint8_t>(std::lround(t * 255)));
  cv::Mat3b out;
  cv::applyColorMap(in, out, cv::COLORMAP_JET);
  const cv::Vec3b c = out(0, 0);
  return cv::Scalar(c[0], c[1], c[2]);
}

}  // namespace

Status WriteMappingFigure(const std::string& path, const std::string& title,
                          const mapping::MappingOutput& out, const OccupancyGrid& truth) {
  const int w = 640, h = 520;
  cv::Mat canvas(h, 3 * w, CV_8UC3, cv::Scalar(255, 255, 255));
  const Eigen::Vector3d& lo = truth.origin();
  const Eigen::Vector3d hi = lo + truth.size().cast<double>() * truth.resolution();
  double z_cut = lo.z();
  for (const auto& T : out.keyframe_poses) z_cut = std::max(z_cut, T.Translation().z());
  z_cut += 0.3;  // cut away the ceiling so the inside can be seen
  const View3d view = MakeView(lo, hi, w, h);
  cv::Mat panels[3] = {canvas(cv::Rect(0, 0, w, h)), canvas(cv::Rect(w, 0, w, h)),
                       canvas(cv::Rect(2 * w, 0, w, h))};

  // Left: points (height-coloured) and keyframe poses (camera centre + optical axis).
  for (const mapping::MapPoint& p : out.points) {
    if (p.p_world.z() > z_cut) continue;
    if (auto px = view.Project(p.p_world)) {
      cv::circle(panels[0], *px, 1, HeightColour(p.p_world.z(), lo.z(), z_cut), cv::FILLED);
    }
  }
  for (const auto& T : out.keyframe_poses) {
    const Eigen::Vector3d& c = T.Translation();
    const Eigen::Vector3d axis = T * Eigen::Vector3d(0, 0, 0.25);
    auto pc = view.Project(c), pa = view.Project(axis);
    if (pc && pa) cv::line(panels[0], *pc, *pa, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    if (pc) cv::circle(panels[0], *pc, 2, cv::Scalar(0, 0, 200), cv::FILLED, cv::LINE_AA);
  }

  // Middle: the mesh, flat-shaded, far triangles first.
  {
    const mapping::TriangleMesh& mesh = out.meshing.mesh;
    struct Tri {
      double depth;
      std::array<cv::Point, 3> px;
      cv::Scalar colour;
    };
    std::vector<Tri> tris;
    const Eigen::Vector3d light = Eigen::Vector3d(0.3, -0.5, 1.0).normalized();
    for (const Eigen::Vector3i& t : mesh.triangles) {
      const Eigen::Vector3d& a = mesh.vertices[t[0]];
      const Eigen::Vector3d& b = mesh.vertices[t[1]];
      const Eigen::Vector3d& c = mesh.vertices[t[2]];
      if (std::max({a.z(), b.z(), c.z()}) > z_cut) continue;
      Tri tri;
      double da = 0, db = 0, dc = 0;
      auto pa = view.Project(a, &da), pb = view.Project(b, &db), pc = view.Project(c, &dc);
      if (!pa || !pb || !pc) continue;
      tri.depth = (da + db + dc) / 3;
      tri.px = {cv::Point(*pa), cv::Point(*pb), cv::Point(*pc)};
      const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
      const double shade = 0.35 + 0.65 * std::abs(n.dot(light));
      tri.colour = cv::Scalar(190 * shade, 200 * shade, 210 * shade);
      tris.push_back(tri);
    }
    std::sort(tris.begin(), tris.end(),
              [](const Tri& x, const Tri& y) { return x.depth > y.depth; });
    for (const Tri& t : tris) {
      cv::fillConvexPoly(panels[1], t.px.data(), 3, t.colour, cv::LINE_AA);
    }
  }

  // Right: our occupancy grid, occupied voxels with a free or unknown 6-neighbour (the visible
  // shell), height-coloured, far voxels first.
  {
    const OccupancyGrid& g = out.has_sparse_mesh ? out.sparse_mesh_grid : out.octomap_grid;
    const Eigen::Vector3i n = g.size();
    struct Vox {
      double depth;
      cv::Point2f px;
      double z;
    };
    std::vector<Vox> voxels;
    auto occupied = [&](int i, int j, int k) {
      return g.InBounds({i, j, k}) && g[g.Linear(i, j, k)] == VoxelState::kOccupied;
    };
    for (int k = 0; k < n.z(); ++k) {
      for (int j = 0; j < n.y(); ++j) {
        for (int i = 0; i < n.x(); ++i) {
          if (!occupied(i, j, k)) continue;
          const Eigen::Vector3d c = g.CenterOf({i, j, k});
          if (c.z() > z_cut) continue;
          if (occupied(i - 1, j, k) && occupied(i + 1, j, k) && occupied(i, j - 1, k) &&
              occupied(i, j + 1, k) && occupied(i, j, k - 1) && occupied(i, j, k + 1)) {
            continue;
          }
          double depth = 0;
          if (auto px = view.Project(c, &depth)) voxels.push_back({depth, *px, c.z()});
        }
      }
    }
    std::sort(voxels.begin(), voxels.end(),
              [](const Vox& x, const Vox& y) { return x.depth > y.depth; });
    for (const Vox& v : voxels) {
      const float half = static_cast<float>(0.5 * view.f * g.resolution() / v.depth) + 0.5f;
      const cv::Scalar colour = HeightColour(v.z, lo.z(), z_cut);
      cv::rectangle(panels[2], cv::Point2f(v.px.x - half, v.px.y - half),
                    cv::Point2f(v.px.x + half, v.px.y + half), colour, cv::FILLED);
    }
  }

  const char* captions[3] = {"3D points and keyframe poses", "mesh (Delaunay + graph cut)",
                             "occupancy grid (height: blue low, red high)"};
  for (int p = 0; p < 3; ++p) {
    cv::putText(panels[p], captions[p], cv::Point(12, 24), cv::FONT_HERSHEY_SIMPLEX, 0.55,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    if (p > 0)
      cv::line(canvas, cv::Point(p * w, 0), cv::Point(p * w, h), cv::Scalar(200, 200, 200));
  }
  cv::putText(canvas, title, cv::Point(12, h - 12), cv::FONT_HERSHEY_SIMPLEX, 0.5,
              cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
  return dataset::WritePngFile(path, canvas);
}

}  // namespace mav::plot
