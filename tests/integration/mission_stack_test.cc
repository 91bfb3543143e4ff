// A mission through the services: mav-simulator (the mission flight: the vehicle in room-easy,
// its rendered stereo camera on DDS), mav-localization (the sparse VO on that stream),
// mav-control (the estimator on the VO's DDS poses, lock-stepped) and mav-planning (the legs on
// the simulator's ground-truth occupancy), each its own process on free loopback ports and a
// private DDS domain, driven by `mavctl mission run` (a fifth process).
//
//   * A one-goal room-easy mission completes with 0 collisions and its goal within 0.15 m, and
//     flies the very trajectory the in-process driver (mav-eval mission's) flies for the seed:
//     ground truth and estimate agree to 1 mm at every sample.
//   * kill -9 of mav-localization mid-mission, then a restart: the vehicle holds on the IMU, the
//     mission re-seeds the restarted VO from the estimate and completes, 0 collisions.

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/common/file.h"
#include "mav/common/time.h"
#include "mav/dataset/mission_file.h"
#include "mav/mission/lockstep_driver.h"
#include "mav/mission/mission.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "tests/common/build_paths.h"
#include "tests/common/stack_process.h"
#include "tests/common/test_domain.h"

namespace mav {
namespace {

using ::mav::test_support::Child;
using ::mav::test_support::FreeTcpPort;
using ::mav::test_support::TestDomain;
using ::mav::test_support::WaitServing;

const std::string kBinDir = mav::testing::BinaryDir() + "/bin";

// From beside the shelf past the central crate to the far side, then up and across.
constexpr char kMission[] = R"(world: room-easy
start: [-2.0, 2.4, 0.0]
altitude: 1.2
hover_s: 1
goals:
  - [2.2, -0.8, 1.0]
  - [2.0, 1.6, 1.6]
land: true
)";
// Its first leg alone: the agreement test (each ctest shard under the 60 s per-test budget).
constexpr char kOneGoalMission[] = R"(world: room-easy
start: [-2.0, 2.4, 0.0]
altitude: 1.2
hover_s: 1
goals:
  - [2.2, -0.8, 1.0]
land: true
)";

struct Row {
  double t = 0;
  Eigen::Vector3d gt, est;
};

std::vector<Row> ReadTrajectory(const std::string& path) {
  std::vector<Row> rows;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<double> v;
    std::stringstream fields(line);
    for (std::string f; std::getline(fields, f, ',');) v.push_back(std::stod(f));
    if (v.size() < 7) continue;
    rows.push_back({v[0], {v[1], v[2], v[3]}, {v[4], v[5], v[6]}});
  }
  return rows;
}

class MissionStackTest : public ::testing::Test {
 protected:
  void SetUp() override {
    domain_ = TestDomain(0);
    dir_ = mav::testing::BinaryDir() + "/Testing/mission-stack-" + std::to_string(::getpid()) +
           "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name();
    ASSERT_TRUE(MakeDirectories(dir_).ok());
    mission_path_ = dir_ + "/room_two_goals.yaml";
    ASSERT_TRUE(WriteStringToFileAtomic(mission_path_, kMission).ok());
    one_goal_path_ = dir_ + "/room_one_goal.yaml";
    ASSERT_TRUE(WriteStringToFileAtomic(one_goal_path_, kOneGoalMission).ok());
    for (int* port : {&sim_port_, &loc_port_, &plan_port_, &ctl_port_}) {
      do {
        *port = FreeTcpPort();
      } while ((port != &sim_port_ && *port == sim_port_) ||
               (port != &loc_port_ && *port == loc_port_) ||
               (port != &plan_port_ && *port == plan_port_));
    }
    simulator_ = Start("mav-simulator", sim_port_);
    localization_ = Start("mav-localization", loc_port_);
    planning_ = Start("mav-planning", plan_port_);
    control_ = Start("mav-control", ctl_port_);
    ASSERT_TRUE(WaitServing(Target(sim_port_), "mav.v1.Simulator")) << "see " << dir_;
    ASSERT_TRUE(WaitServing(Target(loc_port_), "mav.v1.Localization")) << "see " << dir_;
    ASSERT_TRUE(WaitServing(Target(plan_port_), "mav.v1.Planning")) << "see " << dir_;
    ASSERT_TRUE(WaitServing(Target(ctl_port_), "mav.v1.Control")) << "see " << dir_;
  }

  static std::string Target(int port) { return "127.0.0.1:" + std::to_string(port); }

