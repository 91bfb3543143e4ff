#include "mav/sim/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "mav/camera/stereo.h"
#include "mav/geometry/se3.h"

namespace mav::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;

TrajectoryOptions Options(MotionProfile profile, uint64_t seed, double duration_s = 60.0) {
  TrajectoryOptions options;
  options.profile = profile;
  options.seed = seed;
  options.duration_s = duration_s;
  options.look_at = Eigen::Vector3d(0, 0, 1.5);
  return options;
}

Trajectory MakeOrDie(const TrajectoryOptions& options) {
  Result<Trajectory> result = Trajectory::Create(options);
  EXPECT_TRUE(result.ok()) << result.status().ToString();
  return std::move(result).value();
}

struct Stats {
  double mean_speed = 0;
  double max_speed = 0;
  double mean_omega = 0;  // mean |omega_body|
  double max_omega = 0;
  double max_tilt = 0;  // angle of the thrust axis (vehicle z = body x) from world up
  double vertical_speed_rms = 0;
  double facing_fraction = 0;  // time share with cam0's axis within 45 deg of the look-at bearing
  double pure_rotation_fraction = 0;  // time share with |omega| > 0.5 rad/s and speed < 0.15 m/s
};

Stats Measure(const Trajectory& trajectory, const Eigen::Vector3d& look_at) {
  const Eigen::Matrix3d r_body_cam0 = camera::EurocStereoCalibration().T_body_cam0.RotationMatrix();
  Stats s;
  int n = 0;
  for (double t = 0; t <= trajectory.duration_s(); t += 0.02, ++n) {
    const TrajectoryState x = trajectory.Evaluate(t);
    const Eigen::Matrix3d r = x.T_world_body.RotationMatrix();
    const double speed = x.v_world.norm();
    const double omega = x.omega_body.norm();
    s.mean_speed += speed;
    s.max_speed = std::max(s.max_speed, speed);
    s.mean_omega += omega;
    s.max_omega = std::max(s.max_omega, omega);
    const Eigen::Vector3d up = r.col(0);
    s.max_tilt = std::max(s.max_tilt, std::acos(std::clamp(up.z(), -1.0, 1.0)));
    s.vertical_speed_rms += x.v_world.z() * x.v_world.z();
    const Eigen::Vector3d axis = r * r_body_cam0.col(2);
    const Eigen::Vector3d to_target = look_at - x.T_world_body.Translation();
    const double angle = std::abs(std::remainder(
        std::atan2(axis.y(), axis.x()) - std::atan2(to_target.y(), to_target.x()), 2 * M_PI));
    if (angle < 45 * kDeg) s.facing_fraction += 1;
    if (omega > 0.5 && speed < 0.15) s.pure_rotation_fraction += 1;
  }
  s.mean_speed /= n;
  s.mean_omega /= n;
  s.vertical_speed_rms = std::sqrt(s.vertical_speed_rms / n);
  s.facing_fraction /= n;
  s.pure_rotation_fraction /= n;
  return s;
}

// Averages over a few seeds, so that the profile comparisons are not about one lucky draw.
Stats MeanStats(MotionProfile profile, int seeds = 4) {
  Stats mean;
  for (int seed = 1; seed <= seeds; ++seed) {
    const TrajectoryOptions options = Options(profile, seed);
    const Stats s = Measure(MakeOrDie(options), options.look_at);
    mean.mean_speed += s.mean_speed / seeds;
    mean.max_speed = std::max(mean.max_speed, s.max_speed);
    mean.mean_omega += s.mean_omega / seeds;
    mean.max_omega = std::max(mean.max_omega, s.max_omega);
    mean.max_tilt = std::max(mean.max_tilt, s.max_tilt);
    mean.vertical_speed_rms += s.vertical_speed_rms / seeds;
    mean.facing_fraction += s.facing_fraction / seeds;
    mean.pure_rotation_fraction += s.pure_rotation_fraction / seeds;
  }
  return mean;
}

