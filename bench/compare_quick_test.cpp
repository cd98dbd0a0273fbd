// Runs the benchmark driver in --quick mode (a smoke test of every section, seconds) and checks that it
// writes a well-formed CSV: the documented header, the same number of fields on every row, numbers where
// numbers belong, and rows from each section. Runs the micro-benchmarks with minimal repetitions and checks
// that they get to the end and write a row with a rate for every benchmark. No timing is asserted.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

namespace {

// Splits one CSV line (RFC 4180 quoting, no embedded newlines).
std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        fields.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        fields.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  EXPECT_FALSE(quoted) << "unterminated quote in: " << line;
  return fields;
}

bool IsNumberOrEmpty(const std::string& s) {
  if (s.empty()) return true;
  char* end = nullptr;
  std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size();
}

TEST(CompareDriver, QuickModeWritesAWellFormedCsv) {
  const std::filesystem::path csv =
      std::filesystem::temp_directory_path() / ("s2m_compare_quick_" + std::to_string(::getpid()) + ".csv");
  const std::string command =
      std::string("\"") + S2M_COMPARE_PATH + "\" --quick --csv \"" + csv.string() + "\" > /dev/null";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  std::ifstream in(csv);
  ASSERT_TRUE(in) << csv;
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  const std::vector<std::string> header = SplitCsv(line);
  const std::vector<std::string> expected = {"section",     "case",       "method",  "points", "views",
                                             "start",       "iterations", "seconds", "error",  "final_error",
                                             "peak_rss_mb", "metric",     "note"};
  ASSERT_EQ(header, expected);
  std::set<std::string> sections, families;
  int rows = 0;
  while (std::getline(in, line)) {
    ++rows;
    const std::vector<std::string> f = SplitCsv(line);
    ASSERT_EQ(f.size(), header.size()) << "row " << rows << ": " << line;
    EXPECT_FALSE(f[0].empty()) << line;
    EXPECT_FALSE(f[2].empty()) << line;
    for (std::size_t k = 3; k <= 10; ++k) EXPECT_TRUE(IsNumberOrEmpty(f[k])) << header[k] << " in " << line;
    sections.insert(f[0].substr(0, 1));
    if (f[0] == "4 families") {
      families.insert(f[1]);
      EXPECT_GT(std::strtod(f[7].c_str(), nullptr), 0.0) << "a family's time per iteration: " << line;
    }
  }
  // Section 2 needs ../shared/data; the others always run.
  EXPECT_TRUE(sections.count("1"));
  EXPECT_TRUE(sections.count("3"));
  EXPECT_TRUE(sections.count("4"));
  EXPECT_GE(rows, 10);
  // Section 4's cost per point of every model family (CostFamilyNames of bench/model_families.h): one row
  // each, a failed fit writes none.
  EXPECT_EQ(families.size(), 9u);
  std::filesystem::remove(csv);
}

TEST(MicroBenchmarks, RunToTheEndAndWriteARateForEveryBenchmark) {
  const std::filesystem::path csv =
      std::filesystem::temp_directory_path() / ("s2m_micro_" + std::to_string(::getpid()) + ".csv");
  // Google Benchmark's CSV reporter aborts the whole run when a user counter appears in some rows only (as it
  // once did at the last benchmark): the CSV is checked to the last row.
  const std::string command = std::string("\"") + S2M_MICRO_BENCHMARKS_PATH +
                              "\" --benchmark_min_time=0.001 --benchmark_out_format=csv --benchmark_out=\"" +
                              csv.string() + "\" > /dev/null 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  std::ifstream in(csv);
  ASSERT_TRUE(in) << csv;
  std::string line;
  std::vector<std::string> header;
  while (std::getline(in, line) && header.empty()) {
    if (line.rfind("name,", 0) == 0) header = SplitCsv(line);  // context lines come first
  }
  ASSERT_FALSE(header.empty()) << "no CSV header in " << csv;
  const auto column = [&](const std::string& name) {
    for (std::size_t k = 0; k < header.size(); ++k)
      if (header[k] == name) return k;
    ADD_FAILURE() << "no column " << name;
    return header.size();
  };
  const std::size_t name_column = column("name"), rate_column = column("items_per_second");
  ASSERT_LT(rate_column, header.size());
  std::set<std::string> names;
  do {
    const std::vector<std::string> f = SplitCsv(line);
    ASSERT_EQ(f.size(), header.size()) << line;
    names.insert(f[name_column]);
    EXPECT_GT(std::strtod(f[rate_column].c_str(), nullptr), 0.0) << line;
  } while (std::getline(in, line));
  for (const char* expected :
       {"FootPointsCold/cylinder", "FootPointsCold/sphere", "FootPointsWarm/bspline_surface",
        "FootPointsWarmTrusted/revolution", "RigidAssembly", "SquaredDistanceFieldQueries/cylinder"})
    EXPECT_TRUE(names.count(expected)) << expected;
  EXPECT_GE(names.size(), 20u);
  std::filesystem::remove(csv);
}

}  // namespace
