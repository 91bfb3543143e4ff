#pragma once
// The planning service's core, free of gRPC, protobuf and DDS: the map, the roadmap and the plans
// of libs/planning (PlanningMap, Roadmap, PlanPath: the very code mav-eval planning runs), shared
// by the gRPC threads and the one worker of a WorkQueue.
//
//   LoadMap / UploadMap / BuildRoadmap / LoadRoadmap / SaveRoadmap
//        |  one long operation at a time (a second one: RESOURCE_EXHAUSTED at once)
//        v
//   [WorkQueue "planning", capacity 1] --> worker: PlanningMap::Load*, Roadmap::Build/Load/Save
//        |  the result, checked against the client's deadline, is installed as a new Snapshot
//        v
//   std::atomic<shared_ptr<const Snapshot>>  {map, roadmap}   (immutable once published)
//        ^
//   PlanPath (any gRPC thread, at most max_plans_in_flight at once): takes the snapshot, runs
//   planning::PlanPath on it without locks; a rebuild or reload swaps the pointer and never
//   blocks or breaks the plans in flight, which finish on the snapshot they took.
//
// Deadlines: every call takes the caller's Termination (the service passes a CallWatch's:
// services/common/call_watch.h, the client's deadline and whether the client went away; gRPC
// also cancels the calls still running when a shutdown's grace period ends), and the core adds
// its own cancel flag (Shutdown). A long operation stops when either fires (the library polls
// them) and keeps nothing: the worker returns its product, the calling thread installs it only
// if the deadline has not passed. A plan is stopped by the library (DEADLINE_EXCEEDED or
// CANCELLED) and is stored (StorePlan) only by a caller that checked its deadline first.
//
// Memory, all bounded by options: a map's grids are refused above max_map_memory_bytes before
// they are allocated (planning::EstimateMapMemory); a roadmap of more than max_milestones is
// refused (~6 KB per milestone while OMPL builds, ~1.4 KB once copied out); one snapshot is
// current, plus the ones plans in flight still hold; the last kPlanHistory successful plans
// (a few KB each: paths and the spline) are kept for GetPlan and SampleTrajectory; the runtime
// statistics keep the last 1000 plans.
//
// Thread-safety: every public method may be called from any thread.

#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/common/work_queue.h"
#include "mav/planning/planner.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/roadmap.h"

namespace mav::planning_service {

struct PlannerCoreOptions {
  // Plans computed at once; one more is refused with RESOURCE_EXHAUSTED at once (overload is
  // signalled instead of queued behind the cores). 0 = 2 x the hardware threads: a plan is
  // CPU-bound (~3 ms median on the power plant), so beyond the cores more in flight only adds
  // latency; on 2 cores 4 clients reach the most plans/s and 8 only add 50 % to the p99
  // (docs/benchmarks.md, "Planning service"). Validated [0, 1024].
  int max_plans_in_flight = 0;
  // A map whose grids (obstacle bits + distance map) would need more bytes is refused with
  // RESOURCE_EXHAUSTED before they are allocated. 2 GiB: the power plant needs 49 MB.
  uint64_t max_map_memory_bytes = uint64_t{2} << 30;
  // Largest roadmap BuildRoadmap builds (RESOURCE_EXHAUSTED above): 200 000 milestones need
  // ~1.3 GB while OMPL builds on the power plant. Validated >= 1.
  uint64_t max_milestones = 200000;
  // Threads of the distance transform and of the roadmap's edge costs. Validated [1, 64].
  int threads = 2;

  bool IsValid(std::string* why) const;
  // max_plans_in_flight with 0 resolved.
  int PlansInFlightLimit() const;
};

// What plans run against. Immutable once published; plans in flight keep theirs alive.
struct Snapshot {
  std::shared_ptr<const planning::PlanningMap> map;  // never null in a published snapshot
  std::shared_ptr<const planning::Roadmap> roadmap;  // null until built or loaded
  std::string roadmap_source;                        // "built", or the file it came from
};

// The outcome of one Plan call with what it ran against.
struct PlanOutcome {
  planning::PlanResult result;
  uint64_t map_fingerprint = 0;
  bool used_roadmap = false;
};

// A successful plan kept for GetPlan / SampleTrajectory.
struct StoredPlan {
  std::string id;
  PlanOutcome outcome;
  double sample_dt_s = 0;  // of the request (the reply's samples)
};

struct CoreStatus {
  std::shared_ptr<const Snapshot> snapshot;  // null before the first map
  bool busy = false;                         // a long operation runs
  std::string operation;                     // its name ("LoadMap", "BuildRoadmap", ...)
  std::string stage;                         // its progress stage ("distance map", "roadmap", ...)
  double fraction = 0;                       // of the stage
  double elapsed_s = 0;                      // since the operation started
  std::string last_error;                    // of the last failed long operation
  uint64_t plans = 0;                        // Plan calls answered with a PlanResult
  uint64_t plans_succeeded = 0;
  uint64_t plans_rejected = 0;  // RESOURCE_EXHAUSTED: too many in flight
  uint64_t plans_failed = 0;    // other errors (deadline, invalid argument, no map)
  uint32_t plans_in_flight = 0;
  uint32_t max_plans_in_flight = 0;
  uint32_t plans_stored = 0;
  RuntimeStats planning_ms;  // handler time of the last 1000 answered plans
};

class PlannerCore {
 public:
  // The successful plans kept (contract: "the server keeps the last 16 plans").
  static constexpr size_t kPlanHistory = 16;

