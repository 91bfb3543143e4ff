#include "mav/mapping/mesh.h"

#include <cstdint>
#include <cstring>
#include <sstream>

#include <Eigen/Geometry>

#include "mav/common/file.h"
#include "mav/common/text.h"

namespace mav::mapping {

double TriangleMesh::Area() const {
  double area = 0.0;
  for (const Eigen::Vector3i& t : triangles) {
    const Eigen::Vector3d& a = vertices[t[0]];
    area += 0.5 * (vertices[t[1]] - a).cross(vertices[t[2]] - a).norm();
  }
  return area;
}

namespace {

template <typename T>
void AppendRaw(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));  // x86/ARM little endian, as the header declares
  out.append(bytes, sizeof(T));
}

enum class PropertyType { kChar, kUChar, kShort, kUShort, kInt, kUInt, kFloat, kDouble };

bool ParsePropertyType(const std::string& name, PropertyType* type) {
  static const std::pair<const char*, PropertyType> kNames[] = {
      {"char", PropertyType::kChar},     {"int8", PropertyType::kChar},
      {"uchar", PropertyType::kUChar},   {"uint8", PropertyType::kUChar},
      {"short", PropertyType::kShort},   {"int16", PropertyType::kShort},
      {"ushort", PropertyType::kUShort}, {"uint16", PropertyType::kUShort},
      {"int", PropertyType::kInt},       {"int32", PropertyType::kInt},
      {"uint", PropertyType::kUInt},     {"uint32", PropertyType::kUInt},
      {"float", PropertyType::kFloat},   {"float32", PropertyType::kFloat},
      {"double", PropertyType::kDouble}, {"float64", PropertyType::kDouble}};
  for (const auto& [n, t] : kNames) {
    if (name == n) {
      *type = t;
      return true;
    }
  }
  return false;
}

size_t SizeOf(PropertyType t) {
  switch (t) {
    case PropertyType::kChar:
    case PropertyType::kUChar:
      return 1;
    case PropertyType::kShort:
    case PropertyType::kUShort:
      return 2;
    case PropertyType::kInt:
    case PropertyType::kUInt:
    case PropertyType::kFloat:
      return 4;
    case PropertyType::kDouble:
      return 8;
  }
  return 0;
}

template <typename T>
T Load(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

double ReadBinary(PropertyType t, const char* p) {
  switch (t) {
    case PropertyType::kChar:
      return Load<int8_t>(p);
    case PropertyType::kUChar:
      return Load<uint8_t>(p);
    case PropertyType::kShort:
      return Load<int16_t>(p);
    case PropertyType::kUShort:
      return Load<uint16_t>(p);
    case PropertyType::kInt:
      return Load<int32_t>(p);
    case PropertyType::kUInt:
      return Load<uint32_t>(p);
    case PropertyType::kFloat:
      return Load<float>(p);
    case PropertyType::kDouble:
      return Load<double>(p);
  }
  return 0.0;
}

struct Property {
  std::string name;
  PropertyType type = PropertyType::kFloat;
  bool is_list = false;
  PropertyType count_type = PropertyType::kUChar;
};

struct Element {
  std::string name;
  int64_t count = 0;
  std::vector<Property> properties;
};

}  // namespace

std::string EncodePly(const TriangleMesh& mesh, PlyEncoding encoding) {
  std::ostringstream header;
  header << "ply\n"
         << (encoding == PlyEncoding::kAscii ? "format ascii 1.0\n"
                                             : "format binary_little_endian 1.0\n")
         << "comment mav::mapping surface mesh, world frame, metres\n"
         << "element vertex " << mesh.vertices.size() << "\n"
         << "property float x\nproperty float y\nproperty float z\n"
         << "element face " << mesh.triangles.size() << "\n"
         << "property list uchar int vertex_indices\n"
         << "end_header\n";
  std::string out = header.str();
  if (encoding == PlyEncoding::kAscii) {
    std::ostringstream body;
    body.precision(9);
    for (const Eigen::Vector3d& v : mesh.vertices) {
      body << static_cast<float>(v.x()) << ' ' << static_cast<float>(v.y()) << ' '
           << static_cast<float>(v.z()) << '\n';
    }
    for (const Eigen::Vector3i& t : mesh.triangles) {
      body << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
    }
    out += body.str();
  } else {
    out.reserve(out.size() + mesh.vertices.size() * 12 + mesh.triangles.size() * 13);
    for (const Eigen::Vector3d& v : mesh.vertices) {
      for (int i = 0; i < 3; ++i) AppendRaw(out, static_cast<float>(v[i]));
    }
    for (const Eigen::Vector3i& t : mesh.triangles) {
      AppendRaw(out, static_cast<uint8_t>(3));
      for (int i = 0; i < 3; ++i) AppendRaw(out, static_cast<int32_t>(t[i]));
    }
  }
  return out;
}

Status WritePly(const std::string& path, const TriangleMesh& mesh, PlyEncoding encoding) {
  return WriteStringToFileAtomic(path, EncodePly(mesh, encoding));
}

