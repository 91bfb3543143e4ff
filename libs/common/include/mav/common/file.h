#pragma once
// File helpers that never leave a half-written file behind: writes go to "<path>.tmp" and are
// renamed into place only when complete.

#include <string>

#include "mav/common/status.h"

namespace mav {

Result<std::string> ReadFileToString(const std::string& path);
Status WriteStringToFileAtomic(const std::string& path, const std::string& contents);
// Creates the directory and its parents; OK if it exists.
Status MakeDirectories(const std::string& path);
bool PathExists(const std::string& path);
bool IsDirectory(const std::string& path);

}  // namespace mav