void Print(const char* name, const Stats& s) {
  std::printf(
      "%-6s speed mean %.2f max %.2f m/s | omega mean %.2f max %.2f rad/s | tilt max %.1f deg | "
      "vz rms %.2f m/s | facing %.0f %% | pure rotation %.0f %%\n",
      name, s.mean_speed, s.max_speed, s.mean_omega, s.max_omega, s.max_tilt / kDeg,
      s.vertical_speed_rms, 100 * s.facing_fraction, 100 * s.pure_rotation_fraction);
}

TEST(TrajectoryTest, ProfilesDifferAsDescribed) {
  const Stats easy = MeanStats(MotionProfile::kEasy);
  const Stats medium = MeanStats(MotionProfile::kMedium);
  const Stats hard = MeanStats(MotionProfile::kHard);
  Print("easy", easy);
  Print("medium", medium);
  Print("hard", hard);

  EXPECT_GT(easy.mean_speed, 0.25);
  EXPECT_LT(easy.mean_speed, 0.55);
  EXPECT_GT(medium.mean_speed, 0.7);
  EXPECT_LT(medium.mean_speed, 1.1);
  EXPECT_GT(medium.mean_speed, 1.6 * easy.mean_speed);

  // Hard: much more rotation, more of it without translation, and vertical bobbing.
  EXPECT_GT(hard.mean_omega, 2.0 * easy.mean_omega);
  EXPECT_GT(hard.mean_omega, 1.3 * medium.mean_omega);
  EXPECT_GT(hard.pure_rotation_fraction, 0.1);
  EXPECT_GT(hard.pure_rotation_fraction, 3 * easy.pure_rotation_fraction);
  EXPECT_GT(hard.vertical_speed_rms, 2.0 * easy.vertical_speed_rms);

  // Tilts: a few degrees when easy, bounded when hard.
  EXPECT_LT(easy.max_tilt, 6 * kDeg);
  EXPECT_LT(medium.max_tilt, 13 * kDeg);
  EXPECT_LT(hard.max_tilt, 21 * kDeg);
  EXPECT_GT(hard.max_tilt, easy.max_tilt);

  // The camera mostly faces the point of interest.
  EXPECT_GT(easy.facing_fraction, 0.8);
  EXPECT_GT(medium.facing_fraction, 0.7);
  EXPECT_GT(hard.facing_fraction, 0.6);
}

TEST(TrajectoryTest, PlantProfileFliesFartherAndFaster) {
  TrajectoryOptions options = Options(MotionProfile::kPlant, 3, 120.0);
  options.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(-20, -20, 2), Eigen::Vector3d(20, 20, 30));
  options.look_at = Eigen::Vector3d(0, 0, 10);
  const Stats plant = Measure(MakeOrDie(options), options.look_at);
  Print("plant", plant);
  EXPECT_GT(plant.mean_speed, 1.2);
  EXPECT_LT(plant.max_tilt, 16 * kDeg);
}

TEST(TrajectoryTest, StaysInsideTheBounds) {
  for (MotionProfile profile : {MotionProfile::kEasy, MotionProfile::kMedium, MotionProfile::kHard,
                                MotionProfile::kPlant}) {
    for (uint64_t seed = 1; seed <= 3; ++seed) {
      TrajectoryOptions options = Options(profile, seed);
      options.bounds =
          Eigen::AlignedBox3d(Eigen::Vector3d(-2.5, -1.0, 0.8), Eigen::Vector3d(1.5, 3.0, 2.2));
      const Trajectory trajectory = MakeOrDie(options);
      for (double t = 0; t <= trajectory.duration_s(); t += 0.01) {
        const Eigen::Vector3d p = trajectory.Evaluate(t).T_world_body.Translation();
        ASSERT_TRUE(options.bounds.contains(p))
            << "profile " << static_cast<int>(profile) << " seed " << seed << " t " << t << ": "
            << p.transpose();
      }
    }
  }
}

