#include "text.h"

#include <charconv>
#include <cmath>

#include "mav/common/log.h"
#include "mav/common/parse.h"
#include "mav/common/text.h"

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
    std::string_view contents, const std::string& name, char sep,
    const std::vector<std::string>& columns,
    const std::function<Status(int line, const std::vector<std::string_view>&)>& row) {
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
      return Status::InvalidArgument(name + ":" + std::to_string(line_number) + ": expected " +
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
  MAV_ASSIGN_OR_RETURN(const double value, ParseDouble(text, Where(path, line, column)));
  if (std::abs(value) > kMaxAbsColumnValue) {
    return Status::InvalidArgument(Where(path, line, column) + ": " + QuoteForError(Trim(text)) +
                                   " is beyond +-1e9, larger than any real measurement");
  }
  return value;
}

Result<int64_t> ParseColumnInt64(std::string_view text, const std::string& path, int line,
                                 const std::string& column) {
  return ParseInt64(text, Where(path, line, column));
}

Status StampSequence::Next(int64_t t_ns, int line, bool* keep) {
  *keep = true;
  const auto where = [&] {
    return path_ + ":" + std::to_string(line) + ": timestamp " + std::to_string(t_ns);
  };
  if (first_) {
    first_ = false;
    previous_ = t_ns;
    return Status::Ok();
  }
  if (t_ns < previous_ ||
      (t_ns == previous_ && options_.repeated_stamps == RepeatedStamps::kReject)) {
    return Status::InvalidArgument(where() + " is not after the previous one (" +
                                   std::to_string(previous_) + ")");
  }
  if (t_ns == previous_) {
    *keep = false;
    const std::string warning = where() + " repeats the previous row's; row dropped (first kept)";
    ++repeats_;
    if (options_.warnings != nullptr) {
      options_.warnings->push_back(warning);
    } else if (repeats_ <= ReadOptions::kMaxLoggedWarnings) {
      MAV_LOG(kWarning) << warning;
    }
    return Status::Ok();
  }
  previous_ = t_ns;
  return Status::Ok();
}

StampSequence::~StampSequence() {
  if (options_.warnings == nullptr && repeats_ > ReadOptions::kMaxLoggedWarnings) {
    MAV_LOG(kWarning) << path_ << ": " << repeats_ - ReadOptions::kMaxLoggedWarnings
                      << " more repeated timestamps dropped (" << repeats_ << " in all)";
  }
}

}  // namespace mav::dataset::internal
