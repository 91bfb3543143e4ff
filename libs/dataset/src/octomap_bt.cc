#include "mav/dataset/octomap_bt.h"

#include <cmath>
#include <sstream>
#include <vector>

#include <octomap/OcTree.h>

#include "mav/common/parse.h"
#include "mav/common/text.h"

namespace mav::dataset {
namespace {

constexpr std::string_view kMagic = "# Octomap OcTree binary file";
// OctoMap's keys have 16 bits: the root is at depth 0, the finest voxels at depth 16.
constexpr int kTreeDepth = 16;

std::vector<std::string_view> Tokens(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  const auto blank = [](char c) { return c == ' ' || c == '\t'; };
  while (i < line.size()) {
    while (i < line.size() && blank(line[i])) ++i;
    size_t j = i;
    while (j < line.size() && !blank(line[j])) ++j;
    if (j > i) tokens.push_back(line.substr(i, j - i));
    i = j;
  }
  return tokens;
}

// The header: lines up to and including "data". Sets *data_start to the first byte of node data.
// Stricter than OctoMap's own token reader (one keyword and value per line, no '\r', every value
// well-formed), so that whatever passes here OctoMap reads the same way.
Status ParseHeader(std::string_view bytes, const std::string& name, OctomapBinaryInfo* info,
                   int64_t* size, size_t* data_start) {
  const auto bad = [&](const std::string& what) {
    return Status::InvalidArgument(name + ": header: " + what);
  };
  size_t pos = bytes.find('\n');
  if (pos == std::string_view::npos || bytes.substr(0, kMagic.size()) != kMagic) {
    return bad(
        "the first line is not '# Octomap OcTree binary file' (not a .bt file, or the "
        "pre-2010 format without a header, which is not supported)");
  }
  ++pos;
  bool have_id = false, have_size = false, have_res = false;
  for (int line = 2;; ++line) {
    if (pos >= bytes.size()) return bad("ends before the 'data' line");
    const size_t end = bytes.find('\n', pos);
    if (end == std::string_view::npos) return bad("ends before the 'data' line");
    const std::string_view text = bytes.substr(pos, end - pos);
    pos = end + 1;
    const std::string where = "line " + std::to_string(line);
    if (text.find('\r') != std::string_view::npos) {
      return bad(where + ": carriage return (OctoMap would misread the line)");
    }
    const std::vector<std::string_view> tokens = Tokens(text);
    if (tokens.empty() || tokens[0].front() == '#') continue;
    const std::string_view key = tokens[0];
    if (key == "data") {
      if (tokens.size() != 1) return bad(where + ": 'data' must be alone on its line");
      break;
    }
    if (tokens.size() != 2) {
      return bad(where + ": expected '<keyword> <value>', got " + QuoteForError(text));
    }
    if (key == "id") {
      info->id = std::string(tokens[1]);
      have_id = true;
    } else if (key == "size") {
      MAV_ASSIGN_OR_RETURN(const uint64_t n, ParseUint64(tokens[1], name + ": header: size"));
      // OctoMap reads it into an unsigned int.
      if (n > 0xffffffffULL) return bad("size " + std::to_string(n) + " exceeds 32 bits");
      *size = static_cast<int64_t>(n);
      have_size = true;
    } else if (key == "res") {
      // Plain decimal only: strtod would also take "0x10" where OctoMap's stream reads 0.
      if (tokens[1].find_first_not_of("0123456789.eE+-") != std::string_view::npos) {
        return bad(where + ": res " + QuoteForError(tokens[1]) + " is not a decimal number");
      }
      MAV_ASSIGN_OR_RETURN(info->resolution_m, ParseDouble(tokens[1], name + ": header: res"));
      have_res = true;
    } else {
      return bad(where + ": unknown keyword " + QuoteForError(key));
    }
  }
  if (!have_id || !have_size || !have_res) {
    return bad(std::string("missing ") + (!have_id ? "'id'" : !have_size ? "'size'" : "'res'"));
  }
  *data_start = pos;
  return Status::Ok();
}

// Walks OctoMap's node encoding (OccupancyOcTreeBase::readBinaryNode): per node two bytes, two
// bits per child (children 0-3 in the first byte, 4-7 in the second, child i in bits 2i and
// 2i+1): value 1 a free leaf, 2 an occupied leaf, 3 an inner node whose own two bytes follow
// (depth first, children in index order), 0 no child. Iterative, so the depth of the input
// cannot overflow our stack.
Status WalkNodes(std::string_view data, const std::string& name, int64_t max_nodes,
                 int64_t* num_nodes) {
  struct Level {
    int depth;    // depth of the nodes still to read at this level
    int pending;  // how many of them
  };
  std::vector<Level> stack = {{0, 1}};  // the root
  size_t pos = 0;
  int64_t nodes = 1;
  while (!stack.empty()) {
    Level& top = stack.back();
    if (top.pending == 0) {
      stack.pop_back();
      continue;
    }
    --top.pending;
    const int depth = top.depth;
    if (pos + 2 > data.size()) {
      return Status::InvalidArgument(name + ": node data ends after " +
                                     std::to_string(data.size()) +
                                     " bytes, the tree needs more "
                                     "(truncated)");
    }
    const uint16_t bits = static_cast<uint16_t>(static_cast<uint8_t>(data[pos]) |
                                                (static_cast<uint8_t>(data[pos + 1]) << 8));
    pos += 2;
    int inner = 0;
    for (int child = 0; child < 8; ++child) {
      const int pair = (bits >> (2 * child)) & 3;
      if (pair == 0) continue;
      ++nodes;
      if (pair == 3) ++inner;
    }
    if (nodes > max_nodes) {
      return Status::InvalidArgument(name + ": more than " + std::to_string(max_nodes) +
                                     " nodes (the limit)");
    }
    if (inner > 0) {
      // The children are at depth + 1; inner ones there would put leaves below depth 16.
      if (depth + 1 >= kTreeDepth) {
        return Status::InvalidArgument(name + ": node data describes a tree deeper than " +
                                       std::to_string(kTreeDepth) + " levels");
      }
      stack.push_back({depth + 1, inner});
    }
  }
  if (pos != data.size()) {
    return Status::InvalidArgument(name + ": " + std::to_string(data.size() - pos) +
                                   " bytes after the end of the tree");
  }
  *num_nodes = nodes;
  return Status::Ok();
}

}  // namespace

bool OctomapReadLimits::IsValid(std::string* why) const {
  const auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (max_nodes < 1) return fail("max_nodes: must be >= 1");
  if (!(min_resolution_m > 0) || !std::isfinite(max_resolution_m) ||
      !(min_resolution_m <= max_resolution_m)) {
    return fail("min_resolution_m, max_resolution_m: need 0 < min <= max < inf");
  }
  return true;
}

Status ValidateOctomapBinary(std::string_view bytes, const std::string& name,
                             const OctomapReadLimits& limits, OctomapBinaryInfo* info) {
  std::string why;
  if (!limits.IsValid(&why)) return Status::InvalidArgument("limits: " + why);
  OctomapBinaryInfo local;
  OctomapBinaryInfo* out = info != nullptr ? info : &local;
  int64_t size = 0;
  size_t data_start = 0;
  MAV_RETURN_IF_ERROR(ParseHeader(bytes, name, out, &size, &data_start));
  if (!(out->resolution_m >= limits.min_resolution_m &&
        out->resolution_m <= limits.max_resolution_m)) {
    return Status::InvalidArgument(name + ": header: res " + std::to_string(out->resolution_m) +
                                   " m is outside [" + std::to_string(limits.min_resolution_m) +
                                   ", " + std::to_string(limits.max_resolution_m) + "]");
  }
  if (size > limits.max_nodes) {
    return Status::InvalidArgument(name + ": header: size " + std::to_string(size) +
                                   " nodes is above the limit of " +
                                   std::to_string(limits.max_nodes));
  }
  const std::string_view data = bytes.substr(data_start);
  out->data_bytes = static_cast<int64_t>(data.size());
  if (size == 0) {
    // OctoMap reads no data for an empty tree.
    if (!data.empty()) {
      return Status::InvalidArgument(name + ": size 0 but " + std::to_string(data.size()) +
                                     " bytes of node data");
    }
    out->num_nodes = 0;
    return Status::Ok();
  }
  MAV_RETURN_IF_ERROR(WalkNodes(data, name, limits.max_nodes, &out->num_nodes));
  if (out->num_nodes != size) {
    return Status::InvalidArgument(name + ": header: size says " + std::to_string(size) +
                                   " nodes, the data has " + std::to_string(out->num_nodes));
  }
  return Status::Ok();
}

Result<std::unique_ptr<octomap::OcTree>> ReadOctomapBinary(std::string_view bytes,
                                                           const std::string& name,
                                                           const OctomapReadLimits& limits) {
  OctomapBinaryInfo info;
  MAV_RETURN_IF_ERROR(ValidateOctomapBinary(bytes, name, limits, &info));
  std::istringstream in{std::string(bytes)};
  auto tree = std::make_unique<octomap::OcTree>(info.resolution_m);
  if (!tree->readBinary(in) || static_cast<int64_t>(tree->size()) != info.num_nodes) {
    return Status::Internal(name + ": OctoMap refused a .bt file that passed validation (" +
                            std::to_string(info.num_nodes) + " nodes)");
  }
  return tree;
}

}  // namespace mav::dataset
