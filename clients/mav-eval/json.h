#pragma once
// A minimal writer for the JSON mav-eval emits: {group: {metric: value}}, where a value is a
// number, a string, or an array of records [{field: number|string, ...}, ...] (the per-query
// lists of mav-eval planning).

#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "mav/common/status.h"

namespace mav::eval_cli {

// A JSON string literal (quotes, backslashes and control characters escaped).
std::string JsonQuote(const std::string& s);
// A JSON number: integers exactly, others to 6 significant digits; null for NaN or infinity.
std::string JsonNumber(double v);

class JsonReport {
 public:
  using Scalar = std::variant<double, std::string>;
  // One element of an array value: fields in order.
  using Record = std::vector<std::pair<std::string, Scalar>>;
  using Value = std::variant<double, std::string, std::vector<Record>>;
  void Set(const std::string& group, const std::string& metric, Value value);
  std::string ToString() const;
  Status WriteFile(const std::string& path) const;

 private:
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, Value>>>> groups_;
};

}  // namespace mav::eval_cli
