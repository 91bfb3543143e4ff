#include "clients/mavctl/control_commands.h"
#include "clients/mavctl/connection.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <thread>

#include "mav/v1/control.grpc.pb.h"
#include "mav/v1/simulator.grpc.pb.h"

#include "mav/common/text.h"
#include "mav/common/time.h"
#include "mav/sim/flight_task.h"
#include "mav/transport/flags.h"
#include "services/control/convert.h"

namespace mav::mavctl {

namespace {

using transport::FlagParser;

constexpr int64_t kControlPort = 50055;
constexpr char kControlPortEnv[] = "MAV_CONTROL_PORT";
constexpr int64_t kSimulatorPort = 50051;
constexpr char kSimulatorPortEnv[] = "MAV_SIMULATOR_PORT";

constexpr char kCtlUsage[] =
    "Usage: mavctl ctl <subcommand> [flags]   (mavctl ctl <subcommand> --help for its flags)\n"
    "  ctl configure [--task t3_1|FILE.yaml] [--controller paper|lee] [--lockstep]\n"
    "                [--pose-frame NAME] [--no-dds]\n"
    "  ctl arm [--in-air] | ctl disarm\n"
    "  ctl hover --position X,Y,Z [--yaw RAD] [--immediate] [--max-speed V] [--max-accel A]\n"
    "  ctl trajectory (--to X,Y,Z --duration S | --plan ID --planning HOST:PORT)\n"
    "                 [--start-t-ns T] [--offset X,Y,Z] [--allow-jump]\n"
    "  ctl gains [--position-omega W ...] | --lee [--lee-position K ...]\n"
    "  ctl state | ctl status\n"
    "Common flags: --address A (127.0.0.1), --port P (50055, env MAV_CONTROL_PORT),\n"
    "--timeout S (RPC deadline, 10 s).\n";

constexpr char kFlightUsage[] =
    "Usage: mavctl sim flight <subcommand> [flags]\n"
    "  sim flight load (--task NAME | --file SERVER_PATH | --yaml LOCAL_FILE) [--seed S]\n"
    "                  [--lockstep] [--rate F] [--step-timeout S] [--map PATH]\n"
    "  sim flight run [--until S] [--pause-on-goal] [--wait] [--wait-timeout S]\n"
    "  sim flight pause | sim flight status\n"
    "Common flags: --address A (127.0.0.1), --port P (50051, env MAV_SIMULATOR_PORT),\n"
    "--timeout S (RPC deadline, 10 s).\n";

struct ControlConnection : mavctl::Connection {
  ControlConnection() : mavctl::Connection(kControlPort, kControlPortEnv) {}
};
struct SimulatorConnection : mavctl::Connection {
  SimulatorConnection() : mavctl::Connection(kSimulatorPort, kSimulatorPortEnv) {}
};

int Usage(const std::string& message) {
  std::cerr << "mavctl: " << message << "\n";
  return 2;
}

std::shared_ptr<grpc::Channel> Channel(const mavctl::Connection& connection) {
  return mavctl::MakeChannel(connection);
}

void SetVector(const std::vector<double>& v, v1::Vector3* out) {
  out->set_x(v[0]);
  out->set_y(v[1]);
  out->set_z(v[2]);
}

std::string Vec(const v1::Vector3& v) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(3) << "(" << v.x() << ", " << v.y() << ", " << v.z()
      << ")";
  return out.str();
}

const char* ModeText(v1::ControlMode mode) {
  switch (mode) {
    case v1::CONTROL_MODE_DISARMED:
      return "DISARMED";
    case v1::CONTROL_MODE_HOVER:
      return "HOVER";
    case v1::CONTROL_MODE_TRAJECTORY:
      return "TRAJECTORY";
    case v1::CONTROL_MODE_FAILSAFE:
      return "FAILSAFE";
    default:
      return "UNSPECIFIED";
  }
}

void PrintStats(const char* label, const v1::RuntimeStats& s) {
  std::cout << label << "mean " << s.mean_ms() << " ms, median " << s.median_ms() << " ms, p95 "
            << s.p95_ms() << " ms, p99 " << s.p99_ms() << " ms, max " << s.max_ms() << " ms ("
            << s.count() << ")\n";
}

// "2.35 s" (two decimals).
std::string Seconds(double s) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.2f s", s);
  return text;
}

