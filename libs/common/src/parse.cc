#include "mav/common/parse.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <string>

namespace mav {

std::string_view Trim(std::string_view text) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!text.empty() && blank(text.front())) text.remove_prefix(1);
  while (!text.empty() && blank(text.back())) text.remove_suffix(1);
  return text;
}

Result<double> ParseDouble(std::string_view text, std::string_view what) {
  const std::string_view trimmed = Trim(text);
  const std::string copy(trimmed);  // strtod needs a terminated string
  if (copy.empty()) {
    return Status::InvalidArgument(std::string(what) + ": empty value, expected a number");
  }
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(copy.c_str(), &end);
  if (end != copy.c_str() + copy.size() || errno == ERANGE || std::isnan(value)) {
    return Status::InvalidArgument(std::string(what) + ": '" + copy + "' is not a number");
  }
  return value;
}

Result<int64_t> ParseInt64(std::string_view text, std::string_view what) {
  const std::string_view trimmed = Trim(text);
  int64_t value = 0;
  const auto [ptr, ec] = std::from_chars(trimmed.data(), trimmed.data() + trimmed.size(), value);
  if (trimmed.empty() || ec != std::errc() || ptr != trimmed.data() + trimmed.size()) {
    return Status::InvalidArgument(std::string(what) + ": '" + std::string(trimmed) +
                                   "' is not an integer");
  }
  return value;
}

std::vector<std::string_view> SplitFields(std::string_view line, char sep) {
  while (!line.empty() && (line.back() == '\r' || line.back() == '\n')) line.remove_suffix(1);
  std::vector<std::string_view> fields;
  size_t start = 0;
  while (true) {
    const size_t pos = line.find(sep, start);
    if (pos == std::string_view::npos) {
      fields.push_back(line.substr(start));
      break;
    }
    fields.push_back(line.substr(start, pos - start));
    start = pos + 1;
  }
  return fields;
}

}  // namespace mav
