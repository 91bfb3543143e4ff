#pragma once
// The last error a long-running component met, stamped with the (monotonic) time it was set, so
// that a status can say how old it is: a client tells a failure of this run from one long gone.
//
//   LastError last_error_;
//   last_error_ = "lock-step: no command for step 12";   // stamped now
//   status.last_error = last_error_.text();
//   status.last_error_age_s = last_error_.AgeS();        // 0 when empty
//
// Not thread-safe (guard it with the component's mutex).

#include <cstdint>
#include <string>
#include <utility>

#include "mav/common/time.h"

namespace mav {

class LastError {
 public:
  LastError& operator=(std::string text) {
    text_ = std::move(text);
    set_ns_ = MonotonicNowNs();
    return *this;
  }
  void clear() {
    text_.clear();
    set_ns_ = 0;
  }
  bool empty() const { return text_.empty(); }
  const std::string& text() const { return text_; }
  // Seconds from when it was set to now_ns (0 when empty).
  double AgeS(int64_t now_ns) const { return empty() ? 0.0 : NsToSeconds(now_ns - set_ns_); }
  double AgeS() const { return AgeS(MonotonicNowNs()); }

 private:
  std::string text_;
  int64_t set_ns_ = 0;
};

}  // namespace mav