void PrintControlStatus(const v1::ControlStatus& s) {
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "mode:       " << ModeText(s.mode()) << (s.armed() ? ", armed" : ", disarmed")
            << (s.configured() ? "" : " (not configured)") << ", controller "
            << (s.controller() == v1::CONTROLLER_TYPE_LEE ? "lee" : "paper")
            << (s.config().lockstep() ? ", lock-step" : "") << ", DDS input "
            << (s.dds_input() ? "on" : "off") << "\n"
            << "estimator:  "
            << (s.estimator_stale() ? "STALE (its inputs stopped)"
                                    : (s.estimator_converged() ? "converged" : "not converged"))
            << ", " << s.imu_samples() << " IMU samples (" << s.imu_rejected() << " rejected, "
            << s.imu_repeated() << " repeated), " << s.poses() << " poses merged ("
            << s.poses_dropped() << " dropped, " << s.poses_rejected() << " rejected)\n"
            << std::setprecision(1) << "rates:      IMU " << s.imu_rate_hz() << " Hz, poses "
            << s.pose_rate_hz() << " Hz (per wall second); " << s.imu_publishers_alive()
            << " IMU publisher(s) alive; last IMU sample "
            << (s.has_imu_age_s() ? Seconds(s.imu_age_s()) + " ago" : "never") << ", last pose "
            << (s.has_pose_age_s() ? Seconds(s.pose_age_s()) + " ago (IMU time)" : "never")
            << (s.takeover_pending() ? "; --takeover pending" : "") << "\n"
            << std::setprecision(4) << "commands:   " << s.commands() << " published to "
            << s.actuator_subscribers() << " subscriber(s), " << s.saturated_steps()
            << " saturated steps, timeouts IMU " << s.imu_timeouts() << " / pose "
            << s.pose_timeouts() << "\n"
            << "tracking:   position RMS " << s.position_rms_m() << " m, rate RMS "
            << s.angular_rate_rms_radps() << " rad/s (estimate vs reference, since Arm)\n";
  PrintStats("step:       ", s.step_ms());
  PrintStats("loop:       ", s.loop_ms());
  if (s.pose_latency().total().count() > 0) {
    const v1::PoseLatency& l = s.pose_latency();
    PrintStats("vision pose, capture -> estimator: ", l.total());
    PrintStats("  frame over DDS:    ", l.frame_transport());
    PrintStats("  localization:      ", l.localization());
    PrintStats("  pose over DDS:     ", l.pose_transport());
    PrintStats("  into the estimator:", l.merge());
  }
  if (!s.last_error().empty()) {
    std::cout << "last error (" << Seconds(s.last_error_age_s()) << " ago): " << s.last_error()
              << "\n";
  }
  std::cout.unsetf(std::ios::fixed);
}

void PrintControlState(const v1::ControlState& s) {
  std::cout << "mode:       " << ModeText(s.mode()) << (s.armed() ? ", armed" : ", disarmed")
            << "\n";
  if (!s.configured()) return;
  const v1::VehicleEstimate& e = s.estimate();
  const v1::Quaternion& q = e.t_world_body().orientation();
  std::cout << std::fixed << std::setprecision(4) << "estimate:   t " << e.t_ns() << " ns, p "
            << Vec(e.t_world_body().position()) << " m, q wxyz (" << q.w() << ", " << q.x() << ", "
            << q.y() << ", " << q.z() << "), v " << Vec(e.velocity()) << " m/s\n"
            << "offsets:    accel " << Vec(e.accel_bias()) << " m/s^2, gyro " << Vec(e.gyro_bias())
            << " rad/s; last pose " << e.last_pose_t_ns() << " ns, " << e.last_pose_delay_ms()
            << " ms late\n"
            << "reference:  p " << Vec(s.reference().position()) << " m, v "
            << Vec(s.reference().velocity()) << " m/s, yaw " << s.reference().yaw_rad()
            << " rad; trajectory " << s.trajectory_t_s() << " / " << s.trajectory_duration_s()
            << " s\n"
            << "errors:     position " << Vec(s.position_error()) << " m, velocity "
            << Vec(s.velocity_error()) << " m/s; integral " << Vec(s.integral())
            << " m/s^2; disturbance " << Vec(s.disturbance()) << " m/s^2\n"
            << "rotors:    ";
  for (double w : s.rotor_speeds_radps()) std::cout << " " << std::setprecision(1) << w;
  std::cout << " rad/s\n";
  std::cout.unsetf(std::ios::fixed);
}

