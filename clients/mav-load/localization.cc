// mav-load localization: mav.v1.Localization/ProcessStereoPair with 752 x 480 MONO8 stereo
// pairs: N frames of a simulator preset rendered in process (room-easy, EuRoC's raw rig: no
// files needed) or the first N of an EuRoC ASL directory (--euroc). Before the load it
// configures the service (Configure: --method, the frames' calibration inline, an input queue of
// --queue frames, DDS input off): this resets the service's trajectory, so do not aim it at a
// stack that is flying.
//
// The service is one VO session with one worker, and frames must come in time order. The calls
// carry consecutive frames: call n (a counter the client threads share) carries frame n of a
// ping-pong walk through the N frames (0, 1, ..., N-1, N-2, ..., 1, 0, 1, ...: the camera moves
// back and forth without a jump, so tracking stays meaningful) stamped t0 + n * frame period.
// At --concurrency 1 that is the data set played as fast as the service can go. At C > 1 the
// calls queue on the one worker: the rate stays that of one worker and the latency grows by the
// wait in the queue (keep --queue >= C, or calls are refused RESOURCE_EXHAUSTED); and two calls
// sent at once may reach the service in the other order: the later-stamped one is processed, the
// other refused ("t_ns ... is not after the previous frame's"), which mav-load counts as the
// reply OUT_OF_ORDER (an artefact of the load, not an error; not in the latency). Replies are
// tallied by tracking state (INITIALIZING, OK, LOST, DEGRADED).

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "mav/v1/localization.grpc.pb.h"

#include "clients/mav-load/commands.h"
#include "clients/mav-load/frames.h"
#include "clients/mav-load/load.h"
#include "mav/common/time.h"
#include "services/common/grpc_status.h"

namespace mav::load {

namespace {

constexpr char kUsage[] =
    "mav-load localization [--address HOST:PORT|TARGET] --concurrency C --duration S\n"
    "                             [--method sparse|sparse-pixel|sparse-subpixel|dense]\n"
    "                             [--frames N] [--seed S | --euroc DIR] [--queue Q]\n"
    "                             [--deadline-ms D] [--fail-on-errors] [--max-p99-ms X]\n"
    "                             [--json FILE] [--cpu-pid PID]\n\n"
    "Configures mav-localization (this resets its trajectory) and calls\n"
    "mav.v1.Localization/ProcessStereoPair back to back with N frames of room-easy rendered in\n"
    "process (or of --euroc DIR), walked forth and back; call n carries the n-th frame of that\n"
    "walk, stamped t0 + n * period, whichever thread makes it. One VO session, one worker: at\n"
    "C > 1 calls queue (latency grows, rate does not), and a frame overtaken by a later one is\n"
    "refused by the service and counted as the reply OUT_OF_ORDER (not an error, not timed).\n"
    "Replies by tracking state.";

struct LocalizationOptions {
  CommonOptions common;
  std::string method = "sparse";
  FrameSelection frames;
  int64_t queue = 0;  // 0: max(2, concurrency)
};

std::optional<int> ParseOptions(const std::vector<std::string>& args, LocalizationOptions* o) {
  FlagParser flags(kUsage);
  AddCommonFlags(&flags, &o->common, 50052);
  flags.AddString("method", &o->method, "sparse (= sparse-subpixel), sparse-pixel, dense");
  flags.AddInt("frames", &o->frames.frames, "frames to cycle through", 1, 2000);
  flags.AddUint64("seed", &o->frames.seed, "seed of the rendered room-easy frames");
  flags.AddString("euroc", &o->frames.euroc, "read the frames from this EuRoC ASL directory");
  flags.AddInt("queue", &o->queue,
               "the service's input queue, frames (Configure.queue_length; 0 = max(2, C))", 0, 100);
  if (std::optional<int> done = ParseFlags(&flags, args, o->common)) return done;
  if (o->method != "sparse" && o->method != "sparse-pixel" && o->method != "sparse-subpixel" &&
      o->method != "dense") {
    return Usage("--method: '" + o->method +
                 "' (known: sparse, sparse-pixel, sparse-subpixel, "
                 "dense)");
  }
  if (o->common.client == "async") {
    return Usage("--client async: mav-load localization has only a synchronous client");
  }
  if (o->queue == 0) o->queue = std::clamp<int64_t>(o->common.concurrency, 2, 100);
  return std::nullopt;
}

v1::LocalizationMethod MethodOf(const std::string& name) {
  if (name == "sparse-pixel") return v1::LOCALIZATION_METHOD_SPARSE_PIXEL;
  if (name == "dense") return v1::LOCALIZATION_METHOD_DENSE;
  return v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL;
}

Status Configure(const LocalizationOptions& o, const StereoFrames& frames,
                 v1::Localization::Stub* stub) {
  v1::LocalizationConfigureRequest request;
  request.set_method(MethodOf(o.method));
  SetCalibration(frames, request.mutable_calibration()->mutable_calibration());
  request.set_queue_length(static_cast<uint32_t>(o.queue));
  request.set_disable_dds_input(true);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  v1::LocalizationStatus status;
  const grpc::Status s = stub->Configure(&context, request, &status);
  if (!s.ok()) {
    return Status::Unavailable("Configure at " + o.common.address +
                               " failed: " + service_common::GrpcCodeName(s.error_code()) + ": " +
                               s.error_message());
  }
  return Status::Ok();
}

std::string TrackingName(v1::TrackingState state) {
  return WithoutPrefix(v1::TrackingState_Name(state), "TRACKING_STATE_");
}

// What the client threads share: the requests without their time stamps, the call counter.
struct Calls {
  std::shared_ptr<v1::Localization::Stub> stub;
  std::vector<v1::ProcessStereoPairRequest> requests;
  int64_t t0_ns = 0;
  int64_t period_ns = 0;
  std::atomic<uint64_t> next{0};

