#include "mav/eval/report.h"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "mav/common/file.h"

namespace mav::eval {
namespace {

TEST(JsonReportTest, GroupsAndMetricsKeepFirstOrderAndReplaceInPlace) {
  JsonReport json;
  EXPECT_TRUE(json.empty());
  json.Set("b", "x", 1.0);
  json.Set("a", "y", std::string("text"));
  json.Set("b", "z", 2.5);
  json.Set("b", "x", 3.0);  // replaces, keeps its place
  EXPECT_FALSE(json.empty());
  EXPECT_EQ(json.ToString(),
            "{\n  \"b\": {\n    \"x\": 3,\n    \"z\": 2.5\n  },\n  \"a\": {\n    \"y\": "
            "\"text\"\n  }\n}\n");
}

TEST(JsonReportTest, RecordsAndNonFiniteNumbers) {
  JsonReport json;
  json.Set("m", "queries",
           std::vector<JsonReport::Record>{{{"status", std::string("OK")}, {"ms", 1.5}},
                                           {{"status", std::string("NO")}, {"ms", NAN}}});
  json.Set("m", "none", std::vector<JsonReport::Record>{});
  EXPECT_EQ(json.ToString(),
            "{\n  \"m\": {\n    \"queries\": [\n      {\"status\": \"OK\", \"ms\": 1.5},\n      "
            "{\"status\": \"NO\", \"ms\": null}\n    ],\n    \"none\": []\n  }\n}\n");
}

TEST(ReportTextTest, LaysOutTitleHeaderRowsNotes) {
  Report report;
  ReportTable& first = report.AddTable("", /*blank_line_before=*/false);
  first.notes = {"setup"};
  ReportTable& second = report.AddTable("Title");
  second.header = {"h1", "h2"};
  second.rows = {"r1"};
  second.notes = {"n1"};
  report.AddTable("", /*blank_line_before=*/false).rows = {"more"};
  EXPECT_EQ(ReportText(report), "setup\n\nTitle\nh1\nh2\nr1\nn1\nmore\n");
  EXPECT_EQ(ReportText(Report()), "");
}

TEST(ReportTextTest, FormatLineHasNoLengthLimit) {
  const std::string long_text(5000, 'x');
  const std::string line = FormatLine("%s|%5.2f|%-4s|", long_text.c_str(), 3.14159, "ab");
  EXPECT_EQ(line.size(), 5000u + 12u);
  EXPECT_EQ(line.substr(5000), "| 3.14|ab  |");
}

TEST(WriteReportJsonTest, DocumentReplacesTheModel) {
  const std::string dir = ::testing::TempDir();
  Report report;
  report.json.Set("g", "m", 1.0);
  ASSERT_TRUE(WriteReportJson(report, dir + "/model.json").ok());
  EXPECT_EQ(*ReadFileToString(dir + "/model.json"), report.json.ToString());
  report.json_document = "{\"own\": 1}\n";
  ASSERT_TRUE(WriteReportJson(report, dir + "/document.json").ok());
  EXPECT_EQ(*ReadFileToString(dir + "/document.json"), "{\"own\": 1}\n");
  EXPECT_FALSE(WriteReportJson(report, dir + "/no/such/dir/x.json").ok());
}

}  // namespace
}  // namespace mav::eval
