#include "ompl_space.h"

#include <ompl/base/MotionValidator.h>
#include <ompl/base/StateSampler.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/util/Console.h>

#include <algorithm>
#include <mutex>
#include <random>

namespace mav::planning::internal {
namespace {

namespace ob = ompl::base;

class ClearanceValidityChecker : public ob::StateValidityChecker {
 public:
  ClearanceValidityChecker(const ob::SpaceInformationPtr& si, const ClearanceMap& map,
                           double required)
      : ob::StateValidityChecker(si), map_(map), required_(required) {}
  bool isValid(const ob::State* state) const override {
    return map_.IsValid(ToVector(state), required_);
  }
  double clearance(const ob::State* state) const override {
    return map_.Clearance(ToVector(state)) - required_;
  }

 private:
  const ClearanceMap& map_;
  double required_;
};

// Motions are straight segments in the map; the map's Lipschitz walk replaces OMPL's fixed
// fraction of the extent.
class ClearanceMotionValidator : public ob::MotionValidator {
 public:
  ClearanceMotionValidator(ob::SpaceInformation* si, const ClearanceMap& map, double required,
                           double tolerance)
      : ob::MotionValidator(si), map_(map), required_(required), tolerance_(tolerance) {}

  bool checkMotion(const ob::State* s1, const ob::State* s2) const override {
    const bool ok = map_.IsSegmentValid(ToVector(s1), ToVector(s2), required_, tolerance_);
    (ok ? valid_ : invalid_)++;
    return ok;
  }

  bool checkMotion(const ob::State* s1, const ob::State* s2,
                   std::pair<ob::State*, double>& last_valid) const override {
    const Eigen::Vector3d a = ToVector(s1), b = ToVector(s2);
    const double fraction = map_.ValidFraction(a, b, required_, tolerance_);
    if (fraction >= 1.0 && map_.bounds().Contains(b)) {
      valid_++;
      return true;
    }
    if (last_valid.first != nullptr) FromVector(a + fraction * (b - a), last_valid.first);
    last_valid.second = fraction;
    invalid_++;
    return false;
  }

 private:
  const ClearanceMap& map_;
  double required_;
  double tolerance_;
};

// Uniform (and near/Gaussian) sampling from a std::mt19937_64 seeded by the caller.
class SeededSampler : public ob::StateSampler {
 public:
  SeededSampler(const ob::StateSpace* space, uint64_t seed)
      : ob::StateSampler(space),
        bounds_(space->as<ob::RealVectorStateSpace>()->getBounds()),
        generator_(seed) {}

  void sampleUniform(ob::State* state) override {
    auto* values = state->as<ob::RealVectorStateSpace::StateType>()->values;
    for (int a = 0; a < 3; ++a) {
      values[a] =
          std::uniform_real_distribution<double>(bounds_.low[a], bounds_.high[a])(generator_);
    }
  }
  void sampleUniformNear(ob::State* state, const ob::State* near, double distance) override {
    const auto* centre = near->as<ob::RealVectorStateSpace::StateType>()->values;
    auto* values = state->as<ob::RealVectorStateSpace::StateType>()->values;
    for (int a = 0; a < 3; ++a) {
      const double lo = std::max(bounds_.low[a], centre[a] - distance);
      const double hi = std::min(bounds_.high[a], centre[a] + distance);
      values[a] = std::uniform_real_distribution<double>(lo, std::max(lo, hi))(generator_);
    }
  }
  void sampleGaussian(ob::State* state, const ob::State* mean, double stddev) override {
    const auto* centre = mean->as<ob::RealVectorStateSpace::StateType>()->values;
    auto* values = state->as<ob::RealVectorStateSpace::StateType>()->values;
    for (int a = 0; a < 3; ++a) {
      const double v = std::normal_distribution<double>(centre[a], stddev)(generator_);
      values[a] = std::clamp(v, bounds_.low[a], bounds_.high[a]);
    }
  }

 private:
  ob::RealVectorBounds bounds_;
  std::mt19937_64 generator_;
};

}  // namespace

void QuietOmpl() {
  static std::once_flag once;
  std::call_once(once, [] { ompl::msg::setLogLevel(ompl::msg::LOG_NONE); });
}

Eigen::Vector3d ToVector(const ompl::base::State* state) {
  const auto* v = state->as<ob::RealVectorStateSpace::StateType>()->values;
  return {v[0], v[1], v[2]};
}

void FromVector(const Eigen::Vector3d& p, ompl::base::State* state) {
  auto* v = state->as<ob::RealVectorStateSpace::StateType>()->values;
  v[0] = p.x();
  v[1] = p.y();
  v[2] = p.z();
}

ompl::base::SpaceInformationPtr MakeSpaceInformation(const ClearanceMap& map, double required,
                                                     double tolerance_m, uint64_t seed) {
  QuietOmpl();
  auto space = std::make_shared<ob::RealVectorStateSpace>(3);
  ob::RealVectorBounds bounds(3);
  for (int a = 0; a < 3; ++a) {
    bounds.setLow(a, map.bounds().min[a]);
    bounds.setHigh(a, map.bounds().max[a]);
  }
  space->setBounds(bounds);
  // Each sampler OMPL allocates gets its own stream, in allocation order.
  auto counter = std::make_shared<uint64_t>(0);
  space->setStateSamplerAllocator([seed, counter](const ob::StateSpace* s) {
    return std::make_shared<SeededSampler>(s, seed * 0x9e3779b97f4a7c15ull + (*counter)++);
  });
  auto si = std::make_shared<ob::SpaceInformation>(space);
  si->setStateValidityChecker(std::make_shared<ClearanceValidityChecker>(si, map, required));
  si->setMotionValidator(
      std::make_shared<ClearanceMotionValidator>(si.get(), map, required, tolerance_m));
  // For planners that interpolate on their own: no coarser than the map resolution.
  si->setStateValidityCheckingResolution(
      std::min(1.0, map.resolution() / space->getMaximumExtent()));
  si->setup();
  return si;
}

}  // namespace mav::planning::internal