int CallControl(const ControlConnection& connection, const std::string& rpc,
                const std::function<grpc::Status(v1::Control::Stub*, grpc::ClientContext*,
                                                 v1::ControlStatus*)>& call) {
  auto stub = v1::Control::NewStub(Channel(connection));
  v1::ControlStatus response;
  if (int rc = CallUnary(connection, rpc,
                         [&](grpc::ClientContext* c) { return call(stub.get(), c, &response); })) {
    return rc;
  }
  PrintControlStatus(response);
  return 0;
}

int Configure(const std::vector<std::string>& args) {
  ControlConnection connection;
  FlagParser flags("mavctl ctl configure",
                   "Configures mav-control: for a flight task (what the contest told the teams:\n"
                   "vehicle, sensor rates, noise, mountings) or with the library defaults.");
  AddConnectionFlags(&flags, &connection);
  std::string task, controller = "paper", pose_frame, plant_map = sim::DefaultPlantMapPath();
  bool lockstep = false, no_dds = false;
  flags.AddString("task", &task, "t3_1 ... t4_3, or a task file .yaml (read here)");
  flags.AddString("controller", &controller, "paper|lee");
  flags.AddBool("lockstep", &lockstep, "the IMU comes from a lock-stepped simulator");
  flags.AddString("pose-frame", &pose_frame,
                  "child_frame_id of the (first) pose source (default pose_sensor0)");
  flags.AddBool("no-dds", &no_dds, "do not subscribe to the IMU and pose topics");
  flags.AddString("plant-map", &plant_map, "--task t4_3: the power plant's OctoMap");
  ParseOrExit(&flags, &connection, args);
  if (controller != "paper" && controller != "lee") {
    return Usage("--controller: " + QuoteForError(controller) + " is not paper or lee");
  }
  const control::ControllerType type =
      controller == "lee" ? control::ControllerType::kLee : control::ControllerType::kPaper;
  v1::ControlConfigureRequest request;
  if (!task.empty()) {
    Result<dataset::FlightTask> spec = sim::FlightTaskFromSpec(task, plant_map);
    if (!spec.ok()) return Usage("--task: " + spec.status().message());
    control_service::ToProto(control_service::ConfigForFlightTask(*spec, type, lockstep), &request);
  } else {
    request.set_controller(type == control::ControllerType::kLee ? v1::CONTROLLER_TYPE_LEE
                                                                 : v1::CONTROLLER_TYPE_PAPER);
    request.set_lockstep(lockstep);
  }
  if (!pose_frame.empty()) {
    if (request.estimator().pose_sources_size() == 0)
      request.mutable_estimator()->add_pose_sources();
    request.mutable_estimator()->mutable_pose_sources(0)->set_frame_id(pose_frame);
  }
  request.set_disable_dds_input(no_dds);
  return CallControl(connection, "Configure",
                     [&](auto* stub, auto* c, auto* r) { return stub->Configure(c, request, r); });
}