  std::unique_ptr<Child> Start(const std::string& binary, int port, const std::string& tag = "") {
    return std::make_unique<Child>(
        std::vector<std::string>{kBinDir + "/" + binary, "--port", std::to_string(port),
                                 "--dds-domain", std::to_string(domain_)},
        dir_ + "/" + binary + tag + ".log");
  }

  // mavctl mission run on `path`, writing dir_/out and dir_/report.json.
  std::unique_ptr<Child> StartMission(const std::string& path) {
    return std::make_unique<Child>(std::vector<std::string>{kBinDir + "/mavctl",
                                                            "mission",
                                                            "run",
                                                            "--mission",
                                                            path,
                                                            "--seed",
                                                            "1",
                                                            "--pose-source",
                                                            "vo",
                                                            "--out",
                                                            dir_ + "/out",
                                                            "--json",
                                                            dir_ + "/report.json",
                                                            "--simulator",
                                                            Target(sim_port_),
                                                            "--localization",
                                                            Target(loc_port_),
                                                            "--planning",
                                                            Target(plan_port_),
                                                            "--control",
                                                            Target(ctl_port_)},
                                   dir_ + "/mavctl.log");
  }

  std::string Report() {
    Result<std::string> text = ReadFileToString(dir_ + "/report.json");
    return text.ok() ? *text : "";
  }

  // The report's outcome, collisions and goal errors.
  void ExpectCompletedWithoutCollision(const std::string& report, int expected_goals) {
    EXPECT_NE(report.find("\"outcome\": \"completed\""), std::string::npos) << report;
    EXPECT_NE(report.find("\"collisions\": 0,"), std::string::npos) << report;
    const std::regex error("\"error_m\": ([0-9.eE+-]+)");
    int goals = 0;
    for (auto it = std::sregex_iterator(report.begin(), report.end(), error);
         it != std::sregex_iterator(); ++it) {
      ++goals;
      EXPECT_LE(std::stod((*it)[1]), 0.15) << "goal " << goals;
    }
    EXPECT_EQ(goals, expected_goals);
  }

  int64_t domain_ = 0;
  std::string dir_, mission_path_, one_goal_path_;
  int sim_port_ = 0, loc_port_ = 0, plan_port_ = 0, ctl_port_ = 0;
  std::unique_ptr<Child> simulator_, localization_, planning_, control_;
};

TEST_F(MissionStackTest, RoomMissionThroughTheServicesFliesTheInProcessTrajectory) {
  std::unique_ptr<Child> mission = StartMission(one_goal_path_);
  const std::optional<int> rc = mission->Wait(std::chrono::seconds(240));
  ASSERT_TRUE(rc.has_value()) << "mavctl mission run still running after 240 s; see " << dir_;
  EXPECT_EQ(*rc, 0) << "see " << dir_ << "/mavctl.log";
  const std::string report = Report();
  ExpectCompletedWithoutCollision(report, 1);
  EXPECT_NE(report.find("\"driver\": \"services\""), std::string::npos);
  const std::vector<Row> services = ReadTrajectory(dir_ + "/out/trajectory.csv");
  ASSERT_GT(services.size(), 200u);

  // Every vision pose's path, frame capture -> mav-control's estimator, stamped at each hop.
  std::smatch latency;
  ASSERT_TRUE(std::regex_search(
      report, latency,
      std::regex("\"pose_latency_ms\": \\{\"count\": ([0-9]+), \"p50\": ([0-9.eE+-]+), "
                 "\"p99\": ([0-9.eE+-]+), \"max\": [0-9.eE+-]+, \"frame_transport_p50\": "
                 "([0-9.eE+-]+), \"localization_p50\": ([0-9.eE+-]+)")))
      << report;
  EXPECT_GT(std::stoi(latency[1]), 50) << "poses with the frame's stamps";
  const double total_p50 = std::stod(latency[2]), localization_p50 = std::stod(latency[5]);
  EXPECT_GT(std::stod(latency[4]), 0.0) << "the frame's DDS hop";
  EXPECT_GT(localization_p50, 0.0);
  EXPECT_GE(total_p50, localization_p50) << "each pose's total includes its localization hop";
  std::cout << "[ figures ] vision pose latency, capture -> estimator: p50 " << total_p50
            << " ms, p99 " << latency[3] << " ms over " << latency[1] << " poses\n";

  // The same mission and seed in one process (mav-eval mission's driver).
  Result<dataset::MissionSpec> spec = dataset::ParseMissionYaml(kOneGoalMission, one_goal_path_);
  ASSERT_TRUE(spec.ok()) << spec.status().ToString();
  mission::LockstepOptions options;
  options.vehicle.seed = 1;
  Result<std::unique_ptr<mission::LockstepDriver>> driver =
      mission::LockstepDriver::Create(*spec, options);
  ASSERT_TRUE(driver.ok()) << driver.status().ToString();
  Result<mission::MissionReport> in_process =
      mission::RunMission(*spec, mission::MissionOptions(), **driver);
  ASSERT_TRUE(in_process.ok()) << in_process.status().ToString();
  EXPECT_EQ(in_process->outcome, mission::MissionOutcome::kCompleted);
  const std::vector<mission::FlightSample>& record = (*driver)->record();
  ASSERT_EQ(record.size(), services.size()) << "the flights differ in length";
  double gt_diff = 0, est_diff = 0;
  for (size_t i = 0; i < record.size(); ++i) {
    ASSERT_NEAR(record[i].t_s, services[i].t, 1e-6) << "sample " << i;
    // The CSV keeps 0.01 mm.
    gt_diff = std::max(gt_diff, (record[i].p_true - services[i].gt).cwiseAbs().maxCoeff());
    est_diff = std::max(est_diff, (record[i].p_est - services[i].est).cwiseAbs().maxCoeff());
  }
  std::cout << "[ figures ] services vs in-process over " << record.size()
            << " samples: ground truth " << gt_diff * 1000 << " mm, estimate " << est_diff * 1000
            << " mm apart at most\n";
  EXPECT_LE(gt_diff, 1e-3);
  EXPECT_LE(est_diff, 1e-3);
}

