#include "services/planning/planner_core.h"

#include <chrono>
#include <cstdio>
#include <string_view>
#include <thread>
#include <utility>

#include "mav/common/file.h"
#include "mav/common/log.h"
#include "mav/common/text.h"
#include "mav/common/time.h"

namespace mav::planning_service {

namespace {

constexpr size_t kStatsWindow = 1000;

bool EndsWith(const std::string& s, std::string_view suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string InstancePrefix() {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%08x", static_cast<unsigned>(WallNowNs() / 1000 & 0xffffffff));
  return buf;
}

}  // namespace

bool PlannerCoreOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (max_plans_in_flight < 0 || max_plans_in_flight > 1024) {
    return fail("max_plans_in_flight: must be in [0, 1024], got " +
                std::to_string(max_plans_in_flight));
  }
  if (max_map_memory_bytes < 1) return fail("max_map_memory_bytes: must be > 0");
  if (max_milestones < 1) return fail("max_milestones: must be >= 1");
  if (threads < 1 || threads > 64) {
    return fail("threads: must be in [1, 64], got " + std::to_string(threads));
  }
  return true;
}

int PlannerCoreOptions::PlansInFlightLimit() const {
  if (max_plans_in_flight > 0) return max_plans_in_flight;
  return 2 * static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

// Clears the core's busy flag when the last copy of the slot goes.
struct PlannerCore::SlotState {
  explicit SlotState(PlannerCore* owner) : core(owner) {}
  SlotState(const SlotState&) = delete;
  SlotState& operator=(const SlotState&) = delete;
  PlannerCore* core;
  ~SlotState() {
    std::lock_guard<std::mutex> lock(core->mutex_);
    core->busy_ = false;
    core->operation_.clear();
    core->stage_.clear();
    core->fraction_ = 0;
  }
};

PlannerCore::PlannerCore(PlannerCoreOptions options)
    : options_(options),
      max_in_flight_(options.PlansInFlightLimit()),
      id_prefix_(InstancePrefix()),
      queue_(WorkQueueOptions::Named("planning", 1)),
      planning_ms_(kStatsWindow) {
  std::string why;
  MAV_CHECK(options_.IsValid(&why)) << why;
}

PlannerCore::~PlannerCore() { Shutdown(); }

void PlannerCore::Shutdown() {
  shutdown_.Cancel();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (operation_cancel_) operation_cancel_->Cancel();
  }
  queue_.Stop("the planning service is shutting down");
}

Result<PlannerCore::Slot> PlannerCore::Reserve(const std::string& operation) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (busy_) {
    const std::string progress =
        stage_.empty()
            ? ""
            : " (" + stage_ + ", " + std::to_string(static_cast<int>(fraction_ * 100)) + " %)";
    return Status::ResourceExhausted(operation + ": " + operation_ + " is running" + progress +
                                     "; one long operation at a time, retry when it is done");
  }
  busy_ = true;
  operation_ = operation;
  stage_.clear();
  fraction_ = 0;
  operation_start_ns_ = MonotonicNowNs();
  return Slot(std::make_shared<SlotState>(this));
}

void PlannerCore::SetProgress(std::string_view stage, double fraction) {
  std::lock_guard<std::mutex> lock(mutex_);
  stage_ = std::string(stage);
  fraction_ = fraction;
}

void PlannerCore::RecordError(const Status& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  last_error_ = status.ToString();
}

template <typename T, typename Fn>
Result<T> PlannerCore::RunOnWorker(const Slot& slot, const Termination& stop, const char* what,
                                   Fn work) {
  CancelFlag cancel;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    operation_cancel_ = cancel;
  }
  const Termination until = stop.WithCancel(cancel);
  // The task holds a copy of the slot: the slot stays taken until the worker is done with it,
  // even when the caller gives up at its deadline and the task runs on to its next poll.
  Ticket<Result<T>> ticket = queue_.Submit<Result<T>>(
      [slot, until, work](const TaskContext&) -> Result<T> { return work(until); },
      QueuePolicy::kReject, until);
  Result<T> result = ticket.Wait(until);
  if (!result.ok()) {
    RecordError(result.status());
    return result.status();
  }
  // A product that arrives after the client's deadline is dropped: the call changes nothing.
  if (Status s = until.Check(what); !s.ok()) {
    RecordError(s);
    return s;
  }
  return result;
}

Status PlannerCore::Install(std::shared_ptr<const Snapshot> next,
                            const std::shared_ptr<const planning::PlanningMap>& expected_map) {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::shared_ptr<const Snapshot> current = snapshot_.load();
  if (expected_map != nullptr && (current == nullptr || current->map != expected_map)) {
    return Status::FailedPrecondition("the map was replaced while the operation ran");
  }
  snapshot_.store(std::move(next));
  return Status::Ok();
}

