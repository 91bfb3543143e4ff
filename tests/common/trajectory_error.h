#pragma once
// The KITTI-style relative translational error (Geiger et al., CVPR 2012) that the odometry tests
// score an estimated trajectory with.

#include <vector>

#include "mav/geometry/se3.h"

namespace mav::test_support {

struct RelativeError {
  double percent = 0;  // mean error in percent of the segment length; 0 without segments
  int segments = 0;    // how many (start, length) segments fitted
};

// For every start frame (step 1) and segment length, the segment ends at the first frame whose
// ground-truth path length passes start + length; both segments are aligned by their first frame.
// Lengths that never fit are skipped. `truth` and `est` are poses of the same frames.
RelativeError RelativeTranslationError(const std::vector<geometry::SE3>& truth,
                                       const std::vector<geometry::SE3>& est,
                                       const std::vector<double>& lengths);

}  // namespace mav::test_support
