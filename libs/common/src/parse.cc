#include "mav/common/parse.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>

#include "mav/common/text.h"

namespace mav {
namespace {

template <typename Int>
Result<Int> ParseInteger(std::string_view text, std::string_view what) {
  const std::string_view trimmed = Trim(text);
  const auto all_digits = [](std::string_view v) {
    return !v.empty() && v.find_first_not_of("0123456789") == std::string_view::npos;
  };
  const auto out_of_range = [&] {
    return Status::InvalidArgument(std::string(what) + ": " + QuoteForError(trimmed) +
                                   " is out of range [" +
                                   std::to_string(std::numeric_limits<Int>::min()) + ", " +
                                   std::to_string(std::numeric_limits<Int>::max()) + "]");
  };
  // from_chars refuses a sign on an unsigned type; "-5" is an integer, just not an unsigned one.
  if (std::numeric_limits<Int>::min() == 0 && !trimmed.empty() && trimmed.front() == '-' &&
      all_digits(trimmed.substr(1)) && trimmed.find_first_not_of("-0") != std::string_view::npos) {
    return out_of_range();
  }
  Int value = 0;
  const auto [ptr, ec] = std::from_chars(trimmed.data(), trimmed.data() + trimmed.size(), value);
  if (!trimmed.empty() && ec == std::errc::result_out_of_range &&
      ptr == trimmed.data() + trimmed.size()) {
    return out_of_range();
  }
  if (trimmed.empty() || ec != std::errc() || ptr != trimmed.data() + trimmed.size()) {
    return Status::InvalidArgument(std::string(what) + ": " + QuoteForError(trimmed) +
                                   " is not an integer");
  }
  return value;
}

}  // namespace

std::string_view Trim(std::string_view text) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!text.empty() && blank(text.front())) text.remove_prefix(1);
  while (!text.empty() && blank(text.back())) text.remove_suffix(1);
  return text;
}

Result<double> ParseDouble(std::string_view text, std::string_view what) {
  const std::string_view trimmed = Trim(text);
  if (trimmed.empty()) {
    return Status::InvalidArgument(std::string(what) + ": empty value, expected a number");
  }
  const std::string copy(trimmed);  // strtod needs a terminated string
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(copy.c_str(), &end);
  if (end != copy.c_str() + copy.size()) {
    return Status::InvalidArgument(std::string(what) + ": " + QuoteForError(trimmed) +
                                   " is not a number");
  }
  if (errno == ERANGE && std::isinf(value)) {
    return Status::InvalidArgument(std::string(what) + ": " + QuoteForError(trimmed) +
                                   " is out of the range of a double (about +-1.8e308)");
  }
  if (!std::isfinite(value)) {
    return Status::InvalidArgument(std::string(what) + ": must be a finite number, got " +
                                   QuoteForError(trimmed));
  }
  return value;
}

Result<int64_t> ParseInt64(std::string_view text, std::string_view what) {
  return ParseInteger<int64_t>(text, what);
}

Result<uint64_t> ParseUint64(std::string_view text, std::string_view what) {
  return ParseInteger<uint64_t>(text, what);
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
