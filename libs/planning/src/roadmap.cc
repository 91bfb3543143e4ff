#include "mav/planning/roadmap.h"

#include <ompl/base/ProblemDefinition.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/geometric/planners/prm/PRMstar.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <numeric>
#include <sstream>

#include "mav/common/file.h"
#include "mav/common/hash.h"
#include "mav/common/parallel.h"
#include "mav/common/time.h"
#include "mav/planning/path.h"
#include "ompl_space.h"

namespace mav::planning {

namespace ob = ompl::base;
namespace og = ompl::geometric;

struct Roadmap::Impl {
  RoadmapInfo info;
  std::vector<Eigen::Vector3d> milestones;
  std::vector<RoadmapEdge> edges;
  std::vector<uint32_t> offsets;  // CSR: neighbours of i in [offsets[i], offsets[i+1])
  std::vector<std::pair<uint32_t, uint32_t>> adjacent;  // (neighbour, edge index)
  // Milestones bucketed on a uniform grid for the nearest-milestone queries.
  Eigen::Vector3d bucket_origin = Eigen::Vector3d::Zero();
  double bucket_size = 1;
  Eigen::Vector3i buckets = Eigen::Vector3i::Ones();
  std::vector<uint32_t> bucket_offsets;
  std::vector<uint32_t> bucket_items;
  std::vector<uint32_t> component;  // connected-component label of each milestone

  Eigen::Vector3i BucketOf(const Eigen::Vector3d& p) const {
    Eigen::Vector3i b;
    for (int a = 0; a < 3; ++a) {
      b[a] = std::clamp(static_cast<int>(std::floor((p[a] - bucket_origin[a]) / bucket_size)), 0,
                        buckets[a] - 1);
    }
    return b;
  }
  int64_t BucketIndex(const Eigen::Vector3i& b) const {
    return b.x() + int64_t{buckets.x()} * (b.y() + int64_t{buckets.y()} * b.z());
  }

  // Derived structures (adjacency, buckets, components, memory) from milestones + edges.
  void Finish(const Box& volume);
};

void Roadmap::Impl::Finish(const Box& volume) {
  const size_t n = milestones.size();
  offsets.assign(n + 1, 0);
  for (const RoadmapEdge& e : edges) {
    ++offsets[e.a + 1];
    ++offsets[e.b + 1];
  }
  std::partial_sum(offsets.begin(), offsets.end(), offsets.begin());
  adjacent.resize(2 * edges.size());
  std::vector<uint32_t> fill(offsets.begin(), offsets.end() - 1);
  for (uint32_t i = 0; i < edges.size(); ++i) {
    adjacent[fill[edges[i].a]++] = {edges[i].b, i};
    adjacent[fill[edges[i].b]++] = {edges[i].a, i};
  }

  // Buckets of about 8 milestones each.
  const double volume_m3 = std::max(1e-9, volume.size().prod());
  bucket_size = std::max(0.25, std::cbrt(volume_m3 * 8.0 / std::max<size_t>(n, 1)));
  bucket_origin = volume.min;
  for (int a = 0; a < 3; ++a) {
    buckets[a] = std::max(1, static_cast<int>(std::ceil(volume.size()[a] / bucket_size)));
  }
  const int64_t num_buckets = int64_t{buckets.x()} * buckets.y() * buckets.z();
  bucket_offsets.assign(num_buckets + 1, 0);
  std::vector<int64_t> bucket_of(n);
  for (size_t i = 0; i < n; ++i) {
    bucket_of[i] = BucketIndex(BucketOf(milestones[i]));
    ++bucket_offsets[bucket_of[i] + 1];
  }
  std::partial_sum(bucket_offsets.begin(), bucket_offsets.end(), bucket_offsets.begin());
  bucket_items.resize(n);
  std::vector<uint32_t> cursor(bucket_offsets.begin(), bucket_offsets.end() - 1);
  for (size_t i = 0; i < n; ++i) bucket_items[cursor[bucket_of[i]]++] = static_cast<uint32_t>(i);

  // Largest connected component (union-find with path halving).
  std::vector<uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const RoadmapEdge& e : edges) parent[find(e.a)] = find(e.b);
  std::vector<uint32_t> count(n, 0);
  uint32_t largest = 0;
  component.resize(n);
  for (size_t i = 0; i < n; ++i) {
    component[i] = find(static_cast<uint32_t>(i));
    largest = std::max(largest, ++count[component[i]]);
  }
  info.milestones = n;
  info.edges = edges.size();
  info.largest_component = largest;
  info.memory_bytes =
      milestones.size() * sizeof(Eigen::Vector3d) + edges.size() * sizeof(RoadmapEdge) +
      offsets.size() * sizeof(uint32_t) + adjacent.size() * sizeof(adjacent[0]) +
      (bucket_offsets.size() + bucket_items.size() + component.size()) * sizeof(uint32_t);
}

