#pragma once
// A progress bar for long command-line work (rendering a data set, building a map).
// On a terminal it redraws one line on stderr; otherwise (CI logs, pipes) it prints a line at
// every 10 % so logs stay short. Thread-compatible: call Update() from one thread.

#include <cstdint>
#include <string>

namespace mav {

class ProgressBar {
 public:
  ProgressBar(std::string label, int64_t total);
  ~ProgressBar();  // Finishes the line if Finish() was not called.

  void Update(int64_t done);
  void Finish();

 private:
  void Draw(bool force);

  std::string label_;
  int64_t total_;
  int64_t done_ = 0;
  int64_t start_ns_;
  int64_t last_draw_ns_ = 0;
  int last_decile_ = -1;
  bool tty_;
  bool finished_ = false;
};

}  // namespace mav
