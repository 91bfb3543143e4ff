#pragma once
// The PRM* roadmap built before the mission (Holzmann et al. 2015, Sec. 3), with OMPL's PRMstar
// (Karaman & Frazzoli, "Sampling-based algorithms for optimal motion planning", IJRR 30(7), 2011;
// Sucan, Moll, Kavraki, "The Open Motion Planning Library", IEEE RAM 2012):
// * milestones are uniform samples of the planning volume whose clearance is at least
//   robot_radius + clearance_margin_m; each new milestone is connected to its
//   k(n) = e (1 + 1/3) log(n) nearest milestones (PRM*'s rule for a 3-D space) by every
//   straight motion that stays valid, checked by ClearanceMap::IsSegmentValid at
//   validity_resolution_m (OMPL's default of 1 % of the extent would let edges cut corners);
// * only the sampling-and-connecting phase of PRM is run (no expansion step), so a build with
//   the same seed and the same max_milestones gives the same roadmap (OMPL only sees the map
//   through ClearanceMap; our own sampler seeds every random draw);
// * the result is copied out of OMPL into an immutable graph (milestones, undirected edges with
//   their length, climb |dz| and proximity integral, see path.h), so any number of queries
//   search it at once without locks (OMPL's planner object is not reentrant).
//
// The roadmap belongs to one map: it records the map's fingerprint (obstacles, volume, robot
// radius); Load() and the planner refuse a roadmap of another map. File format: docs/planning.md,
// "Roadmap file".

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/planning/clearance_map.h"

namespace mav::planning {

struct RoadmapOptions {
  // How long PRM* samples and connects, s: a safety net; the milestone limit below normally
  // ends the build first (~10 s for 100 k milestones on the power plant map). Validated
  // (0, 600].
  double time_budget_s = 45;
  // Stop once the roadmap has this many milestones; 0 = no limit (the time budget decides).
  // With a limit that the budget allows, the roadmap is deterministic for the seed. 100 k on
  // the power plant's 125 000 m^3: paths within a few percent of the shortest, 3.7 M edges,
  // ~0.7 GB while OMPL builds, ~130 MB once copied out (docs/planning.md has the trade-off).
  uint64_t max_milestones = 100000;
  // Seed of every random draw of the build (0 is a valid seed).
  uint64_t seed = 1;
  // Step of the motion checks near obstacles, m; 0 = ClearanceMap::kDefaultToleranceM (1 cm).
  // Must not be coarser than the map resolution. Validated [0, 1].
  double validity_resolution_m = 0;
  // Clearance the milestones and edges keep beyond the robot radius, m: room for the spline to
  // deviate from the straight edges without coming closer than the radius. 5 cm: larger
  // margins close narrow passages and lengthen the paths around every obstacle. Validated
  // [0, 1].
  double clearance_margin_m = 0.05;
  // Threads for the edge costs after PRM* (PRM* itself runs on one). Validated [1, 64].
  int threads = 2;

  bool IsValid(std::string* why) const;
};

struct RoadmapInfo {
  uint64_t milestones = 0;
  uint64_t edges = 0;
  uint64_t largest_component = 0;  // milestones in the largest connected component
  double build_s = 0;              // PRM* + copying out (0 for a loaded roadmap: see load_ms)
  double load_ms = 0;              // reading the file (0 for a built roadmap)
  uint64_t seed = 0;
  uint64_t map_fingerprint = 0;
  double robot_radius_m = 0;
  double clearance_margin_m = 0;
  double validity_resolution_m = 0;
  uint64_t memory_bytes = 0;  // the graph's arrays
};

// An undirected roadmap edge with the terms of the paper's cost (path.h).
struct RoadmapEdge {
  uint32_t a = 0, b = 0;  // milestone indices
  float length_m = 0;     // |b - a|
  float climb_m = 0;      // |z_b - z_a|
  float proximity = 0;    // integral of the proximity penalty along the edge (path.h)
};

class Roadmap {
 public:
  // Builds the roadmap over map.bounds(). INVALID_ARGUMENT: bad options (field named), or a
  // validity resolution coarser than the map's; DEADLINE_EXCEEDED / CANCELLED when `stop`
  // fires (nothing is kept; the time budget is not an error). Progress stage "roadmap".
  static Result<std::shared_ptr<const Roadmap>> Build(const ClearanceMap& map,
                                                      const RoadmapOptions& options,
                                                      const Termination& stop = {},
                                                      const ProgressCallback& progress = {});

  // Saves atomically (written to <path>.tmp, then renamed). IO_ERROR naming the file.
  Status Save(const std::string& path) const;
  std::string Serialize() const;
  // Whether the file at `path` starts as a roadmap file does (its magic bytes): a caller about
  // to overwrite a file checks it is one. False for a missing or unreadable file.
  static bool IsRoadmapFile(const std::string& path);
  // NOT_FOUND: no such file; DATA_LOSS naming the file: not a roadmap file, unknown version,
  // truncated, checksum mismatch, inconsistent contents; FAILED_PRECONDITION: built for another
  // map (fingerprint or robot radius differ).
  static Result<std::shared_ptr<const Roadmap>> Load(const std::string& path,
                                                     const ClearanceMap& map);
  static Result<std::shared_ptr<const Roadmap>> Deserialize(std::string_view bytes,
                                                            const std::string& source,
                                                            const ClearanceMap& map);

  ~Roadmap();
  Roadmap(const Roadmap&) = delete;
  Roadmap& operator=(const Roadmap&) = delete;

  const RoadmapInfo& info() const;
  // OK when this roadmap was built on `map` (same fingerprint and robot radius), else
  // FAILED_PRECONDITION saying which differs.
  Status CheckBelongsTo(const ClearanceMap& map) const;

  // Read access for the searches (immutable; safe from any thread).
  size_t num_milestones() const;
  const Eigen::Vector3d& milestone(size_t i) const;
  const std::vector<RoadmapEdge>& edges() const;
  // (neighbour, edge index) pairs of milestone i.
  std::pair<const std::pair<uint32_t, uint32_t>*, const std::pair<uint32_t, uint32_t>*> neighbours(
      size_t i) const;
  // Connected-component label of milestone i: two milestones are joined by roadmap edges iff
  // their labels are equal.
  uint32_t component(size_t i) const;
  // Up to k milestones nearest to p, nearest first.
  std::vector<uint32_t> Nearest(const Eigen::Vector3d& p, size_t k) const;

  struct Impl;

 private:
  explicit Roadmap(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mav::planning
