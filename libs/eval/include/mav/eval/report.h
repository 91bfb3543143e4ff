#pragma once
// The generic result of an evaluation, as mav-eval prints and saves it: ordered text tables and
// a JSON model. Every evaluation of libs/eval returns a typed summary (LocalizationSummary,
// MappingSummary, ...) and converts it into a Report (LocalizationReport, ...); one writer prints
// any Report (ReportText) and saves its JSON (WriteReportJson), so the figures of every command
// go through the same code.
//
// The JSON model is {group: {metric: value}}, where a value is a number, a string, or an array
// of records [{field: number|string, ...}, ...] (the per-query lists of the planning
// comparison).

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "mav/common/status.h"

namespace mav::eval {

class JsonReport {
 public:
  using Scalar = std::variant<double, std::string>;
  // One element of an array value: fields in order.
  using Record = std::vector<std::pair<std::string, Scalar>>;
  using Value = std::variant<double, std::string, std::vector<Record>>;

  // Sets `metric` of `group`; groups and metrics keep the order of their first Set, a second Set
  // of the same metric replaces its value in place.
  void Set(const std::string& group, const std::string& metric, Value value);
  bool empty() const { return groups_.empty(); }
  // The document, two-space indented, one metric a line (numbers: JsonNumber, text.h).
  std::string ToString() const;
  Status WriteFile(const std::string& path) const;

 private:
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, Value>>>> groups_;
};

// One text table: an optional title line, header lines, one line a row, then notes. The lines
// are formatted by the report's conversion (each table has its own column widths); the writer
// only lays them out.
struct ReportTable {
  bool blank_line_before = true;  // false: continues the previous table's block
  std::string title;              // empty: none
  std::vector<std::string> header;
  std::vector<std::string> rows;
  std::vector<std::string> notes;
};

struct Report {
  std::vector<ReportTable> tables;  // in print order
  JsonReport json;
  // A report whose JSON has a format of its own (the mission report of mav/mission/report.h,
  // shared with mavctl mission run): when non-empty, written instead of `json`.
  std::string json_document;

  // Appends a table and returns it for filling.
  ReportTable& AddTable(std::string title = "", bool blank_line_before = true);
};

// The tables as text: per table a blank line (blank_line_before), the title, the header lines,
// the rows and the notes, each line ending in '\n'.
std::string ReportText(const Report& report);

// The report's JSON (json_document, else json.ToString()) written to `path` atomically.
Status WriteReportJson(const Report& report, const std::string& path);

// printf-style formatting of one line of a table.
std::string FormatLine(const char* format, ...) __attribute__((format(printf, 1, 2)));

// Progress of a long evaluation: `done` of `total` units (frames, keyframes) of `stage`.
using StepProgress = std::function<void(std::string_view stage, int64_t done, int64_t total)>;

}  // namespace mav::eval