int Hover(const std::vector<std::string>& args) {
  ControlConnection connection;
  FlagParser flags("mavctl ctl hover", "Flies to a position (smooth move) and holds it.");
  AddConnectionFlags(&flags, &connection);
  std::string position;
  double yaw = 0, max_speed = 0, max_accel = 0;
  bool immediate = false;
  flags.AddString("position", &position, "X,Y,Z in the world frame, m");
  flags.AddDouble("yaw", &yaw, "yaw, rad");
  flags.AddBool("immediate", &immediate, "hold it at once (no move)");
  flags.AddDouble("max-speed", &max_speed, "move's speed limit, m/s (0 = configured)");
  flags.AddDouble("max-accel", &max_accel, "move's acceleration limit, m/s^2 (0 = configured)");
  ParseOrExit(&flags, &connection, args);
  Result<std::vector<double>> p = ParseNumbers(position, 3, "--position");
  if (!p.ok()) return Usage(p.status().message());
  v1::HoverRequest request;
  SetVector(*p, request.mutable_position());
  request.set_yaw_rad(yaw);
  request.set_immediate(immediate);
  if (max_speed != 0 || max_accel != 0) {
    request.mutable_limits()->set_max_speed_mps(max_speed);
    request.mutable_limits()->set_max_accel_mps2(max_accel);
  }
  return CallControl(connection, "Hover",
                     [&](auto* stub, auto* c, auto* r) { return stub->Hover(c, request, r); });
}

// A rest-to-rest quintic from `from` to `to` in `duration_s`:
// p(tau) = from + d (10 u^3 - 15 u^4 + 6 u^5), u = tau / T.
void RestToRestQuintic(const v1::Vector3& from, const std::vector<double>& to, double duration_s,
                       v1::PolynomialTrajectory* out) {
  v1::PolynomialSegment* s = out->add_segments();
  s->set_duration_s(duration_s);
  const double start[3] = {from.x(), from.y(), from.z()};
  google::protobuf::RepeatedField<double>* axes[3] = {s->mutable_x(), s->mutable_y(),
                                                      s->mutable_z()};
  const double t = duration_s;
  for (int a = 0; a < 3; ++a) {
    const double d = to[static_cast<size_t>(a)] - start[a];
    for (double c : {start[a], 0.0, 0.0, 10 * d / (t * t * t), -15 * d / (t * t * t * t),
                     6 * d / (t * t * t * t * t)}) {
      axes[a]->Add(c);
    }
  }
  out->set_duration_s(duration_s);
}

int Trajectory(const std::vector<std::string>& args) {
  ControlConnection connection;
  FlagParser flags("mavctl ctl trajectory",
                   "Flies a trajectory: a rest-to-rest quintic from the current reference to\n"
                   "--to in --duration, or a plan of a Planning service.");
  AddConnectionFlags(&flags, &connection);
  std::string to, plan, planning, offset;
  double duration = 0;
  int64_t start_t_ns = 0;
  bool allow_jump = false;
  flags.AddString("to", &to, "X,Y,Z end point, m");
  flags.AddDouble("duration", &duration, "--to: duration, s");
  flags.AddString("plan", &plan, "a plan id of the planning service");
  flags.AddString("planning", &planning, "--plan: host:port of mav-planning");
  flags.AddInt("start-t-ns", &start_t_ns, "start on the controller's time line (0 = now)");
  flags.AddString("offset", &offset, "X,Y,Z added to the trajectory, m");
  flags.AddBool("allow-jump", &allow_jump, "accept a start far from the current reference");
  ParseOrExit(&flags, &connection, args);
  if (to.empty() == plan.empty())
    return Usage("ctl trajectory needs exactly one of --to or --plan");
  v1::SetTrajectoryRequest request;
  auto stub = v1::Control::NewStub(Channel(connection));
  if (!to.empty()) {
    Result<std::vector<double>> end = ParseNumbers(to, 3, "--to");
    if (!end.ok()) return Usage(end.status().message());
    if (!(duration > 0)) return Usage("--duration: must be > 0 s");
    v1::ControlState state;
    if (int rc = CallUnary(connection, "GetState", [&](grpc::ClientContext* c) {
          return stub->GetState(c, v1::ControlGetStateRequest(), &state);
        })) {
      return rc;
    }
    RestToRestQuintic(state.reference().position(), *end, duration, request.mutable_trajectory());
  } else {
    request.mutable_plan()->set_plan_id(plan);
    request.mutable_plan()->set_planning_address(planning);
  }
  if (!offset.empty()) {
    Result<std::vector<double>> o = ParseNumbers(offset, 3, "--offset");
    if (!o.ok()) return Usage(o.status().message());
    SetVector(*o, request.mutable_offset());
  }
  request.set_start_t_ns(start_t_ns);
  request.set_allow_jump(allow_jump);
  v1::ControlStatus response;
  if (int rc = CallUnary(connection, "SetTrajectory", [&](grpc::ClientContext* c) {
        return stub->SetTrajectory(c, request, &response);
      })) {
    return rc;
  }
  PrintControlStatus(response);
  return 0;
}