  // Frame of call n: a walk forth and back through the frames.
  size_t FrameOf(uint64_t n) const {
    const uint64_t count = requests.size();
    if (count == 1) return 0;
    const uint64_t i = n % (2 * count - 2);
    return static_cast<size_t>(i < count ? i : 2 * count - 2 - i);
  }
};

grpc::Status Call(Calls* calls, grpc::ClientContext* context, Reply* reply) {
  const uint64_t n = calls->next.fetch_add(1);
  v1::ProcessStereoPairRequest request = calls->requests[calls->FrameOf(n)];
  request.mutable_stereo()->set_t_ns(calls->t0_ns + static_cast<int64_t>(n) * calls->period_ns);
  v1::ProcessStereoPairResponse response;
  grpc::Status status = calls->stub->ProcessStereoPair(context, request, &response);
  if (status.ok()) {
    reply->name = TrackingName(response.tracking_state());
    return status;
  }
  if (status.error_code() == grpc::StatusCode::INVALID_ARGUMENT &&
      status.error_message().find("is not after the previous frame's") != std::string::npos) {
    *reply = Reply{"OUT_OF_ORDER", false};
    return grpc::Status::OK;
  }
  return status;
}

}  // namespace

int RunLocalization(const std::vector<std::string>& args) {
  LocalizationOptions options;
  if (std::optional<int> done = ParseOptions(args, &options)) return *done;
  Result<std::shared_ptr<grpc::Channel>> channel = Connect(options.common, "mav.v1.Localization");
  if (!channel.ok()) return Fail(channel.status().message());
  const int64_t render_ns = MonotonicNowNs();
  Result<StereoFrames> frames = LoadFrames(options.frames);
  if (!frames.ok()) return Fail(frames.status().message());
  std::printf("frames:   %zu of %s, %dx%d, %s, in %.1f s\n", frames->t_ns.size(),
              frames->source.c_str(), frames->left[0].cols, frames->left[0].rows,
              frames->rectified ? "rectified" : "raw", SecondsSince(render_ns));
  auto calls = std::make_shared<Calls>();
  calls->stub = v1::Localization::NewStub(*channel);
  if (Status s = Configure(options, *frames, calls->stub.get()); !s.ok()) return Fail(s.message());
  for (size_t k = 0; k < frames->t_ns.size(); ++k) {
    v1::ProcessStereoPairRequest request;
    SetStereoImages(*frames, k, request.mutable_stereo());
    calls->requests.push_back(std::move(request));
  }
  calls->t0_ns = frames->t_ns.front();
  calls->period_ns = frames->period_ns;

  LoadRun run;
  run.command = "localization";
  run.what = options.method + ", " + std::to_string(calls->requests.size()) + " frames, queue " +
             std::to_string(options.queue);
  run.channel = *channel;
  run.call = [calls](grpc::ClientContext* context, Reply* reply) {
    return Call(calls.get(), context, reply);
  };
  return RunLoad(options.common, run);
}

}  // namespace mav::load