bool RoadmapOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!(time_budget_s > 0 && time_budget_s <= 600)) {
    msg << "time_budget_s: must be in (0, 600] s, got " << time_budget_s;
  } else if (!(validity_resolution_m >= 0 && validity_resolution_m <= 1)) {
    msg << "validity_resolution_m: must be in [0, 1] m, got " << validity_resolution_m;
  } else if (!(clearance_margin_m >= 0 && clearance_margin_m <= 1)) {
    msg << "clearance_margin_m: must be in [0, 1] m, got " << clearance_margin_m;
  } else if (threads < 1 || threads > 64) {
    msg << "threads: must be in [1, 64], got " << threads;
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

Roadmap::Roadmap(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Roadmap::~Roadmap() = default;

const RoadmapInfo& Roadmap::info() const { return impl_->info; }
size_t Roadmap::num_milestones() const { return impl_->milestones.size(); }
const Eigen::Vector3d& Roadmap::milestone(size_t i) const { return impl_->milestones[i]; }
const std::vector<RoadmapEdge>& Roadmap::edges() const { return impl_->edges; }
uint32_t Roadmap::component(size_t i) const { return impl_->component[i]; }

std::pair<const std::pair<uint32_t, uint32_t>*, const std::pair<uint32_t, uint32_t>*>
Roadmap::neighbours(size_t i) const {
  const auto* base = impl_->adjacent.data();
  return {base + impl_->offsets[i], base + impl_->offsets[i + 1]};
}

std::vector<uint32_t> Roadmap::Nearest(const Eigen::Vector3d& p, size_t k) const {
  const Impl& m = *impl_;
  std::vector<std::pair<double, uint32_t>> found;
  if (m.milestones.empty() || k == 0) return {};
  const Eigen::Vector3i centre = m.BucketOf(p);
  const int max_ring = m.buckets.maxCoeff();
  for (int ring = 0; ring <= max_ring; ++ring) {
    const Eigen::Vector3i lo = (centre.array() - ring).max(0).matrix();
    const Eigen::Vector3i hi = (centre.array() + ring).min(m.buckets.array() - 1).matrix();
    for (int z = lo.z(); z <= hi.z(); ++z) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int x = lo.x(); x <= hi.x(); ++x) {
          const Eigen::Vector3i b(x, y, z);
          if ((b - centre).cwiseAbs().maxCoeff() != ring) continue;  // the shell only
          const int64_t index = m.BucketIndex(b);
          for (uint32_t s = m.bucket_offsets[index]; s < m.bucket_offsets[index + 1]; ++s) {
            const uint32_t id = m.bucket_items[s];
            found.emplace_back((m.milestones[id] - p).squaredNorm(), id);
          }
        }
      }
    }
    // Everything beyond this ring is at least ring * bucket_size away.
    if (found.size() >= k) {
      std::nth_element(found.begin(), found.begin() + (k - 1), found.end());
      const double reach = ring * m.bucket_size;
      if (found[k - 1].first <= reach * reach) break;
    }
  }
  std::sort(found.begin(), found.end());
  if (found.size() > k) found.resize(k);
  std::vector<uint32_t> ids;
  ids.reserve(found.size());
  for (const auto& f : found) ids.push_back(f.second);
  return ids;
}

