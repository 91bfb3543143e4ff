#pragma once
// A minimal writer for the JSON mav-eval emits: {group: {metric: value}}, where a value is a
// number, a string, or an array of records [{field: number|string, ...}, ...] (the per-query
// lists of mav-eval planning).

#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "mav/common/status.h"
#include "mav/common/text.h"

namespace mav::eval_cli {

// JsonQuote and JsonNumber: mav/common/text.h.

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