TEST(TrajectoryTest, KeepsClearanceFromAPillar) {
  // A vertical pillar of radius 0.4 m at (1.2, -0.8): distance to its surface.
  const auto pillar = [](const Eigen::Vector3d& p) {
    return (p.head<2>() - Eigen::Vector2d(1.2, -0.8)).norm() - 0.4;
  };
  const auto closest_approach = [&](const Trajectory& trajectory) {
    double closest = 1e9;
    for (double t = 0; t <= trajectory.duration_s(); t += 0.005) {
      closest = std::min(closest, pillar(trajectory.Evaluate(t).T_world_body.Translation()));
    }
    return closest;
  };
  int free_runs_too_close = 0;
  for (MotionProfile profile :
       {MotionProfile::kEasy, MotionProfile::kMedium, MotionProfile::kHard}) {
    for (uint64_t seed = 1; seed <= 3; ++seed) {
      TrajectoryOptions options = Options(profile, seed);
      options.clearance = pillar;
      options.min_clearance = 0.6;
      // The generator samples the spline at most 5 cm apart: allow half that between samples.
      EXPECT_GE(closest_approach(MakeOrDie(options)), 0.6 - 0.025)
          << "profile " << static_cast<int>(profile) << " seed " << seed;
      options.clearance = nullptr;
      if (closest_approach(MakeOrDie(options)) < 0.6) ++free_runs_too_close;
    }
  }
  // Without the clearance function the same seeds do come closer, so the check above is active.
  EXPECT_GE(free_runs_too_close, 3);
}

