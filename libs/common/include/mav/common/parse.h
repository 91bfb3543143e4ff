#pragma once
// Strict text-to-number parsing and splitting, for CSV rows, YAML scalars and CLI flags.
// Every failure returns InvalidArgument naming `what` (a field, column or flag) and quoting the
// text (QuoteForError: truncated and escaped), e.g.
// "imu0/data.csv:12: column 'w_RS_S_x [rad s^-1]': 'abc' is not a number".

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mav/common/status.h"

namespace mav {

// Whole-string parses: leading/trailing blanks allowed, anything else is an error.
//
// ParseDouble accepts only finite numbers: "nan", "inf", "-inf", "infinity" and values that
// overflow a double ("1e309") are errors ("must be a finite number" / "out of the range of a
// double"), since every number we read (a position, a rate, a noise density, a flag) is meant to
// be finite and an infinity read from a file would only fail later and obscurely (a plot spanning
// infinite metres, an "inf m" trajectory). A value too small for a double ("1e-400") reads as the
// nearest double (0 or a subnormal), like any other rounding. No caller needs an infinity today;
// if one ever does, give it an explicit option rather than loosening this.
Result<double> ParseDouble(std::string_view text, std::string_view what);
// Integers in [INT64_MIN, INT64_MAX]; a longer integer is "out of range [min, max]", not
// "not an integer".
Result<int64_t> ParseInt64(std::string_view text, std::string_view what);
// Integers in [0, UINT64_MAX] (e.g. seeds).
Result<uint64_t> ParseUint64(std::string_view text, std::string_view what);

// Splits on `sep`, keeping empty fields ("a,,b" -> 3 fields). Trailing '\r' is removed first.
std::vector<std::string_view> SplitFields(std::string_view line, char sep);
std::string_view Trim(std::string_view text);

}  // namespace mav
