#include "json.h"

#include <cmath>
#include <cstdio>

#include "mav/common/file.h"

namespace mav::eval_cli {
namespace {

std::string Quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string Number(double v) {
  if (!std::isfinite(v)) return "null";  // JSON has no NaN/inf
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

}  // namespace

void JsonReport::Set(const std::string& group, const std::string& metric, Value value) {
  for (auto& [name, metrics] : groups_) {
    if (name != group) continue;
    for (auto& [m, v] : metrics) {
      if (m == metric) {
        v = std::move(value);
        return;
      }
    }
    metrics.emplace_back(metric, std::move(value));
    return;
  }
  groups_.push_back({group, {{metric, std::move(value)}}});
}

std::string JsonReport::ToString() const {
  std::string out = "{\n";
  for (size_t g = 0; g < groups_.size(); ++g) {
    out += "  " + Quote(groups_[g].first) + ": {";
    const auto& metrics = groups_[g].second;
    for (size_t i = 0; i < metrics.size(); ++i) {
      out += (i == 0 ? "\n    " : ",\n    ") + Quote(metrics[i].first) + ": ";
      const Value& v = metrics[i].second;
      out += std::holds_alternative<double>(v) ? Number(std::get<double>(v))
                                               : Quote(std::get<std::string>(v));
    }
    out += g + 1 < groups_.size() ? "\n  },\n" : "\n  }\n";
  }
  return out + "}\n";
}

Status JsonReport::WriteFile(const std::string& path) const {
  return WriteStringToFileAtomic(path, ToString());
}

}  // namespace mav::eval_cli
