#pragma once
// Minimal leveled logging to stderr: `MAV_LOG(kInfo) << "loaded " << n << " frames";`
// The threshold comes from SetLogLevel() or the MAV_LOG_LEVEL environment variable
// (debug|info|warning|error), read once.

#include <sstream>

namespace mav {

enum class LogLevel { kDebug = 0, kInfo = 1, kWarning = 2, kError = 3 };

void SetLogLevel(LogLevel level);
LogLevel GetLogLevel();

namespace internal {
class LogMessage {
 public:
  LogMessage(LogLevel level, const char* file, int line);
  ~LogMessage();
  std::ostream& stream() { return stream_; }

 private:
  LogLevel level_;
  std::ostringstream stream_;
};
}  // namespace internal

}  // namespace mav

#define MAV_LOG(level)                                 \
  if (::mav::LogLevel::level < ::mav::GetLogLevel()) { \
  } else                                               \
    ::mav::internal::LogMessage(::mav::LogLevel::level, __FILE__, __LINE__).stream()
