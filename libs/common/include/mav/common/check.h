#pragma once
// MAV_CHECK: a violated invariant is a bug. It prints the condition, the place and a message,
// then aborts. Expected failures are Status values (status.h), never checks.
//
//   MAV_CHECK(width > 0) << "image width " << width;

#include <sstream>

namespace mav::internal {

class CheckFailure {
 public:
  CheckFailure(const char* condition, const char* file, int line);
  [[noreturn]] ~CheckFailure();
  std::ostream& stream() { return stream_; }

 private:
  std::ostringstream stream_;
};

// Lets `MAV_CHECK(c) << ...` be a single expression of type void.
struct Voidify {
  void operator&(std::ostream&) {}
};

}  // namespace mav::internal

#define MAV_CHECK(condition)                 \
  (condition) ? (void)0                      \
              : ::mav::internal::Voidify() & \
                    ::mav::internal::CheckFailure(#condition, __FILE__, __LINE__).stream()
