#include "text.h"

#include <charconv>

#include "mav/common/file.h"
#include "mav/common/parse.h"

namespace mav::dataset::internal {

std::string FormatDouble(double value) {
  std::string out;
  AppendDouble(&out, value);
  return out;
}

void AppendDouble(std::string* out, double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out->append(buffer, result.ptr);
}

namespace {

std::vector<std::string_view> SplitBlanks(std::string_view line) {
  std::vector<std::string_view> fields;
  size_t i = 0;
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  while (i < line.size()) {
    while (i < line.size() && blank(line[i])) ++i;
    if (i >= line.size()) break;
    size_t j = i;
    while (j < line.size() && !blank(line[j])) ++j;
    fields.push_back(line.substr(i, j - i));
    i = j;
  }
  return fields;
}

}  // namespace

Status ForEachRow(
    const std::string& path, char sep, const std::vector<std::string>& columns,
    const std::function<Status(int line, const std::vector<std::string_view>&)>& row) {
  MAV_ASSIGN_OR_RETURN(const std::string contents, ReadFileToString(path));
  std::string_view rest(contents);
  int line_number = 0;
  while (!rest.empty()) {
    const size_t end = rest.find('\n');
    std::string_view line = rest.substr(0, end);
    rest = end == std::string_view::npos ? std::string_view() : rest.substr(end + 1);
    ++line_number;
    const std::string_view trimmed = Trim(line);
    if (trimmed.empty() || trimmed.front() == '#') continue;
    std::vector<std::string_view> fields =
        sep == ' ' ? SplitBlanks(trimmed) : SplitFields(trimmed, sep);
    if (fields.size() != columns.size()) {
      return Status::InvalidArgument(path + ":" + std::to_string(line_number) + ": expected " +
                                     std::to_string(columns.size()) + " columns, got " +
                                     std::to_string(fields.size()));
    }
    MAV_RETURN_IF_ERROR(row(line_number, fields));
  }
  return Status::Ok();
}

std::string Where(const std::string& path, int line, const std::string& column) {
  return path + ":" + std::to_string(line) + ": column '" + column + "'";
}

Result<double> ParseColumnDouble(std::string_view text, const std::string& path, int line,
                                 const std::string& column) {
  return ParseDouble(text, Where(path, line, column));
}

Result<int64_t> ParseColumnInt64(std::string_view text, const std::string& path, int line,
                                 const std::string& column) {
  return ParseInt64(text, Where(path, line, column));
}

Status CheckIncreasing(int64_t t_ns, int64_t* previous, bool* first, const std::string& path,
                       int line) {
  if (!*first && t_ns <= *previous) {
    return Status::InvalidArgument(path + ":" + std::to_string(line) + ": timestamp " +
                                   std::to_string(t_ns) + " is not after the previous one (" +
                                   std::to_string(*previous) + ")");
  }
  *first = false;
  *previous = t_ns;
  return Status::Ok();
}

}  // namespace mav::dataset::internal
