#include "mav/planning/reference_path.h"

#include <cmath>
#include <limits>
#include <queue>
#include <sstream>

#include "mav/common/time.h"
#include "mav/planning/path.h"

namespace mav::planning {
namespace {

enum : uint8_t { kKnown = 1, kValid = 2, kClosed = 4 };

class LazyThetaStar {
 public:
  LazyThetaStar(const PlanningMap& map, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                double required)
      : map_(map), a_(a), b_(b), required_(required) {
    size_ = map.grid_size();
    origin_ = map.grid_origin();
    cell_ = map.resolution();
    n_ = static_cast<uint32_t>(int64_t{size_.x()} * size_.y() * size_.z());
    start_ = n_;
    goal_ = n_ + 1;
    g_.assign(n_ + 2, std::numeric_limits<float>::infinity());
    parent_.assign(n_ + 2, kNone);
    state_.assign(n_ + 2, 0);
    start_links_ = LinksOf(a);
    goal_links_ = LinksOf(b);
  }

  // Runs the search; false when the goal is unreachable.
  Result<bool> Run(uint64_t max_expansions, const Termination& stop) {
    g_[start_] = 0;
    parent_[start_] = start_;
    Push(start_);
    while (!open_.empty()) {
      const uint32_t s = open_.top().second;
      open_.pop();
      if (state_[s] & kClosed) continue;
      SetVertex(s);
      if (s == goal_) return true;
      state_[s] |= kClosed;
      if ((++expansions_ & 4095) == 0) MAV_RETURN_IF_ERROR(stop.Check("reference path"));
      if (max_expansions > 0 && expansions_ > max_expansions) {
        return Status::ResourceExhausted("reference path: more than " +
                                         std::to_string(max_expansions) + " expansions");
      }
      const uint32_t ps = parent_[s];
      ForNeighbours(s, [&](uint32_t t) {
        if (state_[t] & kClosed) return;
        const float candidate = g_[ps] + static_cast<float>((Position(ps) - Position(t)).norm());
        if (candidate < g_[t]) {
          g_[t] = candidate;
          parent_[t] = ps;
          Push(t);
        }
      });
    }
    return false;
  }

  std::vector<Eigen::Vector3d> Path() const {
    std::vector<Eigen::Vector3d> path;
    for (uint32_t v = goal_;; v = parent_[v]) {
      path.push_back(Position(v));
      if (v == start_) break;
    }
    return {path.rbegin(), path.rend()};
  }
  uint64_t expansions() const { return expansions_; }

 private:
  static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

  Eigen::Vector3i Cell(uint32_t v) const {
    const int64_t i = v % size_.x(), j = (v / size_.x()) % size_.y(),
                  k = v / (int64_t{size_.x()} * size_.y());
    return Eigen::Vector3i(static_cast<int>(i), static_cast<int>(j), static_cast<int>(k));
  }
  Eigen::Vector3d Position(uint32_t v) const {
    if (v == start_) return a_;
    if (v == goal_) return b_;
    return origin_ + (Cell(v).cast<double>().array() + 0.5).matrix() * cell_;
  }
  bool Valid(uint32_t v) {
    if (!(state_[v] & kKnown)) {
      state_[v] |= kKnown | (map_.IsValid(Position(v), required_) ? kValid : 0);
    }
    return state_[v] & kValid;
  }
  // Valid cell centres around p that p sees.
  std::vector<uint32_t> LinksOf(const Eigen::Vector3d& p) {
    std::vector<uint32_t> links;
    const Eigen::Vector3i c = ((p - origin_) / cell_).array().floor().cast<int>();
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const Eigen::Vector3i q = c + Eigen::Vector3i(dx, dy, dz);
          if ((q.array() < 0).any() || (q.array() >= size_.array()).any()) continue;
          const uint32_t v = q.x() + size_.x() * (q.y() + size_.y() * q.z());
          if (Valid(v) && map_.IsSegmentValid(p, Position(v), required_)) links.push_back(v);
        }
      }
    }
    return links;
  }
  template <typename F>
  void ForNeighbours(uint32_t s, F&& f) {
    if (s == start_ || s == goal_) {
      for (uint32_t v : s == start_ ? start_links_ : goal_links_) f(v);
      return;
    }
    const Eigen::Vector3i c = Cell(s);
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          const Eigen::Vector3i q = c + Eigen::Vector3i(dx, dy, dz);
          if ((q.array() < 0).any() || (q.array() >= size_.array()).any()) continue;
          const uint32_t v = q.x() + size_.x() * (q.y() + size_.y() * q.z());
          if (Valid(v)) f(v);
        }
      }
    }
    for (uint32_t v : start_links_) {
      if (v == s) f(start_);
    }
    for (uint32_t v : goal_links_) {
      if (v == s) f(goal_);
    }
  }
  // Lazy Theta*'s SetVertex: the optimistic parent is checked now; without a line of sight the
  // best closed neighbour becomes the parent.
  void SetVertex(uint32_t s) {
    if (s == start_ || map_.IsSegmentValid(Position(parent_[s]), Position(s), required_)) return;
    g_[s] = std::numeric_limits<float>::infinity();
    ForNeighbours(s, [&](uint32_t t) {
      if (!(state_[t] & kClosed)) return;
      const float candidate = g_[t] + static_cast<float>((Position(t) - Position(s)).norm());
      if (candidate < g_[s]) {
        g_[s] = candidate;
        parent_[s] = t;
      }
    });
  }
  void Push(uint32_t v) { open_.emplace(g_[v] + static_cast<float>((Position(v) - b_).norm()), v); }

  const PlanningMap& map_;
  const Eigen::Vector3d a_, b_;
  const double required_;
  Eigen::Vector3i size_;
  Eigen::Vector3d origin_;
  double cell_;
  uint32_t n_, start_, goal_;
  std::vector<float> g_;
  std::vector<uint32_t> parent_;
  std::vector<uint8_t> state_;
  std::vector<uint32_t> start_links_, goal_links_;
  using Entry = std::pair<float, uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open_;
  uint64_t expansions_ = 0;
};

}  // namespace