int Gains(const std::vector<std::string>& args) {
  ControlConnection connection;
  FlagParser flags("mavctl ctl gains",
                   "Replaces the controller's gains (0 = default; the integral state is kept).");
  AddConnectionFlags(&flags, &connection);
  double position_omega = 0, position_zeta = 0, integral = 0, attitude_omega = 0, attitude_zeta = 0,
         yaw_omega = 0, yaw_zeta = 0;
  double lee_position = 0, lee_velocity = 0, lee_attitude = 0, lee_rate = 0;
  bool lee = false;
  flags.AddDouble("position-omega", &position_omega,
                  "paper: translational omega, rad/s (all axes)");
  flags.AddDouble("position-zeta", &position_zeta, "paper: translational damping");
  flags.AddDouble("integral", &integral, "paper: integral gain K_i, 1/s^3");
  flags.AddDouble("attitude-omega", &attitude_omega, "paper: roll/pitch omega, rad/s");
  flags.AddDouble("attitude-zeta", &attitude_zeta, "paper: roll/pitch damping");
  flags.AddDouble("yaw-omega", &yaw_omega, "paper: yaw omega, rad/s");
  flags.AddDouble("yaw-zeta", &yaw_zeta, "paper: yaw damping");
  flags.AddBool("lee", &lee, "set the Lee controller's gains instead");
  flags.AddDouble("lee-position", &lee_position, "lee: position gain, N/m (all axes)");
  flags.AddDouble("lee-velocity", &lee_velocity, "lee: velocity gain, N s/m");
  flags.AddDouble("lee-attitude", &lee_attitude, "lee: roll/pitch attitude gain, N m/rad");
  flags.AddDouble("lee-rate", &lee_rate, "lee: roll/pitch angular-rate gain, N m s/rad");
  ParseOrExit(&flags, &connection, args);
  v1::SetGainsRequest request;
  auto all = [](double v, v1::Vector3* out) {
    out->set_x(v);
    out->set_y(v);
    out->set_z(v);
  };
  if (lee) {
    v1::LeeGains* g = request.mutable_lee_gains();
    all(lee_position, g->mutable_position_gain());
    all(lee_velocity, g->mutable_velocity_gain());
    g->mutable_attitude_gain()->set_x(lee_attitude);
    g->mutable_attitude_gain()->set_y(lee_attitude);
    g->mutable_angular_rate_gain()->set_x(lee_rate);
    g->mutable_angular_rate_gain()->set_y(lee_rate);
  } else {
    v1::ControllerGains* g = request.mutable_gains();
    all(position_omega, g->mutable_position_omega_radps());
    all(position_zeta, g->mutable_position_zeta());
    all(integral, g->mutable_integral_gain());
    g->set_attitude_omega_radps(attitude_omega);
    g->set_attitude_zeta(attitude_zeta);
    g->set_yaw_omega_radps(yaw_omega);
    g->set_yaw_zeta(yaw_zeta);
  }
  return CallControl(connection, "SetGains",
                     [&](auto* stub, auto* c, auto* r) { return stub->SetGains(c, request, r); });
}

// ---- sim flight
// -----------------------------------------------------------------------------------