Result<planning::MapInfo> PlannerCore::LoadMapFile(const std::string& path,
                                                   planning::MapOptions options,
                                                   const Termination& stop) {
  MAV_ASSIGN_OR_RETURN(Slot slot, Reserve("LoadMap"));
  options.max_memory_bytes = options_.max_map_memory_bytes;
  options.threads = options_.threads;
  using MapPtr = std::shared_ptr<const planning::PlanningMap>;
  MAV_ASSIGN_OR_RETURN(
      MapPtr map,
      RunOnWorker<MapPtr>(slot, stop, "LoadMap", [this, path, options](const Termination& until) {
        return planning::PlanningMap::LoadFile(
            path, options, until, [this](std::string_view s, double f) { SetProgress(s, f); });
      }));
  auto next = std::make_shared<Snapshot>();
  next->map = map;
  MAV_RETURN_IF_ERROR(Install(std::move(next), nullptr));
  MAV_LOG(kInfo) << "map " << map->info().source << ": " << map->info().resolution_m << " m, "
                 << map->info().memory.bytes / 1000000 << " MB, loaded in "
                 << map->info().load_ms + map->info().distance_map_ms << " ms";
  return map->info();
}

Result<planning::MapInfo> PlannerCore::LoadMapBytes(const Slot& slot, std::string bytes,
                                                    const std::string& source,
                                                    planning::MapOptions options,
                                                    const Termination& stop) {
  MAV_CHECK(slot != nullptr) << "LoadMapBytes needs a reserved slot";
  options.max_memory_bytes = options_.max_map_memory_bytes;
  options.threads = options_.threads;
  using MapPtr = std::shared_ptr<const planning::PlanningMap>;
  auto shared_bytes = std::make_shared<const std::string>(std::move(bytes));
  MAV_ASSIGN_OR_RETURN(
      MapPtr map,
      RunOnWorker<MapPtr>(slot, stop, "LoadMap",
                          [this, shared_bytes, source, options](const Termination& until) {
                            return planning::PlanningMap::LoadBytes(
                                *shared_bytes, source, options, until,
                                [this](std::string_view s, double f) { SetProgress(s, f); });
                          }));
  auto next = std::make_shared<Snapshot>();
  next->map = map;
  MAV_RETURN_IF_ERROR(Install(std::move(next), nullptr));
  MAV_LOG(kInfo) << "map " << source << ": " << map->info().resolution_m << " m, "
                 << map->info().memory.bytes / 1000000 << " MB";
  return map->info();
}

Result<planning::RoadmapInfo> PlannerCore::BuildRoadmap(planning::RoadmapOptions options,
                                                        const Termination& stop) {
  if (options.max_milestones > options_.max_milestones) {
    return Status::ResourceExhausted("max_milestones: " + std::to_string(options.max_milestones) +
                                     " is above the server's limit of " +
                                     std::to_string(options_.max_milestones) +
                                     " (--max-milestones)");
  }
  const std::shared_ptr<const Snapshot> current = snapshot_.load();
  if (current == nullptr) return Status::FailedPrecondition("no map: call LoadMap first");
  MAV_ASSIGN_OR_RETURN(Slot slot, Reserve("BuildRoadmap"));
  options.threads = options_.threads;
  const std::shared_ptr<const planning::PlanningMap> map = current->map;
  using RoadmapPtr = std::shared_ptr<const planning::Roadmap>;
  MAV_ASSIGN_OR_RETURN(
      RoadmapPtr roadmap,
      RunOnWorker<RoadmapPtr>(
          slot, stop, "BuildRoadmap", [this, map, options](const Termination& until) {
            return planning::Roadmap::Build(
                *map, options, until, [this](std::string_view s, double f) { SetProgress(s, f); });
          }));
  auto next = std::make_shared<Snapshot>();
  next->map = map;
  next->roadmap = roadmap;
  next->roadmap_source = "built";
  MAV_RETURN_IF_ERROR(Install(std::move(next), map));
  MAV_LOG(kInfo) << "roadmap built: " << roadmap->info().milestones << " milestones, "
                 << roadmap->info().edges << " edges in " << roadmap->info().build_s << " s";
  return roadmap->info();
}

Result<planning::RoadmapInfo> PlannerCore::LoadRoadmap(const std::string& path,
                                                       const Termination& stop) {
  const std::shared_ptr<const Snapshot> current = snapshot_.load();
  if (current == nullptr) return Status::FailedPrecondition("no map: call LoadMap first");
  MAV_ASSIGN_OR_RETURN(Slot slot, Reserve("LoadRoadmap"));
  const std::shared_ptr<const planning::PlanningMap> map = current->map;
  using RoadmapPtr = std::shared_ptr<const planning::Roadmap>;
  MAV_ASSIGN_OR_RETURN(
      RoadmapPtr roadmap,
      RunOnWorker<RoadmapPtr>(slot, stop, "LoadRoadmap", [this, map, path](const Termination&) {
        SetProgress("roadmap file", 0);
        return planning::Roadmap::Load(path, *map);
      }));
  auto next = std::make_shared<Snapshot>();
  next->map = map;
  next->roadmap = roadmap;
  next->roadmap_source = path;
  MAV_RETURN_IF_ERROR(Install(std::move(next), map));
  MAV_LOG(kInfo) << "roadmap " << path << ": " << roadmap->info().milestones << " milestones in "
                 << roadmap->info().load_ms << " ms";
  return roadmap->info();
}

