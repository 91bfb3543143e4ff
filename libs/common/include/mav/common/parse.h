#pragma once
// Strict text-to-number parsing and splitting, for CSV rows, YAML scalars and CLI flags.
// Every failure returns InvalidArgument naming `what` (a field, column or flag), e.g.
// "imu0/data.csv:12: column 'w_RS_S_x [rad s^-1]': 'abc' is not a number".

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mav/common/status.h"

namespace mav {

// Whole-string parses: leading/trailing blanks allowed, anything else is an error.
Result<double> ParseDouble(std::string_view text, std::string_view what);
Result<int64_t> ParseInt64(std::string_view text, std::string_view what);

// Splits on `sep`, keeping empty fields ("a,,b" -> 3 fields). Trailing '\r' is removed first.
std::vector<std::string_view> SplitFields(std::string_view line, char sep);
std::string_view Trim(std::string_view text);

}  // namespace mav
