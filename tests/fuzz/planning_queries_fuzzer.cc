// libFuzzer target: planning query files (dataset::ParsePlanningQueries, what mav-load and the
// planning benchmarks read: "x y z x y z [x y z ...]" per line).

#include <cmath>

#include "fuzz_checks.h"
#include "mav/dataset/planning_queries.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  const auto queries = dataset::ParsePlanningQueries(fuzz::AsText(data, size), fuzz::kName);
  if (!queries.ok()) {
    fuzz::CheckFailure(queries.status());
    return 0;
  }
  MAV_CHECK(!queries->empty());
  for (const dataset::PlanningQuery& q : *queries) {
    MAV_CHECK(q.points.size() >= 2);
    for (const Eigen::Vector3d& p : q.points) MAV_CHECK(p.allFinite());
  }
  return 0;
}