Status Roadmap::CheckBelongsTo(const ClearanceMap& map) const {
  const RoadmapInfo& info = impl_->info;
  // The radius first: it is part of the fingerprint too, but this message says what differs.
  if (info.robot_radius_m != map.robot_radius()) {
    return Status::FailedPrecondition("the roadmap was built for robot radius " +
                                      std::to_string(info.robot_radius_m) + " m, the map uses " +
                                      std::to_string(map.robot_radius()) + " m");
  }
  if (info.map_fingerprint != map.fingerprint()) {
    std::ostringstream msg;
    msg << "the roadmap was built on another map (fingerprint " << std::hex << info.map_fingerprint
        << ", this map " << map.fingerprint() << ")";
    return Status::FailedPrecondition(msg.str());
  }
  return Status::Ok();
}

Result<std::shared_ptr<const Roadmap>> Roadmap::Build(const ClearanceMap& map,
                                                      const RoadmapOptions& options,
                                                      const Termination& stop,
                                                      const ProgressCallback& progress) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  if (options.validity_resolution_m > map.resolution()) {
    return Status::InvalidArgument(
        "validity_resolution_m: " + std::to_string(options.validity_resolution_m) +
        " m is coarser than the map resolution " + std::to_string(map.resolution()) + " m");
  }
  MAV_RETURN_IF_ERROR(stop.Check("roadmap build"));
  const int64_t start_ns = MonotonicNowNs();
  const double tolerance = options.validity_resolution_m > 0 ? options.validity_resolution_m
                                                             : ClearanceMap::kDefaultToleranceM;
  const double required = map.robot_radius() + options.clearance_margin_m;

  auto impl = std::make_unique<Impl>();
  {
    const ob::SpaceInformationPtr si =
        internal::MakeSpaceInformation(map, required, tolerance, options.seed);
    auto problem = std::make_shared<ob::ProblemDefinition>(si);
    problem->setOptimizationObjective(std::make_shared<ob::PathLengthOptimizationObjective>(si));
    og::PRMstar prm(si);
    prm.setProblemDefinition(problem);
    prm.setup();
    const int64_t budget_ns = SecondsToNs(options.time_budget_s);
    int64_t last_report_ns = start_ns;
    const ob::PlannerTerminationCondition done([&] {
      const int64_t now = MonotonicNowNs();
      const double time_fraction = static_cast<double>(now - start_ns) / budget_ns;
      const double count_fraction =
          options.max_milestones > 0
              ? static_cast<double>(prm.milestoneCount()) / options.max_milestones
              : 0.0;
      if (progress && now - last_report_ns > 250'000'000) {
        last_report_ns = now;
        progress("roadmap", std::min(1.0, std::max(time_fraction, count_fraction)));
      }
      return time_fraction >= 1.0 || count_fraction >= 1.0 || stop.ShouldStop();
    });
    // Only the sample-and-connect phase: PRM's expansion step alternates on wall-clock time,
    // which would make the roadmap depend on the machine's speed.
    prm.growRoadmap(done);
    MAV_RETURN_IF_ERROR(stop.Check("roadmap build"));

    const og::PRM::Graph& graph = prm.getRoadmap();
    const auto states = boost::get(og::PRM::vertex_state_t(), graph);
    impl->milestones.reserve(boost::num_vertices(graph));
    for (auto [v, end] = boost::vertices(graph); v != end; ++v) {
      impl->milestones.push_back(internal::ToVector(states[*v]));
    }
    impl->edges.reserve(boost::num_edges(graph));
    for (auto [e, end] = boost::edges(graph); e != end; ++e) {
      RoadmapEdge edge;
      edge.a = static_cast<uint32_t>(boost::source(*e, graph));
      edge.b = static_cast<uint32_t>(boost::target(*e, graph));
      impl->edges.push_back(edge);
    }
  }

  // The edge terms of the cost, on all threads.
  {
    std::vector<RoadmapEdge>& edges = impl->edges;
    const std::vector<Eigen::Vector3d>& points = impl->milestones;
    ParallelFor(options.threads, static_cast<int64_t>(edges.size()),
                [&](int, int64_t begin, int64_t end) {
                  for (int64_t i = begin; i < end; ++i) {
                    const Eigen::Vector3d& a = points[edges[i].a];
                    const Eigen::Vector3d& b = points[edges[i].b];
                    edges[i].length_m = static_cast<float>((b - a).norm());
                    edges[i].climb_m = static_cast<float>(std::abs(b.z() - a.z()));
                    edges[i].proximity = static_cast<float>(SegmentProximity(map, a, b));
                  }
                });
  }
  MAV_RETURN_IF_ERROR(stop.Check("roadmap build"));

  RoadmapInfo& info = impl->info;
  info.seed = options.seed;
  info.map_fingerprint = map.fingerprint();
  info.robot_radius_m = map.robot_radius();
  info.clearance_margin_m = options.clearance_margin_m;
  info.validity_resolution_m = tolerance;
  impl->Finish(map.bounds());
  info.build_s = SecondsSince(start_ns);
  if (progress) progress("roadmap", 1.0);
  return std::shared_ptr<const Roadmap>(new Roadmap(std::move(impl)));
}

