#include "min_cut.h"

#include <algorithm>

// GCC reports -Wmaybe-uninitialized inside Boost.Graph's edge iterators once they are inlined here
// (a known false positive of boost::optional); the SYSTEM include does not silence inlined code.
// Clang has no such warning (and would warn about the unknown group).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include <boost/graph/adjacency_list.hpp>
#include <boost/graph/boykov_kolmogorov_max_flow.hpp>

#include "mav/common/check.h"

namespace mav::mapping::internal {
namespace {

using Traits = boost::adjacency_list_traits<boost::vecS, boost::vecS, boost::directedS>;
using Graph = boost::adjacency_list<
    boost::vecS, boost::vecS, boost::directedS,
    boost::property<boost::vertex_index_t, long,
                    boost::property<boost::vertex_color_t, boost::default_color_type,
                                    boost::property<boost::vertex_distance_t, long,
                                                    boost::property<boost::vertex_predecessor_t,
                                                                    Traits::edge_descriptor>>>>,
    boost::property<
        boost::edge_capacity_t, double,
        boost::property<boost::edge_residual_capacity_t, double,
                        boost::property<boost::edge_reverse_t, Traits::edge_descriptor>>>>;

void AddPair(Graph& g, int u, int v, double cap_uv, double cap_vu) {
  auto capacity = boost::get(boost::edge_capacity, g);
  auto reverse = boost::get(boost::edge_reverse, g);
  const auto e = boost::add_edge(u, v, g).first;
  const auto r = boost::add_edge(v, u, g).first;
  capacity[e] = cap_uv;
  capacity[r] = cap_vu;
  reverse[e] = r;
  reverse[r] = e;
}

}  // namespace

MinCut SolveMinCut(const StGraph& graph) {
  const int n = graph.num_nodes;
  MAV_CHECK(static_cast<int>(graph.source_cap.size()) == n &&
            static_cast<int>(graph.sink_cap.size()) == n);
  const int source = n;
  const int sink = n + 1;
  Graph g(n + 2);
  for (const StGraph::Edge& e : graph.edges) {
    if (e.cap_uv > 0.0 || e.cap_vu > 0.0) AddPair(g, e.u, e.v, e.cap_uv, e.cap_vu);
  }
  // Terminal links: only the excess of one side matters (the common part min(s, t) is flow that
  // any cut pays), which keeps the search trees small.
  double constant_flow = 0.0;
  for (int i = 0; i < n; ++i) {
    const double s = graph.source_cap[i];
    const double t = graph.sink_cap[i];
    const double common = std::min(s, t);
    constant_flow += common;
    if (s - common > 0.0) AddPair(g, source, i, s - common, 0.0);
    if (t - common > 0.0) AddPair(g, i, sink, t - common, 0.0);
  }
  MinCut cut;
  cut.flow = constant_flow + boost::boykov_kolmogorov_max_flow(g, source, sink);
  auto color = boost::get(boost::vertex_color, g);
  cut.sink_side.resize(n);
  // Black = source search tree; white (sink tree) and gray (free) go to the sink side, as the
  // Boost documentation defines the minimum cut.
  for (int i = 0; i < n; ++i) {
    cut.sink_side[i] = color[i] == boost::black_color ? 0 : 1;
  }
  return cut;
}

}  // namespace mav::mapping::internal
