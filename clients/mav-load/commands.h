#pragma once
// The commands of mav-load (main.cc dispatches): each parses its flags (load.h's common ones and
// its own), prepares its requests and the server, and runs the shared load loop. Each returns the
// exit status: 0; 1 a failed condition or the server cannot be reached / set up; 2 usage error.

#include <string>
#include <vector>

namespace mav::load {

int RunPlanning(const std::vector<std::string>& args);      // planning.cc
int RunLocalization(const std::vector<std::string>& args);  // localization.cc
int RunMapping(const std::vector<std::string>& args);       // mapping.cc
int RunControl(const std::vector<std::string>& args);       // control.cc

}  // namespace mav::load