bool ReferenceOptions::IsValid(std::string* why) const {
  if (required_clearance_m >= 0 && std::isfinite(required_clearance_m)) return true;
  if (why) *why = "required_clearance_m: must be finite and >= 0";
  return false;
}

Result<ReferencePath> ShortestReferencePath(const PlanningMap& map, const Eigen::Vector3d& a,
                                            const Eigen::Vector3d& b,
                                            const ReferenceOptions& options,
                                            const Termination& stop) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  const double required =
      options.required_clearance_m > 0 ? options.required_clearance_m : map.robot_radius();
  if (!map.IsValid(a, required)) return Status::InvalidArgument("a: not a valid state");
  if (!map.IsValid(b, required)) return Status::InvalidArgument("b: not a valid state");
  const int64_t start_ns = MonotonicNowNs();
  ReferencePath out;
  if (map.IsSegmentValid(a, b, required)) {
    out.found = true;
    out.path = {a, b};
  } else {
    LazyThetaStar search(map, a, b, required);
    MAV_ASSIGN_OR_RETURN(out.found, search.Run(options.max_expansions, stop));
    out.expansions = search.expansions();
    if (out.found) {
      ShortenOptions taut;
      taut.max_cost_increase = 0;
      taut.required_clearance_m = required;
      taut.corner_passes = 40;
      out.path = ShortenPath(map, CostWeights{1, 0, 0}, search.Path(), taut, stop);
    }
  }
  out.length_m = PathLength(out.path);
  out.search_ms = MsSince(start_ns);
  return out;
}

Result<std::vector<EvaluationQuery>> RandomQueries(const PlanningMap& map,
                                                   const RandomQueryOptions& options,
                                                   const Termination& stop) {
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> u(0, 1);
  const Box& b = map.bounds();
  const double z0 = std::max(b.min.z(), options.min_z_m), z1 = std::min(b.max.z(), options.max_z_m);
  std::vector<EvaluationQuery> out;
  int blocked = 0, free = 0;
  for (int candidate = 0; candidate < options.max_candidates; ++candidate) {
    if (blocked >= options.blocked && free >= options.free) break;
    MAV_RETURN_IF_ERROR(stop.Check("random queries"));
    EvaluationQuery q;
    for (Eigen::Vector3d* p : {&q.start, &q.goal}) {
      *p = Eigen::Vector3d(b.min.x() + u(rng) * b.size().x(), b.min.y() + u(rng) * b.size().y(),
                           z0 + u(rng) * (z1 - z0));
    }
    const double d = (q.goal - q.start).norm();
    if (d < options.min_distance_m || d > options.max_distance_m) continue;
    if (!map.IsValid(q.start) || !map.IsValid(q.goal)) continue;
    q.straight_line_free = map.IsSegmentValid(q.start, q.goal, map.robot_radius());
    if (q.straight_line_free ? free >= options.free : blocked >= options.blocked) continue;
    if (options.reference_expansions > 0) {
      ReferenceOptions ro;
      ro.max_expansions = options.reference_expansions;
      Result<ReferencePath> reference = ShortestReferencePath(map, q.start, q.goal, ro, stop);
      if (!reference.ok()) {
        if (reference.status().code() == StatusCode::kResourceExhausted) continue;
        return reference.status();
      }
      if (!reference->found) continue;
      q.reference_length_m = reference->length_m;
    }
    (q.straight_line_free ? free : blocked)++;
    out.push_back(q);
  }
  return out;
}

}  // namespace mav::planning
