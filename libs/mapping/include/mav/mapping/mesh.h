#pragma once
// A triangle surface mesh and its PLY (Stanford polygon format) input/output.
//
// PLY as written here (opens in MeshLab, CloudCompare, Blender):
//   element vertex N   with float x, y, z            (world frame, metres)
//   element face M     with list uchar int vertex_indices (always 3 indices, counter-clockwise
//                      seen from outside: the normal (v1-v0)x(v2-v0) points into free space)
// in either `ascii 1.0` or `binary_little_endian 1.0`. ReadPly accepts both encodings, vertex
// properties of type float or double (extra vertex properties are skipped) and triangular faces.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::mapping {

struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;   // world frame [m]
  std::vector<Eigen::Vector3i> triangles;  // indices into `vertices`, outward (free-side) normal

  bool empty() const { return triangles.empty(); }
  // Sum of the triangle areas [m^2].
  double Area() const;
};

enum class PlyEncoding { kAscii, kBinaryLittleEndian };

// Writes atomically (temporary file renamed into place). Fails with IO_ERROR naming the path.
Status WritePly(const std::string& path, const TriangleMesh& mesh,
                PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian);
// Serialises to a string (the exact bytes WritePly writes).
std::string EncodePly(const TriangleMesh& mesh, PlyEncoding encoding);

// Reads a PLY written by us or by common tools. Errors (DATA_LOSS / INVALID_ARGUMENT) name the
// file and the offending header line or element index.
Result<TriangleMesh> ReadPly(const std::string& path);
Result<TriangleMesh> DecodePly(const std::string& bytes, const std::string& name_for_errors);

}  // namespace mav::mapping
