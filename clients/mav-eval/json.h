#pragma once
// A minimal writer for the flat JSON mav-eval emits: {group: {metric: number|string}}.

#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "mav/common/status.h"

namespace mav::eval_cli {

class JsonReport {
 public:
  using Value = std::variant<double, std::string>;
  void Set(const std::string& group, const std::string& metric, Value value);
  std::string ToString() const;
  Status WriteFile(const std::string& path) const;

 private:
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, Value>>>> groups_;
};

}  // namespace mav::eval_cli