TEST(TrajectoryTest, FailsWhenNoClearPathExists) {
  TrajectoryOptions options = Options(MotionProfile::kEasy, 1, 10.0);
  options.clearance = [](const Eigen::Vector3d&) { return 0.1; };
  options.min_clearance = 0.5;
  const Result<Trajectory> result = Trajectory::Create(options);
  ASSERT_FALSE(result.ok());
  EXPECT_EQ(result.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(result.status().message().find("min_clearance"), std::string::npos);

  // A wall through the whole box at x = 0 leaves one side free: still feasible.
  options.clearance = [](const Eigen::Vector3d& p) { return std::abs(p.x()); };
  EXPECT_TRUE(Trajectory::Create(options).ok());
}

TEST(TrajectoryTest, IsDeterministicForASeed) {
  const TrajectoryOptions options = Options(MotionProfile::kHard, 42, 20.0);
  const Trajectory a = MakeOrDie(options);
  const Trajectory b = MakeOrDie(options);
  const Trajectory c = MakeOrDie(Options(MotionProfile::kHard, 43, 20.0));
  double max_diff_other_seed = 0;
  for (double t = 0; t <= 20.0; t += 0.1) {
    const TrajectoryState sa = a.Evaluate(t), sb = b.Evaluate(t), sc = c.Evaluate(t);
    ASSERT_EQ(sa.T_world_body.Translation(), sb.T_world_body.Translation());
    ASSERT_EQ(sa.T_world_body.Rotation().coeffs(), sb.T_world_body.Rotation().coeffs());
    ASSERT_EQ(sa.omega_body, sb.omega_body);
    max_diff_other_seed =
        std::max(max_diff_other_seed,
                 (sa.T_world_body.Translation() - sc.T_world_body.Translation()).norm());
  }
  EXPECT_GT(max_diff_other_seed, 0.5);
}

TEST(TrajectoryTest, DerivativesMatchFiniteDifferences) {
  for (MotionProfile profile :
       {MotionProfile::kEasy, MotionProfile::kMedium, MotionProfile::kHard}) {
    const Trajectory trajectory = MakeOrDie(Options(profile, 7, 30.0));
    const double h = 1e-5;
    for (double t = 0.5; t < 29.5; t += 0.37) {
      const TrajectoryState x = trajectory.Evaluate(t);
      const TrajectoryState before = trajectory.Evaluate(t - h);
      const TrajectoryState after = trajectory.Evaluate(t + h);
      const Eigen::Vector3d v_numeric =
          (after.T_world_body.Translation() - before.T_world_body.Translation()) / (2 * h);
      const Eigen::Vector3d a_numeric = (after.v_world - before.v_world) / (2 * h);
      // omega_body: R(t)^T dR/dt = Hat(omega); central difference on the group.
      const Eigen::Vector3d omega_numeric =
          geometry::LogSO3(before.T_world_body.Rotation().conjugate() *
                           after.T_world_body.Rotation()) /
          (2 * h);
      const Eigen::Vector3d alpha_numeric = (after.omega_body - before.omega_body) / (2 * h);
      EXPECT_LT((x.v_world - v_numeric).norm(), 1e-6) << "t " << t;
      EXPECT_LT((x.a_world - a_numeric).norm(), 1e-6) << "t " << t;
      EXPECT_LT((x.omega_body - omega_numeric).norm(), 1e-6) << "t " << t;
      EXPECT_LT((x.alpha_body - alpha_numeric).norm(), 1e-5) << "t " << t;
    }
  }
}

TEST(TrajectoryTest, BodyFrameIsEurocsImuFrame) {
  // Hovering-ish start: body x points up, cam0 looks horizontally.
  const Trajectory trajectory = MakeOrDie(Options(MotionProfile::kEasy, 1, 10.0));
  const TrajectoryState x = trajectory.Evaluate(0.0);
  const Eigen::Matrix3d r = x.T_world_body.RotationMatrix();
  EXPECT_GT(r.col(0).z(), std::cos(6 * kDeg));
  const Eigen::Matrix3d r_world_cam0 =
      r * camera::EurocStereoCalibration().T_body_cam0.RotationMatrix();
  EXPECT_LT(std::abs(r_world_cam0.col(2).z()), std::sin(8 * kDeg));  // optical axis ~horizontal
  EXPECT_LT(r_world_cam0.col(1).z(), -std::cos(8 * kDeg));           // image y points down
  EXPECT_NEAR(RotationVehicleBody().determinant(), 1.0, 1e-12);
}

TEST(TrajectoryTest, EvaluateClampsTime) {
  const Trajectory trajectory = MakeOrDie(Options(MotionProfile::kMedium, 2, 10.0));
  EXPECT_EQ(trajectory.duration_s(), 10.0);
  EXPECT_EQ(trajectory.Evaluate(-5.0).T_world_body.Translation(),
            trajectory.Evaluate(0.0).T_world_body.Translation());
  EXPECT_EQ(trajectory.Evaluate(50.0).T_world_body.Translation(),
            trajectory.Evaluate(10.0).T_world_body.Translation());
}

TEST(TrajectoryTest, InvalidOptionsNameTheField) {
  struct Case {
    std::string field;
    std::function<void(TrajectoryOptions*)> mutate;
  };
  const std::vector<Case> cases = {
      {"duration_s", [](TrajectoryOptions* o) { o->duration_s = 0; }},
      {"duration_s", [](TrajectoryOptions* o) { o->duration_s = std::nan(""); }},
      {"bounds", [](TrajectoryOptions* o) { o->bounds.max().z() = o->bounds.min().z(); }},
      {"bounds",
       [](TrajectoryOptions* o) {
         o->bounds.min().x() = -std::numeric_limits<double>::infinity();
       }},
      {"min_clearance", [](TrajectoryOptions* o) { o->min_clearance = -0.1; }},
      {"look_at", [](TrajectoryOptions* o) { o->look_at.y() = std::nan(""); }},
      {"profile", [](TrajectoryOptions* o) { o->profile = static_cast<MotionProfile>(17); }},
  };
  for (const Case& c : cases) {
    TrajectoryOptions options;
    c.mutate(&options);
    std::string why;
    EXPECT_FALSE(options.IsValid(&why));
    EXPECT_NE(why.find(c.field), std::string::npos) << why;
    const Result<Trajectory> result = Trajectory::Create(options);
    ASSERT_FALSE(result.ok());
    EXPECT_EQ(result.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(result.status().message().find(c.field), std::string::npos);
  }
  std::string why;
  EXPECT_TRUE(TrajectoryOptions().IsValid(&why)) << why;
}

}  // namespace
}  // namespace mav::sim
