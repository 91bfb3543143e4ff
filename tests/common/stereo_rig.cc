#include "tests/common/stereo_rig.h"

namespace mav::test_support {

camera::RectifiedStereo EurocLikeRig(double focal_px, double cx, double cy) {
  camera::RectifiedStereo rig;
  rig.width = 752;
  rig.height = 480;
  rig.fx = rig.fy = focal_px;
  rig.cx = cx;
  rig.cy = cy;
  rig.baseline = 0.11;
  return rig;
}

}  // namespace mav::test_support
