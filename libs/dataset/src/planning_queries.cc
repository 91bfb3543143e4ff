#include "mav/dataset/planning_queries.h"

#include <cmath>
#include <sstream>

#include "mav/common/file.h"
#include "mav/common/parse.h"

namespace mav::dataset {

Result<std::vector<PlanningQuery>> ReadPlanningQueries(const std::string& path) {
  if (!PathExists(path)) return Status::NotFound(path + ": no such file");
  MAV_ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path));
  return ParsePlanningQueries(text, path);
}

Result<std::vector<PlanningQuery>> ParsePlanningQueries(std::string_view text,
                                                        const std::string& name) {
  std::vector<PlanningQuery> out;
  std::istringstream in{std::string(text)};
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const std::string where = name + ":" + std::to_string(number);
    line = line.substr(0, line.find('#'));
    std::istringstream words(line);
    std::vector<double> values;
    for (std::string word; words >> word;) {
      std::string what = where;
      what += ": value " + std::to_string(values.size() + 1);
      MAV_ASSIGN_OR_RETURN(const double v, ParseDouble(word, what));
      if (!std::isfinite(v)) {
        return Status::InvalidArgument(where + ": '" + word + "' is not finite");
      }
      values.push_back(v);
    }
    if (values.empty()) continue;
    if (values.size() < 6 || values.size() % 3 != 0) {
      return Status::InvalidArgument(
          where + ": expected start and goal (and waypoints) as x y z triples, got " +
          std::to_string(values.size()) + " numbers");
    }
    PlanningQuery q;
    q.where = where;
    for (size_t i = 0; i < values.size(); i += 3) {
      q.points.emplace_back(values[i], values[i + 1], values[i + 2]);
    }
    out.push_back(std::move(q));
  }
  if (out.empty()) return Status::InvalidArgument(name + ": no queries");
  return out;
}

}  // namespace mav::dataset