// ---- File format (docs/planning.md, "Roadmap file") ------------------------------------------

namespace {

constexpr char kMagic[8] = {'M', 'A', 'V', 'P', 'R', 'M', '\n', '\x1a'};
constexpr uint32_t kVersion = 1;
constexpr size_t kHeaderBytes = 80;
constexpr size_t kMilestoneBytes = 3 * sizeof(double);
constexpr size_t kEdgeBytes = 2 * sizeof(uint32_t) + 3 * sizeof(float);

template <typename T>
void Put(std::string* out, const T& v) {
  out->append(reinterpret_cast<const char*>(&v), sizeof(T));
}

template <typename T>
T Get(const char* data, size_t* offset) {
  T v;
  std::memcpy(&v, data + *offset, sizeof(T));
  *offset += sizeof(T);
  return v;
}

}  // namespace

std::string Roadmap::Serialize() const {
  const Impl& m = *impl_;
  std::string out;
  out.reserve(kHeaderBytes + m.milestones.size() * kMilestoneBytes + m.edges.size() * kEdgeBytes +
              8);
  out.append(kMagic, sizeof(kMagic));
  Put<uint32_t>(&out, kVersion);
  Put<uint32_t>(&out, 0);  // flags
  Put<uint64_t>(&out, m.info.map_fingerprint);
  Put<double>(&out, m.info.robot_radius_m);
  Put<double>(&out, m.info.clearance_margin_m);
  Put<double>(&out, m.info.validity_resolution_m);
  Put<uint64_t>(&out, m.info.seed);
  Put<double>(&out, m.info.build_s);
  Put<uint64_t>(&out, m.milestones.size());
  Put<uint64_t>(&out, m.edges.size());
  for (const Eigen::Vector3d& p : m.milestones) {
    for (int a = 0; a < 3; ++a) Put<double>(&out, p[a]);
  }
  for (const RoadmapEdge& e : m.edges) {
    Put<uint32_t>(&out, e.a);
    Put<uint32_t>(&out, e.b);
    Put<float>(&out, e.length_m);
    Put<float>(&out, e.climb_m);
    Put<float>(&out, e.proximity);
  }
  Fnv1a64 h;
  h.AddBytes(out.data(), out.size());
  Put<uint64_t>(&out, h.value());
  return out;
}

Status Roadmap::Save(const std::string& path) const {
  return WriteStringToFileAtomic(path, Serialize());
}

Result<std::shared_ptr<const Roadmap>> Roadmap::Load(const std::string& path,
                                                     const ClearanceMap& map) {
  if (!PathExists(path)) return Status::NotFound(path + ": no such file");
  MAV_ASSIGN_OR_RETURN(const std::string bytes, ReadFileToString(path));
  return Deserialize(bytes, path, map);
}

