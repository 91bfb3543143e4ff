#include "mav/eval/report.h"

#include <algorithm>
#include <cstdarg>
#include <cstdio>

#include "mav/common/file.h"
#include "mav/common/text.h"

namespace mav::eval {

namespace {

std::string ScalarText(const JsonReport::Scalar& v) {
  return std::holds_alternative<double>(v) ? JsonNumber(std::get<double>(v))
                                           : JsonQuote(std::get<std::string>(v));
}

std::string ValueText(const JsonReport::Value& v) {
  if (std::holds_alternative<double>(v)) return JsonNumber(std::get<double>(v));
  if (std::holds_alternative<std::string>(v)) return JsonQuote(std::get<std::string>(v));
  const auto& records = std::get<std::vector<JsonReport::Record>>(v);
  std::string out = "[";
  for (size_t r = 0; r < records.size(); ++r) {
    out += (r == 0 ? "\n      {" : ",\n      {");
    for (size_t f = 0; f < records[r].size(); ++f) {
      out += (f == 0 ? "" : ", ") + JsonQuote(records[r][f].first) + ": " +
             ScalarText(records[r][f].second);
    }
    out += "}";
  }
  return out + (records.empty() ? "]" : "\n    ]");
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
    out += "  " + JsonQuote(groups_[g].first) + ": {";
    const auto& metrics = groups_[g].second;
    for (size_t i = 0; i < metrics.size(); ++i) {
      out += (i == 0 ? "\n    " : ",\n    ") + JsonQuote(metrics[i].first) + ": ";
      out += ValueText(metrics[i].second);
    }
    out += g + 1 < groups_.size() ? "\n  },\n" : "\n  }\n";
  }
  return out + "}\n";
}

Status JsonReport::WriteFile(const std::string& path) const {
  return WriteStringToFileAtomic(path, ToString());
}

ReportTable& Report::AddTable(std::string title, bool blank_line_before) {
  ReportTable& table = tables.emplace_back();
  table.title = std::move(title);
  table.blank_line_before = blank_line_before;
  return table;
}

std::string ReportText(const Report& report) {
  std::string out;
  for (const ReportTable& table : report.tables) {
    if (table.blank_line_before) out += "\n";
    if (!table.title.empty()) out += table.title + "\n";
    for (const auto* lines : {&table.header, &table.rows, &table.notes}) {
      for (const std::string& line : *lines) out += line + "\n";
    }
  }
  return out;
}

Status WriteReportJson(const Report& report, const std::string& path) {
  if (!report.json_document.empty()) return WriteStringToFileAtomic(path, report.json_document);
  return report.json.WriteFile(path);
}

std::string FormatLine(const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list copy;
  va_copy(copy, args);
  const int n = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  std::string out(static_cast<size_t>(std::max(n, 0)) + 1, '\0');
  std::vsnprintf(out.data(), out.size(), format, args);
  va_end(args);
  out.resize(static_cast<size_t>(std::max(n, 0)));
  return out;
}

}  // namespace mav::eval