const char* FlightStateText(v1::FlightState state) {
  switch (state) {
    case v1::FLIGHT_STATE_IDLE:
      return "IDLE";
    case v1::FLIGHT_STATE_LOADED:
      return "LOADED";
    case v1::FLIGHT_STATE_RUNNING:
      return "RUNNING";
    case v1::FLIGHT_STATE_PAUSED:
      return "PAUSED";
    case v1::FLIGHT_STATE_FINISHED:
      return "FINISHED";
    default:
      return "UNSPECIFIED";
  }
}

void PrintFlightStatus(const v1::FlightStatus& s) {
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "state:      " << FlightStateText(s.state());
  if (!s.pause_reason().empty()) std::cout << " (" << s.pause_reason() << ")";
  std::cout << "\n";
  if (s.has_task()) {
    const v1::FlightTaskSummary& t = s.task();
    std::cout << "task:       " << t.name() << " (" << t.kind() << ", " << t.duration_s()
              << " s, seed " << t.seed() << ", "
              << (t.lockstep() ? std::string("lock-step")
                               : "real time x" + std::to_string(t.real_time_factor()))
              << ")" << (t.map_path().empty() ? "" : ", map " + t.map_path()) << "\n";
  }
  std::cout << "time:       " << NsToSeconds(s.t_ns()) << " s, " << s.steps() << " steps, "
            << std::setprecision(1) << s.speed_factor() << "x real time since the last start\n"
            << "published:  " << s.imu_published() << " imu, " << s.poses_published() << " poses, "
            << s.ground_truth_published() << " ground truth\n"
            << "commands:   " << s.commands_received() << " received from " << s.actuator_writers()
            << " writer(s), " << s.commands_rejected() << " rejected, " << s.stale_steps()
            << " stale steps\n"
            << "failsafe:   "
            << (s.failsafe_active() ? "ACTIVE (no valid command: level, descending)" : "off")
            << ", engaged " << s.failsafe_engagements() << " time(s), " << std::setprecision(1)
            << s.failsafe_s() << " s flown by it\n"
            << std::setprecision(3) << "vehicle:    " << Vec(s.position()) << " m"
            << (s.lifted_off() ? ", lifted off" : ", on the ground") << ", goal " << s.goal_index()
            << ", " << s.collisions_size() << " collision(s)\n";
  for (const v1::FlightCollision& c : s.collisions()) {
    std::cout << "  collision at " << c.t_s() << " s " << Vec(c.position()) << ": " << c.what()
              << "\n";
  }
  PrintStats("step:       ", s.step_ms());
  PrintStats("cmd wait:   ", s.command_wait_ms());
  if (!s.last_error().empty()) {
    std::cout << "last error (" << Seconds(s.last_error_age_s()) << " ago): " << s.last_error()
              << "\n";
  }
  if (s.has_score()) {
    const v1::FlightScore& sc = s.score();
    std::cout << std::setprecision(4) << "score:      " << sc.points() << " of " << sc.max_points()
              << " points; position RMS " << sc.position_rms_m() << " m, angular-rate RMS "
              << sc.angular_rate_rms_radps() << " rad/s, settling " << sc.settling_time_s() << " s"
              << (sc.all_settled() ? "" : " (not all settled)") << ", " << sc.collisions()
              << " collisions\n";
    for (const v1::FlightGoalScore& g : sc.goals()) {
      std::cout << "  goal " << g.goal() << ": from " << g.from_s() << " s, "
                << (g.settled() ? "settled " : "never settled ") << g.settling_time_s()
                << " s, window " << g.window_start_s() << " s, position RMS " << g.position_rms_m()
                << " m, rate RMS " << g.angular_rate_rms_radps() << " rad/s, points "
                << g.position_points() << " + " << g.angular_rate_points() << " + "
                << g.settling_points();
      if (g.path_length_m() > 0) {
        std::cout << "; leg " << g.path_length_m() << " m in " << g.flight_time_s() << " s, mean "
                  << g.mean_speed_mps() << " m/s, peak " << g.peak_speed_mps() << " m/s";
      }
      std::cout << "\n";
    }
  }
  std::cout.unsetf(std::ios::fixed);
}

