// The planning query file of mav-eval planning and mav-load (mav/dataset/planning_queries.h).

#include <gtest/gtest.h>

#include <string>

#include "mav/dataset/planning_queries.h"

namespace mav::dataset {
namespace {

TEST(PlanningQueriesTest, ReadsStartGoalAndWaypointsWithComments) {
  auto q = ParsePlanningQueries(
      "# t4_3\n2 -27 15  20 -15 15\n\n  1 2 3 4 5 6 7 8 9   # a waypoint\n", "q.txt");
  ASSERT_TRUE(q.ok()) << q.status().ToString();
  ASSERT_EQ(q->size(), 2u);
  EXPECT_EQ((*q)[0].where, "q.txt:2");
  ASSERT_EQ((*q)[0].points.size(), 2u);
  EXPECT_EQ((*q)[0].points[0], Eigen::Vector3d(2, -27, 15));
  EXPECT_EQ((*q)[0].points[1], Eigen::Vector3d(20, -15, 15));
  ASSERT_EQ((*q)[1].points.size(), 3u);
  EXPECT_EQ((*q)[1].points[1], Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ((*q)[1].where, "q.txt:4");
}

TEST(PlanningQueriesTest, RefusesBadLinesNamingFileAndLine) {
  auto q = ParsePlanningQueries("1 2 3 4 5 6\n1 2 3 4 5\n", "q.txt");
  ASSERT_FALSE(q.ok());
  EXPECT_EQ(q.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(q.status().message().rfind("q.txt:2: ", 0), 0u) << q.status().message();

  q = ParsePlanningQueries("1 2 3 4 5 x\n", "q.txt");
  ASSERT_FALSE(q.ok());
  EXPECT_EQ(q.status().message().rfind("q.txt:1: ", 0), 0u) << q.status().message();

  q = ParsePlanningQueries("1 2 3 4 5 inf\n", "q.txt");
  ASSERT_FALSE(q.ok());
  EXPECT_EQ(q.status().code(), StatusCode::kInvalidArgument);

  q = ParsePlanningQueries("# nothing\n\n", "q.txt");
  ASSERT_FALSE(q.ok());
  EXPECT_NE(q.status().message().find("no queries"), std::string::npos);

  EXPECT_EQ(ReadPlanningQueries("/nonexistent/queries.txt").status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace mav::dataset