bool Roadmap::IsRoadmapFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char head[sizeof(kMagic)] = {};
  in.read(head, sizeof(head));
  return in.gcount() == static_cast<std::streamsize>(sizeof(head)) &&
         std::memcmp(head, kMagic, sizeof(kMagic)) == 0;
}

Result<std::shared_ptr<const Roadmap>> Roadmap::Deserialize(std::string_view bytes,
                                                            const std::string& source,
                                                            const ClearanceMap& map) {
  const int64_t start_ns = MonotonicNowNs();
  const auto loss = [&](const std::string& what) {
    return Status::DataLoss(source + ": not a valid roadmap file: " + what);
  };
  if (bytes.size() < kHeaderBytes + 8) return loss("shorter than the header");
  if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) return loss("bad magic");
  const char* data = bytes.data();
  size_t offset = sizeof(kMagic);
  const uint32_t version = Get<uint32_t>(data, &offset);
  if (version != kVersion) {
    return loss("unknown version " + std::to_string(version) + " (this build reads " +
                std::to_string(kVersion) + ")");
  }
  Get<uint32_t>(data, &offset);  // flags
  auto impl = std::make_unique<Impl>();
  RoadmapInfo& info = impl->info;
  info.map_fingerprint = Get<uint64_t>(data, &offset);
  info.robot_radius_m = Get<double>(data, &offset);
  info.clearance_margin_m = Get<double>(data, &offset);
  info.validity_resolution_m = Get<double>(data, &offset);
  info.seed = Get<uint64_t>(data, &offset);
  info.build_s = Get<double>(data, &offset);
  const uint64_t num_milestones = Get<uint64_t>(data, &offset);
  const uint64_t num_edges = Get<uint64_t>(data, &offset);
  // Sizes first (a corrupt count must not drive an allocation), then the checksum.
  if (num_milestones > (bytes.size() / kMilestoneBytes) ||
      num_edges > (bytes.size() / kEdgeBytes) ||
      kHeaderBytes + num_milestones * kMilestoneBytes + num_edges * kEdgeBytes + 8 !=
          bytes.size()) {
    return loss("size " + std::to_string(bytes.size()) + " bytes disagrees with " +
                std::to_string(num_milestones) + " milestones and " + std::to_string(num_edges) +
                " edges (truncated?)");
  }
  Fnv1a64 h;
  h.AddBytes(data, bytes.size() - 8);
  size_t sum_offset = bytes.size() - 8;
  if (h.value() != Get<uint64_t>(data, &sum_offset)) return loss("checksum mismatch");
  if (!(info.robot_radius_m > 0) || !std::isfinite(info.clearance_margin_m) ||
      !(info.validity_resolution_m > 0)) {
    return loss("bad header values");
  }
  impl->milestones.resize(num_milestones);
  for (Eigen::Vector3d& p : impl->milestones) {
    for (int a = 0; a < 3; ++a) p[a] = Get<double>(data, &offset);
    if (!p.allFinite()) return loss("non-finite milestone");
  }
  impl->edges.resize(num_edges);
  for (RoadmapEdge& e : impl->edges) {
    e.a = Get<uint32_t>(data, &offset);
    e.b = Get<uint32_t>(data, &offset);
    e.length_m = Get<float>(data, &offset);
    e.climb_m = Get<float>(data, &offset);
    e.proximity = Get<float>(data, &offset);
    if (e.a >= num_milestones || e.b >= num_milestones || e.a == e.b) {
      return loss("edge between invalid milestones");
    }
    if (!(e.length_m >= 0) || !(e.climb_m >= 0) || !(e.proximity >= 0)) {
      return loss("bad edge cost");
    }
  }
  auto roadmap = std::shared_ptr<Roadmap>(new Roadmap(std::move(impl)));
  MAV_RETURN_IF_ERROR(roadmap->CheckBelongsTo(map).WithContext(source));
  roadmap->impl_->Finish(map.bounds());
  roadmap->impl_->info.load_ms = MsSince(start_ns);
  return std::shared_ptr<const Roadmap>(std::move(roadmap));
}

}  // namespace mav::planning