  // MAV_CHECKs valid options (the server's own flags, validated by main).
  explicit PlannerCore(PlannerCoreOptions options = {});
  ~PlannerCore();  // Shutdown()
  PlannerCore(const PlannerCore&) = delete;
  PlannerCore& operator=(const PlannerCore&) = delete;

  // The one long-operation slot, held while a long operation is under way (an upload holds it
  // while its bytes arrive, so a second upload is refused before it buffers anything). Released
  // when the last copy goes (the worker's copy goes when its task has run).
  using Slot = std::shared_ptr<void>;
  // RESOURCE_EXHAUSTED "<operation>: <the running one> is running ..." when the slot is taken.
  Result<Slot> Reserve(const std::string& operation);
  // Reports the progress of the operation holding the slot (stage, fraction of it).
  void SetProgress(std::string_view stage, double fraction);

  // Loads a map (the library's errors: NOT_FOUND, DATA_LOSS naming the source, INVALID_ARGUMENT
  // naming the option, RESOURCE_EXHAUSTED above max_map_memory_bytes) and installs it with no
  // roadmap. DEADLINE_EXCEEDED / CANCELLED: nothing replaced. `options.max_memory_bytes` and
  // `options.threads` are the server's.
  Result<planning::MapInfo> LoadMapFile(const std::string& path, planning::MapOptions options,
                                        const Termination& stop);
  // The same from bytes (an upload, the mapping service's map) under a reserved slot.
  Result<planning::MapInfo> LoadMapBytes(const Slot& slot, std::string bytes,
                                         const std::string& source, planning::MapOptions options,
                                         const Termination& stop);

  // Builds a roadmap on the current map and installs it. FAILED_PRECONDITION without a map;
  // RESOURCE_EXHAUSTED above max_milestones or when busy; the library's INVALID_ARGUMENT;
  // DEADLINE_EXCEEDED / CANCELLED: nothing kept.
  Result<planning::RoadmapInfo> BuildRoadmap(planning::RoadmapOptions options,
                                             const Termination& stop);
  // Loads a roadmap file of the current map (library: NOT_FOUND, DATA_LOSS, FAILED_PRECONDITION
  // for another map) and installs it.
  Result<planning::RoadmapInfo> LoadRoadmap(const std::string& path, const Termination& stop);
  // Saves the current roadmap. FAILED_PRECONDITION without one, or when `path` exists and is not
  // a roadmap file (never overwritten); INVALID_ARGUMENT "path: ..." unless it ends in
  // ".mavprm"; IO_ERROR naming the file.
  Result<planning::RoadmapInfo> SaveRoadmap(const std::string& path, const Termination& stop);

  // Plans on the current snapshot (see the file comment). FAILED_PRECONDITION without a map;
  // RESOURCE_EXHAUSTED when max_plans_in_flight plans run; the library's INVALID_ARGUMENT and
  // DEADLINE_EXCEEDED / CANCELLED.
  Result<PlanOutcome> Plan(const planning::PlanRequest& request, const Termination& stop);
  // Counts an answered Plan (the statistics of GetStatus): `handler_ms` is the caller's whole
  // time for it, `success` whether the plan reached SUCCESS.
  void RecordAnswered(bool success, double handler_ms);
  // Counts a Plan that ended in an error other than too many in flight.
  void RecordFailed();
  // Stores a successful plan (the oldest of kPlanHistory goes) and returns its new id.
  std::string StorePlan(const PlanOutcome& outcome, double sample_dt_s);
  // Null for an unknown or forgotten id.
  std::shared_ptr<const StoredPlan> FindPlan(const std::string& id) const;

  // The current snapshot (null before the first map).
  std::shared_ptr<const Snapshot> snapshot() const { return snapshot_.load(); }
  CoreStatus GetStatus() const;
  const PlannerCoreOptions& options() const { return options_; }

  // Cancels the long operation in progress and stops the worker. Idempotent.
  void Shutdown();

 private:
  struct SlotState;

  // Runs `work` on the worker under `slot` until `stop` (or Shutdown) ends it, waits for it,
  // then checks the deadline: a late product is dropped.
  template <typename T, typename Fn>
  Result<T> RunOnWorker(const Slot& slot, const Termination& stop, const char* what, Fn work);
  // Installs `next` as the snapshot when `expected_map` is still the current map (else
  // FAILED_PRECONDITION: the map changed while the operation ran).
  Status Install(std::shared_ptr<const Snapshot> next,
                 const std::shared_ptr<const planning::PlanningMap>& expected_map);
  void RecordError(const Status& status);

  const PlannerCoreOptions options_;
  const int max_in_flight_;
  const std::string id_prefix_;  // plan ids "<prefix>-<n>": distinct across server restarts
  CancelFlag shutdown_;          // plans on the roadmap
  WorkQueue queue_;
  std::atomic<std::shared_ptr<const Snapshot>> snapshot_;
  std::atomic<int> in_flight_{0};

  mutable std::mutex mutex_;
  // Guarded by mutex_.
  bool busy_ = false;
  std::optional<CancelFlag> operation_cancel_;  // of the long operation running, for Shutdown
  std::string operation_;
  std::string stage_;
  double fraction_ = 0;
  int64_t operation_start_ns_ = 0;
  std::string last_error_;
  uint64_t plans_ = 0, plans_succeeded_ = 0, plans_rejected_ = 0, plans_failed_ = 0;
  uint64_t next_plan_ = 1;
  RuntimeWindow planning_ms_;
  std::deque<std::shared_ptr<const StoredPlan>> history_;  // oldest first, <= kPlanHistory
};

}  // namespace mav::planning_service