Result<planning::RoadmapInfo> PlannerCore::SaveRoadmap(const std::string& path,
                                                       const Termination& stop) {
  if (!EndsWith(path, ".mavprm")) {
    return Status::InvalidArgument("path: " + QuoteForError(path) + " must end in \".mavprm\"");
  }
  const std::shared_ptr<const Snapshot> current = snapshot_.load();
  if (current == nullptr || current->roadmap == nullptr) {
    return Status::FailedPrecondition("no roadmap: call BuildRoadmap or LoadRoadmap first");
  }
  if (PathExists(path) && !planning::Roadmap::IsRoadmapFile(path)) {
    return Status::FailedPrecondition("path: " + path +
                                      " exists and is not a roadmap file; not overwriting it");
  }
  MAV_ASSIGN_OR_RETURN(Slot slot, Reserve("SaveRoadmap"));
  const std::shared_ptr<const planning::Roadmap> roadmap = current->roadmap;
  using Info = planning::RoadmapInfo;
  MAV_ASSIGN_OR_RETURN(Info info,
                       RunOnWorker<Info>(slot, stop, "SaveRoadmap",
                                         [this, roadmap, path](const Termination&) -> Result<Info> {
                                           SetProgress("roadmap file", 0);
                                           MAV_RETURN_IF_ERROR(roadmap->Save(path));
                                           return roadmap->info();
                                         }));
  auto next = std::make_shared<Snapshot>(*current);
  next->roadmap_source = path;
  MAV_RETURN_IF_ERROR(Install(std::move(next), current->map));
  MAV_LOG(kInfo) << "roadmap saved to " << path;
  return info;
}

Result<PlanOutcome> PlannerCore::Plan(const planning::PlanRequest& request,
                                      const Termination& stop) {
  const std::shared_ptr<const Snapshot> snapshot = snapshot_.load();
  if (snapshot == nullptr) {
    RecordFailed();
    return Status::FailedPrecondition("no map: call LoadMap first");
  }
  // Admission: counted before the work, refused at once above the limit.
  if (in_flight_.fetch_add(1) >= max_in_flight_) {
    in_flight_.fetch_sub(1);
    std::lock_guard<std::mutex> lock(mutex_);
    ++plans_rejected_;
    return Status::ResourceExhausted("PlanPath: " + std::to_string(max_in_flight_) +
                                     " plans in flight, the server's limit "
                                     "(--max-plans-in-flight); retry later");
  }
  Result<planning::PlanResult> result = planning::PlanPath(*snapshot->map, snapshot->roadmap.get(),
                                                           request, stop.WithCancel(shutdown_));
  in_flight_.fetch_sub(1);
  if (!result.ok()) {
    RecordFailed();
    return result.status();
  }
  PlanOutcome outcome;
  outcome.used_roadmap = snapshot->roadmap != nullptr && request.use_roadmap &&
                         snapshot->roadmap->num_milestones() > 0;
  outcome.map_fingerprint = snapshot->map->fingerprint();
  outcome.result = std::move(result).value();
  return outcome;
}

void PlannerCore::RecordAnswered(bool success, double handler_ms) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++plans_;
  if (success) ++plans_succeeded_;
  planning_ms_.Add(handler_ms);
}

void PlannerCore::RecordFailed() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++plans_failed_;
}

std::string PlannerCore::StorePlan(const PlanOutcome& outcome, double sample_dt_s) {
  auto stored = std::make_shared<StoredPlan>();
  stored->outcome = outcome;
  stored->sample_dt_s = sample_dt_s;
  std::lock_guard<std::mutex> lock(mutex_);
  stored->id = id_prefix_ + "-" + std::to_string(next_plan_++);
  history_.push_back(stored);
  while (history_.size() > kPlanHistory) history_.pop_front();
  return stored->id;
}

std::shared_ptr<const StoredPlan> PlannerCore::FindPlan(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& plan : history_) {
    if (plan->id == id) return plan;
  }
  return nullptr;
}

CoreStatus PlannerCore::GetStatus() const {
  CoreStatus s;
  s.snapshot = snapshot_.load();
  s.plans_in_flight = static_cast<uint32_t>(std::max(0, in_flight_.load()));
  s.max_plans_in_flight = static_cast<uint32_t>(max_in_flight_);
  std::lock_guard<std::mutex> lock(mutex_);
  s.busy = busy_;
  s.operation = operation_;
  s.stage = stage_;
  s.fraction = fraction_;
  s.elapsed_s = busy_ ? SecondsSince(operation_start_ns_) : 0;
  s.last_error = last_error_;
  s.plans = plans_;
  s.plans_succeeded = plans_succeeded_;
  s.plans_rejected = plans_rejected_;
  s.plans_failed = plans_failed_;
  s.plans_stored = static_cast<uint32_t>(history_.size());
  s.planning_ms = planning_ms_.Summary();
  return s;
}

}  // namespace mav::planning_service