Result<TriangleMesh> DecodePly(const std::string& bytes, const std::string& name) {
  auto bad = [&](const std::string& m) { return Status::DataLoss(name + ": " + m); };
  size_t pos = 0;
  int line_no = 0;
  auto next_line = [&](std::string* line) {
    if (pos >= bytes.size()) return false;
    size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) end = bytes.size();
    *line = bytes.substr(pos, end - pos);
    if (!line->empty() && line->back() == '\r') line->pop_back();
    pos = end + 1;
    ++line_no;
    return true;
  };
  std::string line;
  if (!next_line(&line) || line != "ply") return bad("line 1: missing 'ply' magic");
  bool ascii = false;
  bool have_format = false;
  std::vector<Element> elements;
  bool header_done = false;
  while (next_line(&line)) {
    std::istringstream in(line);
    std::string word;
    in >> word;
    const std::string where = "header line " + std::to_string(line_no) + ": ";
    if (word == "format") {
      std::string format;
      in >> format;
      if (format == "ascii") {
        ascii = true;
      } else if (format != "binary_little_endian") {
        return bad(where + "unsupported format " + QuoteForError(format));
      }
      have_format = true;
    } else if (word == "element") {
      Element e;
      in >> e.name >> e.count;
      if (in.fail() || e.count < 0) return bad(where + "malformed element line");
      elements.push_back(e);
    } else if (word == "property") {
      if (elements.empty()) return bad(where + "property before any element");
      Property p;
      std::string type;
      in >> type;
      if (type == "list") {
        std::string count_type, item_type;
        in >> count_type >> item_type >> p.name;
        p.is_list = true;
        if (!ParsePropertyType(count_type, &p.count_type) ||
            !ParsePropertyType(item_type, &p.type)) {
          return bad(where + "unknown list types");
        }
      } else {
        in >> p.name;
        if (!ParsePropertyType(type, &p.type))
          return bad(where + "unknown type " + QuoteForError(type));
      }
      elements.back().properties.push_back(p);
    } else if (word == "end_header") {
      header_done = true;
      break;
    } else if (word != "comment" && word != "obj_info" && !word.empty()) {
      return bad(where + "unexpected keyword " + QuoteForError(word));
    }
  }
  if (!header_done) return bad("no end_header");
  if (!have_format) return bad("no format line");

  TriangleMesh mesh;
  std::istringstream ascii_in(ascii ? bytes.substr(pos) : std::string());
  for (const Element& e : elements) {
    const bool is_vertex = e.name == "vertex";
    const bool is_face = e.name == "face";
    int xyz[3] = {-1, -1, -1};
    for (size_t i = 0; i < e.properties.size(); ++i) {
      if (e.properties[i].name == "x") xyz[0] = static_cast<int>(i);
      if (e.properties[i].name == "y") xyz[1] = static_cast<int>(i);
      if (e.properties[i].name == "z") xyz[2] = static_cast<int>(i);
    }
    if (is_vertex && (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)) {
      return bad("element vertex lacks x, y or z");
    }
    for (int64_t k = 0; k < e.count; ++k) {
      const std::string where = "element " + e.name + "[" + std::to_string(k) + "]: ";
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      std::vector<double> list;
      for (size_t pi = 0; pi < e.properties.size(); ++pi) {
        const Property& p = e.properties[pi];
        auto read_value = [&](PropertyType t, double* value) {
          if (ascii) {
            ascii_in >> *value;
            return !ascii_in.fail();
          }
          if (pos + SizeOf(t) > bytes.size()) return false;
          *value = ReadBinary(t, bytes.data() + pos);
          pos += SizeOf(t);
          return true;
        };
        if (p.is_list) {
          double count = 0;
          if (!read_value(p.count_type, &count) || count < 0) return bad(where + "truncated");
          for (int c = 0; c < static_cast<int>(count); ++c) {
            double value = 0;
            if (!read_value(p.type, &value)) return bad(where + "truncated");
            if (is_face && p.name == "vertex_indices") list.push_back(value);
          }
        } else {
          double value = 0;
          if (!read_value(p.type, &value)) return bad(where + "truncated");
          for (int a = 0; a < 3; ++a) {
            if (static_cast<int>(pi) == xyz[a]) v[a] = value;
          }
        }
      }
      if (is_vertex) mesh.vertices.push_back(v);
      if (is_face) {
        if (list.size() != 3) {
          return Status::InvalidArgument(name + ": " + where +
                                         "only triangles are supported, got " +
                                         std::to_string(list.size()) + " indices");
        }
        Eigen::Vector3i t(static_cast<int>(list[0]), static_cast<int>(list[1]),
                          static_cast<int>(list[2]));
        mesh.triangles.push_back(t);
      }
    }
  }
  for (size_t k = 0; k < mesh.triangles.size(); ++k) {
    for (int a = 0; a < 3; ++a) {
      const int i = mesh.triangles[k][a];
      if (i < 0 || i >= static_cast<int>(mesh.vertices.size())) {
        return bad("element face[" + std::to_string(k) + "]: vertex index " + std::to_string(i) +
                   " out of range");
      }
    }
  }
  return mesh;
}

Result<TriangleMesh> ReadPly(const std::string& path) {
  MAV_ASSIGN_OR_RETURN(std::string bytes, ReadFileToString(path));
  return DecodePly(bytes, path);
}

}  // namespace mav::mapping
