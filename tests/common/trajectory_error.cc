#include "tests/common/trajectory_error.h"

namespace mav::test_support {

RelativeError RelativeTranslationError(const std::vector<geometry::SE3>& truth,
                                       const std::vector<geometry::SE3>& est,
                                       const std::vector<double>& lengths) {
  std::vector<double> dist(truth.size(), 0.0);
  for (size_t k = 1; k < truth.size(); ++k) {
    dist[k] = dist[k - 1] + (truth[k].Translation() - truth[k - 1].Translation()).norm();
  }
  double sum = 0;
  RelativeError error;
  for (size_t s = 0; s < truth.size(); ++s) {
    for (double len : lengths) {
      size_t e = s;
      while (e < truth.size() && dist[e] < dist[s] + len) ++e;
      if (e == truth.size()) continue;
      const geometry::SE3 gt = truth[s].Inverse() * truth[e];
      const geometry::SE3 es = est[s].Inverse() * est[e];
      sum += (gt.Translation() - es.Translation()).norm() / len;
      ++error.segments;
    }
  }
  if (error.segments > 0) error.percent = 100.0 * sum / error.segments;
  return error;
}

}  // namespace mav::test_support