TEST_F(MissionStackTest, KilledLocalizationIsRestartedReseededAndTheMissionCompletes) {
  std::unique_ptr<Child> mission = StartMission(mission_path_);
  // Mid-leg (the take-off ends near 9 s): kill -9 the localization, restart it at once.
  auto simulator = v1::Simulator::NewStub(
      grpc::CreateChannel(Target(sim_port_), grpc::InsecureChannelCredentials()));
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  double t_s = 0;
  while (t_s < 11.0 && std::chrono::steady_clock::now() < give_up) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
    v1::FlightStatus status;
    if (simulator->GetFlightStatus(&context, v1::GetFlightStatusRequest(), &status).ok()) {
      t_s = NsToSeconds(status.t_ns());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_GE(t_s, 11.0) << "the flight did not reach 11 s; see " << dir_;
  localization_->Signal(SIGKILL);
  ASSERT_TRUE(localization_->Wait(std::chrono::seconds(5)).has_value());
  std::this_thread::sleep_for(std::chrono::seconds(1));  // down for a second of wall time
  double restart_t_s = 0;
  {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
    v1::FlightStatus status;
    ASSERT_TRUE(simulator->GetFlightStatus(&context, v1::GetFlightStatusRequest(), &status).ok());
    restart_t_s = NsToSeconds(status.t_ns());
  }
  localization_ = Start("mav-localization", loc_port_, "-restarted");
  const std::optional<int> rc = mission->Wait(std::chrono::seconds(240));
  ASSERT_TRUE(rc.has_value()) << "mavctl mission run still running after 240 s; see " << dir_;
  EXPECT_EQ(*rc, 0) << "see " << dir_ << "/mavctl.log";
  const std::string report = Report();
  ExpectCompletedWithoutCollision(report, 2);
  EXPECT_NE(report.find("localization re-seeded from the estimate"), std::string::npos) << report;
  // Back to the mission (the hold left: "resume") within 3 s of the restart (the flight's clock:
  // lock-stepped, it moves only as the mission ticks), and never near the ground meanwhile.
  const std::smatch resume = [&] {
    std::smatch m;
    std::regex_search(report, m, std::regex("\\{\"t_s\": ([0-9.eE+-]+), \"what\": \"resume"));
    return m;
  }();
  ASSERT_FALSE(resume.empty()) << report;
  const double resumed_t_s = std::stod(resume[1]);
  EXPECT_LE(resumed_t_s - restart_t_s, 3.0) << "restarted at " << restart_t_s << " s";
  double min_z = 1e9;
  for (const Row& row : ReadTrajectory(dir_ + "/out/trajectory.csv")) {
    if (row.t >= 11.0 && row.t <= resumed_t_s) min_z = std::min(min_z, row.gt.z());
  }
  EXPECT_GT(min_z, 0.5) << "never near the ground while localization was down";
  std::cout << "[ figures ] localization killed at 11 s, restarted 1 s of wall time later at "
            << restart_t_s << " s of flight; mission resumed at " << resumed_t_s
            << " s; lowest point meanwhile " << min_z << " m\n";
}

}  // namespace
}  // namespace mav
