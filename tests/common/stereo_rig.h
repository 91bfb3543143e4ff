#pragma once
// The rectified stereo rigs of the tests: EuRoC's 752x480 images and 11 cm baseline, with the
// focal length and principal point a test was tuned with.

#include "mav/camera/stereo.h"

namespace mav::test_support {

// A 752x480 rectified rig with fx = fy = `focal_px` and an 11 cm baseline.
camera::RectifiedStereo EurocLikeRig(double focal_px, double cx, double cy);

// The mapping tests' rig: f = 450 px, centred principal point, fx b = 49.5 px m.
inline camera::RectifiedStereo CenteredEurocLikeRig() { return EurocLikeRig(450.0, 376.0, 240.0); }

}  // namespace mav::test_support
