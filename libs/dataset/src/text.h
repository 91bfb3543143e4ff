#pragma once
// Internal text helpers shared by the readers and writers of this library.

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "mav/common/status.h"

namespace mav::dataset::internal {

// Shortest decimal text that parses back to exactly `value` (std::to_chars).
std::string FormatDouble(double value);
void AppendDouble(std::string* out, double value);

// Reads `path` and calls `row(line_number, fields)` for every line that is neither blank nor a
// '#' comment, after splitting on `sep` (',' for CSV; ' ' splits on runs of blanks and tabs).
// Checks the field count against `columns` (names used in error messages):
// "path:line: expected 7 columns, got 5". Stops at the first error `row` returns.
Status ForEachRow(const std::string& path, char sep, const std::vector<std::string>& columns,
                  const std::function<Status(int line, const std::vector<std::string_view>&)>& row);

// "path:line: column 'name'" -> used as the `what` of ParseDouble/ParseInt64.
std::string Where(const std::string& path, int line, const std::string& column);
Result<double> ParseColumnDouble(std::string_view text, const std::string& path, int line,
                                 const std::string& column);
Result<int64_t> ParseColumnInt64(std::string_view text, const std::string& path, int line,
                                 const std::string& column);
// Checks t_ns > *previous (strictly increasing) and updates *previous.
Status CheckIncreasing(int64_t t_ns, int64_t* previous, bool* first, const std::string& path,
                       int line);

}  // namespace mav::dataset::internal
