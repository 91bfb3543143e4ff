#pragma once
// Minimum s-t cut on a plain edge list (private to mav::mapping). Keeps Boost.Graph in one
// translation unit.

#include <cstdint>
#include <vector>

namespace mav::mapping::internal {

struct StGraph {
  struct Edge {
    int u = 0;
    int v = 0;
    double cap_uv = 0.0;  // capacity u -> v
    double cap_vu = 0.0;  // capacity v -> u
  };
  int num_nodes = 0;
  std::vector<double> source_cap;  // per node: source -> node
  std::vector<double> sink_cap;    // per node: node -> sink
  std::vector<Edge> edges;
};

struct MinCut {
  std::vector<uint8_t> sink_side;  // 1 = node on the sink side of the minimum cut
  double flow = 0.0;
};

// Boykov-Kolmogorov max-flow (Boost.Graph). Capacities must be finite and >= 0.
MinCut SolveMinCut(const StGraph& graph);

}  // namespace mav::mapping::internal