int CallFlight(const SimulatorConnection& connection, const std::string& rpc,
               const std::function<grpc::Status(v1::Simulator::Stub*, grpc::ClientContext*,
                                                v1::FlightStatus*)>& call,
               v1::FlightStatus* response, bool print) {
  auto stub = v1::Simulator::NewStub(Channel(connection));
  if (int rc = CallUnary(connection, rpc,
                         [&](grpc::ClientContext* c) { return call(stub.get(), c, response); })) {
    return rc;
  }
  if (print) PrintFlightStatus(*response);
  return 0;
}

int FlightLoad(const std::vector<std::string>& args) {
  SimulatorConnection connection;
  FlagParser flags("mavctl sim flight load", "Loads a flight task into the simulator.");
  AddConnectionFlags(&flags, &connection);
  std::string task, file, yaml, map;
  int64_t seed = 1;
  bool lockstep = false;
  double rate = 0, step_timeout = 0;
  flags.AddString("task", &task, "a built-in task: t3_1 t3_2 t3_3 t4_1 t4_2 t4_3");
  flags.AddString("file", &file, "a task file on the server");
  flags.AddString("yaml", &yaml, "a task file read here and sent as text");
  flags.AddInt("seed", &seed, "sensor noise seed");
  flags.AddBool("lockstep", &lockstep, "wait for each step's actuator command");
  flags.AddDouble("rate", &rate, "real time: factor (0 = 1)");
  flags.AddDouble("step-timeout", &step_timeout, "lock-step: wait per step, s (0 = 2 s)");
  flags.AddString("map", &map, "replace the task's map (OctoMap .bt on the server)");
  ParseOrExit(&flags, &connection, args);
  if (static_cast<int>(!task.empty()) + static_cast<int>(!file.empty()) +
          static_cast<int>(!yaml.empty()) !=
      1) {
    return Usage("sim flight load needs exactly one of --task, --file or --yaml");
  }
  if (seed < 0) return Usage("--seed: must be >= 0");
  v1::LoadFlightTaskRequest request;
  if (!task.empty()) request.set_builtin(task);
  if (!file.empty()) request.set_path(file);
  if (!yaml.empty()) {
    std::ifstream in(yaml);
    if (!in) return Usage("--yaml: cannot read " + yaml);
    std::stringstream text;
    text << in.rdbuf();
    request.set_yaml(text.str());
  }
  request.set_seed(static_cast<uint64_t>(seed));
  request.set_lockstep(lockstep);
  request.set_real_time_factor(rate);
  request.set_lockstep_timeout_s(step_timeout);
  request.set_map_path(map);
  v1::FlightStatus response;
  return CallFlight(
      connection, "LoadFlightTask",
      [&](auto* stub, auto* c, auto* r) { return stub->LoadFlightTask(c, request, r); }, &response,
      true);
}

int FlightRun(const std::vector<std::string>& args) {
  SimulatorConnection connection;
  FlagParser flags("mavctl sim flight run",
                   "Starts or resumes the flight; --wait returns when it pauses or ends.");
  AddConnectionFlags(&flags, &connection);
  double until = 0, wait_timeout = 600;
  bool pause_on_goal = false, wait = false;
  flags.AddDouble("until", &until, "pause at this simulated time, s (0 = to the end)");
  flags.AddBool("pause-on-goal", &pause_on_goal, "pause when a goal is published");
  flags.AddBool("wait", &wait, "wait until the flight is no longer RUNNING");
  flags.AddDouble("wait-timeout", &wait_timeout, "--wait: give up after S seconds");
  ParseOrExit(&flags, &connection, args);
  v1::StartFlightRequest request;
  request.set_run_until_s(until);
  request.set_pause_on_goal(pause_on_goal);
  v1::FlightStatus status;
  if (int rc = CallFlight(
          connection, "StartFlight",
          [&](auto* stub, auto* c, auto* r) { return stub->StartFlight(c, request, r); }, &status,
          !wait)) {
    return rc;
  }
  if (!wait) return 0;
  const int64_t give_up_ns = MonotonicNowNs() + SecondsToNs(wait_timeout);
  while (status.state() == v1::FLIGHT_STATE_RUNNING) {
    if (MonotonicNowNs() > give_up_ns) {
      std::cerr << "mavctl: the flight still runs after " << wait_timeout
                << " s (--wait-timeout)\n";
      return 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (int rc = CallFlight(
            connection, "GetFlightStatus",
            [&](auto* stub, auto* c, auto* r) {
              return stub->GetFlightStatus(c, v1::GetFlightStatusRequest(), r);
            },
            &status, false)) {
      return rc;
    }
  }
  PrintFlightStatus(status);
  // A lock-step timeout is a failure of the loop, not of this call: say so in the exit status.
  return status.last_error().rfind("lock-step", 0) == 0 && status.state() == v1::FLIGHT_STATE_PAUSED
             ? 1
             : 0;
}

}  // namespace

