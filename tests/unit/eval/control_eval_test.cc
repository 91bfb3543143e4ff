#include "mav/eval/control_eval.h"

#include <cmath>

#include <gtest/gtest.h>

namespace mav::eval {
namespace {

TEST(ControllerTuningTest, DefaultsKeepTheDefaultDesign) {
  control::AutopilotOptions options;
  const control::AutopilotOptions before = options;
  ControllerTuning().Apply(&options);
  EXPECT_EQ(options.paper_gains.position_omega_radps, before.paper_gains.position_omega_radps);
  EXPECT_EQ(options.paper_gains.attitude_omega_radps, before.paper_gains.attitude_omega_radps);
  EXPECT_EQ(options.disturbance_observer_s, before.disturbance_observer_s);
  EXPECT_EQ(options.vehicle.mass_kg, before.vehicle.mass_kg);
  EXPECT_TRUE(options.estimator.couple_tilt);
  EXPECT_FALSE(options.gust_gains.has_value());  // no gain scheduling without a gust pole
}

TEST(ControllerTuningTest, PolesGiveTheTripleRootGains) {
  ControllerTuning tuning;
  tuning.position_pole_radps = 2.0;
  tuning.gust_pole_radps = 4.0;
  tuning.gust_attitude_omega_radps = 30.0;
  tuning.model_mass_kg = 1.5;
  tuning.decoupled_estimator = true;
  control::AutopilotOptions options;
  tuning.Apply(&options);
  // (s + P)^3 = s^3 + 3P s^2 + 3P^2 s + P^3: omega = sqrt(3) P, zeta = sqrt(3) / 2, ki = P^3.
  EXPECT_NEAR(options.paper_gains.position_omega_radps.x(), std::sqrt(3.0) * 2.0, 1e-12);
  EXPECT_NEAR(options.paper_gains.position_zeta.z(), std::sqrt(3.0) / 2.0, 1e-12);
  EXPECT_NEAR(options.paper_gains.integral_gain.y(), 8.0, 1e-12);
  ASSERT_TRUE(options.gust_gains.has_value());
  EXPECT_NEAR(options.gust_gains->integral_gain.x(), 64.0, 1e-12);
  EXPECT_EQ(options.gust_gains->attitude_omega_radps, 30.0);
  EXPECT_EQ(options.vehicle.mass_kg, 1.5);
  EXPECT_FALSE(options.estimator.couple_tilt);
}

TEST(ControlReportTest, PaperTableShowsDashesWithoutRuns) {
  const Report report = ControlReport(ControlSummary());
  ASSERT_EQ(report.tables.size(), 2u);
  EXPECT_TRUE(report.tables[0].rows.empty());
  ASSERT_EQ(report.tables[1].rows.size(), 6u);
  EXPECT_NE(report.tables[1].rows[0].find("0.055          -          -"), std::string::npos)
      << report.tables[1].rows[0];
  EXPECT_TRUE(report.json.empty());
}

}  // namespace
}  // namespace mav::eval
