#pragma once
// A small command-line flag parser shared by the command-line tools and services: "--name value" or
// "--name=value", boolean switches without a value, positional arguments kept in order. Every error
// names the flag: "--frames: 'ten' is not an integer", "unknown flag '--frame' (see --help)".

#include <cstdint>
#include <string>
#include <vector>

#include "mav/common/status.h"

namespace mav {

class FlagParser {
 public:
  // `usage` is the first line of Help(), e.g. "mav-sim generate --preset P --out DIR [flags]".
  explicit FlagParser(std::string usage) : usage_(std::move(usage)) {}
  // For a program without subcommands: "usage: <program> [flags]" followed by `description`.
  FlagParser(const std::string& program, const std::string& description)
      : usage_(program + " [flags]" + (description.empty() ? "" : "\n\n" + description)),
        program_(program) {}

  // The target keeps its value unless the flag is given; its current value is shown as default.
  void AddString(const std::string& name, std::string* target, const std::string& help);
  void AddInt64(const std::string& name, int64_t* target, const std::string& help);
  void AddInt(const std::string& name, int64_t* target, const std::string& help) {
    AddInt64(name, target, help);
  }
  void AddUint64(const std::string& name, uint64_t* target, const std::string& help);
  void AddDouble(const std::string& name, double* target, const std::string& help);
  // A switch: "--name" sets true; "--name=true|false|1|0" is accepted too.
  void AddBool(const std::string& name, bool* target, const std::string& help);

  // Parses args (without the program and command names). Sets *help (if given) when --help/-h
  // was seen. With `positional` null, a positional argument is an error.
  Status Parse(const std::vector<std::string>& args, std::vector<std::string>* positional,
               bool* help = nullptr);
  // Parses argv[first..argc). On error prints "<program>: <error>" and the usage to stderr and
  // exits with status 2; on --help prints the usage to stdout and exits 0.
  std::vector<std::string> ParseOrExit(int argc, char** argv, int first = 1,
                                       bool allow_positional = false);
  // True if the flag appeared on the command line.
  bool WasSet(const std::string& name) const;
  std::string Help() const;
  std::string Usage() const { return Help(); }

 private:
  enum class Kind { kString, kInt64, kUint64, kDouble, kBool };
  struct Flag {
    std::string name;
    Kind kind;
    void* target;
    std::string help;
    std::string default_text;
    bool set = false;
  };
  Flag* Find(const std::string& name);
  Status Assign(Flag* flag, const std::string& value);

  std::string usage_;
  std::string program_;  // for ParseOrExit's messages
  std::vector<Flag> flags_;
};

}  // namespace mav
