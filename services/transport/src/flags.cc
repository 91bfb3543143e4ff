#include "mav/transport/flags.h"

#include <cstdlib>
#include <string>

#include "mav/common/parse.h"

namespace mav::transport {

Result<int64_t> PortFromEnv(const std::string& name, int64_t fallback) {
  const char* text = std::getenv(name.c_str());
  if (text == nullptr || *text == '\0') return fallback;
  MAV_ASSIGN_OR_RETURN(int64_t port, ParseInt64(text, "environment variable " + name));
  if (port < 0 || port > 65535) {
    return Status::InvalidArgument("environment variable " + name + ": port " +
                                   std::to_string(port) + " is outside [0, 65535]");
  }
  return port;
}

}  // namespace mav::transport
