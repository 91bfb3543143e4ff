#pragma once
// Internal text helpers shared by the readers and writers of this library.

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "mav/common/status.h"
#include "mav/dataset/read_options.h"

namespace mav::dataset::internal {

// Shortest decimal text that parses back to exactly `value` (std::to_chars).
std::string FormatDouble(double value);
void AppendDouble(std::string* out, double value);

// Calls `row(line_number, fields)` for every line of `contents` that is neither blank nor a '#'
// comment, after splitting on `sep` (',' for CSV; ' ' splits on runs of blanks and tabs).
// Checks the field count against `columns` (names used in error messages):
// "name:line: expected 7 columns, got 5". Stops at the first error `row` returns. `name` is the
// path (or whatever stands for it) in messages.
Status ForEachRow(std::string_view contents, const std::string& name, char sep,
                  const std::vector<std::string>& columns,
                  const std::function<Status(int line, const std::vector<std::string_view>&)>& row);

// "path:line: column 'name'" -> used as the `what` of ParseDouble/ParseInt64.
std::string Where(const std::string& path, int line, const std::string& column);

// Largest magnitude accepted in a numeric column (positions in m, velocities, IMU readings,
// biases, matrix entries). Far beyond anything measured (1e9 m is 150 Earth radii) yet small
// enough that squares and sums of such values stay finite, so a path length or an error computed
// from what a reader accepted is never inf.
inline constexpr double kMaxAbsColumnValue = 1e9;

// ParseDouble (finite) and |value| <= kMaxAbsColumnValue, naming path, line and column.
Result<double> ParseColumnDouble(std::string_view text, const std::string& path, int line,
                                 const std::string& column);
Result<int64_t> ParseColumnInt64(std::string_view text, const std::string& path, int line,
                                 const std::string& column);

// The time stamps of one file, row by row: refuses time going backwards; a stamp equal to the
// previous one is refused or dropped with a warning, as `options` says (read_options.h).
class StampSequence {
 public:
  StampSequence(std::string path, const ReadOptions& options)
      : path_(std::move(path)), options_(options) {}
  // Logs how many warnings were not logged (see ReadOptions::warnings).
  ~StampSequence();
  StampSequence(const StampSequence&) = delete;
  StampSequence& operator=(const StampSequence&) = delete;

  // OK with *keep = true for a stamp after the previous one (or the first); OK with
  // *keep = false for a repeated stamp that is to be dropped (after warning); InvalidArgument
  // "path:line: timestamp T is not after the previous one (P)" otherwise.
  Status Next(int64_t t_ns, int line, bool* keep);

 private:
  std::string path_;
  ReadOptions options_;
  bool first_ = true;
  int64_t previous_ = 0;
  int repeats_ = 0;
};

}  // namespace mav::dataset::internal
