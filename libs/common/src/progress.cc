#include "mav/common/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>

#include "mav/common/time.h"

namespace mav {

ProgressBar::ProgressBar(std::string label, int64_t total)
    : label_(std::move(label)),
      total_(std::max<int64_t>(total, 1)),
      start_ns_(MonotonicNowNs()),
      tty_(isatty(STDERR_FILENO) == 1) {}

ProgressBar::~ProgressBar() {
  if (!finished_) Finish();
}

void ProgressBar::Update(int64_t done) {
  done_ = std::clamp<int64_t>(done, 0, total_);
  Draw(false);
}

void ProgressBar::Finish() {
  if (finished_) return;
  done_ = total_;
  Draw(true);
  if (tty_) std::fputc('\n', stderr);
  finished_ = true;
}

void ProgressBar::Draw(bool force) {
  const int64_t now = MonotonicNowNs();
  const double fraction = static_cast<double>(done_) / static_cast<double>(total_);
  const double elapsed_s = NsToSeconds(now - start_ns_);
  const double eta_s = fraction > 0 ? elapsed_s * (1.0 - fraction) / fraction : 0.0;
  if (tty_) {
    if (!force && now - last_draw_ns_ < 100'000'000) return;  // 10 redraws per second at most
    last_draw_ns_ = now;
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(fraction * kWidth);
    std::fprintf(stderr, "\r%s [%.*s%*s] %3d%% %lld/%lld  %.1fs elapsed, %.1fs left",
                 label_.c_str(), filled, "##############################", kWidth - filled, "",
                 static_cast<int>(fraction * 100), static_cast<long long>(done_),
                 static_cast<long long>(total_), elapsed_s, eta_s);
    std::fflush(stderr);
    return;
  }
  const int decile = static_cast<int>(fraction * 10);
  if (decile == last_decile_ && !force) return;
  if (decile == last_decile_ && force && done_ != total_) return;
  if (force && last_decile_ == 10) return;
  last_decile_ = decile;
  std::fprintf(stderr, "%s: %3d%% (%lld/%lld) %.1fs elapsed\n", label_.c_str(), decile * 10,
               static_cast<long long>(done_), static_cast<long long>(total_), elapsed_s);
}

}  // namespace mav