int ControlCommand(const std::vector<std::string>& args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::cout << kCtlUsage;
    return args.empty() ? 2 : 0;
  }
  const std::string& sub = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (sub == "configure") return Configure(rest);
  if (sub == "hover") return Hover(rest);
  if (sub == "trajectory") return Trajectory(rest);
  if (sub == "gains") return Gains(rest);
  if (sub == "arm" || sub == "disarm" || sub == "status") {
    ControlConnection connection;
    FlagParser flags("mavctl ctl " + sub, "");
    AddConnectionFlags(&flags, &connection);
    bool in_air = false;
    if (sub == "arm") {
      flags.AddBool("in-air", &in_air,
                    "take over a vehicle already flying (its controller was restarted): hold it "
                    "where it is");
    }
    ParseOrExit(&flags, &connection, rest);
    if (sub == "arm") {
      v1::ArmRequest request;
      request.set_in_air(in_air);
      return CallControl(connection, "Arm", [&request](auto* stub, auto* c, auto* r) {
        return stub->Arm(c, request, r);
      });
    }
    if (sub == "disarm") {
      return CallControl(connection, "Disarm", [](auto* stub, auto* c, auto* r) {
        return stub->Disarm(c, v1::DisarmRequest(), r);
      });
    }
    return CallControl(connection, "GetStatus", [](auto* stub, auto* c, auto* r) {
      return stub->GetStatus(c, v1::ControlGetStatusRequest(), r);
    });
  }
  if (sub == "state") {
    ControlConnection connection;
    FlagParser flags("mavctl ctl state", "");
    AddConnectionFlags(&flags, &connection);
    ParseOrExit(&flags, &connection, rest);
    auto stub = v1::Control::NewStub(Channel(connection));
    v1::ControlState state;
    if (int rc = CallUnary(connection, "GetState", [&](grpc::ClientContext* c) {
          return stub->GetState(c, v1::ControlGetStateRequest(), &state);
        })) {
      return rc;
    }
    PrintControlState(state);
    return 0;
  }
  std::cerr << "mavctl: unknown ctl subcommand '" << sub << "'\n" << kCtlUsage;
  return 2;
}

int FlightCommand(const std::vector<std::string>& args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::cout << kFlightUsage;
    return args.empty() ? 2 : 0;
  }
  const std::string& sub = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (sub == "load") return FlightLoad(rest);
  if (sub == "run") return FlightRun(rest);
  if (sub == "pause" || sub == "status") {
    SimulatorConnection connection;
    FlagParser flags("mavctl sim flight " + sub, "");
    AddConnectionFlags(&flags, &connection);
    ParseOrExit(&flags, &connection, rest);
    v1::FlightStatus status;
    return CallFlight(
        connection, sub == "pause" ? "PauseFlight" : "GetFlightStatus",
        [&](auto* stub, auto* c, auto* r) {
          return sub == "pause" ? stub->PauseFlight(c, v1::PauseFlightRequest(), r)
                                : stub->GetFlightStatus(c, v1::GetFlightStatusRequest(), r);
        },
        &status, true);
  }
  std::cerr << "mavctl: unknown sim flight subcommand '" << sub << "'\n" << kFlightUsage;
  return 2;
}

}  // namespace mav::mavctl
