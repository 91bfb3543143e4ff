#pragma once
// Helpers for the dataset tests (and the other tests that run the built tools): a temporary
// directory removed at the end of a test, whole-file reads and writes, running a binary.

#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/common/build_paths.h"

namespace mav::dataset::testing {

class TempDir {
 public:
  TempDir() {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = (std::filesystem::temp_directory_path() /
             ("mav_dataset_" + std::string(info ? info->test_suite_name() : "x") + "_" +
              std::string(info ? info->name() : "y") + "_" + std::to_string(getpid())))
                .string();
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

inline void WriteFile(const std::string& path, const std::string& contents) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << contents;
}

inline std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

struct RunResult {
  int exit_code = -1;  // 124 if `timeout` stopped it
  std::string output;  // stdout and stderr
};

// Runs build/bin/<binary> <args> under `timeout`, so that a hang fails the test instead of
// stalling it.
inline RunResult RunTool(const std::string& binary, const std::string& args, int timeout_s = 120) {
  const std::string command = "timeout " + std::to_string(timeout_s) + " " +
                              mav::testing::BinaryDir() + "/bin/" + binary + " " + args + " 2>&1";
  RunResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  char buffer[4096];
  size_t n;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) result.output.append(buffer, n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

}  // namespace mav::dataset::testing
