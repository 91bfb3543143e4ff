#pragma once
// A small command-line flag parser shared by the command-line tools and services: "--name value" or
// "--name=value", boolean switches without a value, positional arguments kept in order. Every error
// names the flag and quotes the value (QuoteForError: escaped, truncated):
// "--frames: 'ten' is not an integer", "--frames: '99999999999999999999' is out of range
// [0, 1000000]", "--occupancy-resolution: must be a finite number, got 'inf'",
// "unknown flag --frame (see --help)".

#include <cstdint>
#include <limits>
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
  // Numeric flags take an optional closed range [min, max]: a value outside it is refused with
  // "--name: 'v' is out of range [min, max]" (shown in Help() too). Doubles must be finite
  // (ParseDouble), so "--x inf" is refused whatever the range.
  void AddString(const std::string& name, std::string* target, const std::string& help);
  void AddInt64(const std::string& name, int64_t* target, const std::string& help,
                int64_t min = std::numeric_limits<int64_t>::min(),
                int64_t max = std::numeric_limits<int64_t>::max());
  void AddInt(const std::string& name, int64_t* target, const std::string& help,
              int64_t min = std::numeric_limits<int64_t>::min(),
              int64_t max = std::numeric_limits<int64_t>::max()) {
    AddInt64(name, target, help, min, max);
  }
  void AddUint64(const std::string& name, uint64_t* target, const std::string& help,
                 uint64_t min = 0, uint64_t max = std::numeric_limits<uint64_t>::max());
  void AddDouble(const std::string& name, double* target, const std::string& help,
                 double min = std::numeric_limits<double>::lowest(),
                 double max = std::numeric_limits<double>::max());
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
    Kind kind = Kind::kString;
    void* target = nullptr;
    std::string help;
    std::string default_text;
    // The accepted range of the numeric kinds, and its text for messages ("" = unrestricted).
    int64_t int_min = 0, int_max = 0;
    uint64_t uint_min = 0, uint_max = 0;
    double double_min = 0, double_max = 0;
    std::string range_text;
    bool set = false;
  };
  static Flag MakeFlag(const std::string& name, Kind kind, void* target, const std::string& help,
                       const std::string& default_text);
  template <typename T>
  void AddNumber(const std::string& name, Kind kind, T* target, const std::string& help, T min,
                 T max);
  Flag* Find(const std::string& name);
  Status Assign(Flag* flag, const std::string& value);

  std::string usage_;
  std::string program_;  // for ParseOrExit's messages
  std::vector<Flag> flags_;
};

}  // namespace mav
