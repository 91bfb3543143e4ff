#include "mav/common/flags.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <type_traits>

#include "mav/common/parse.h"
#include "mav/common/text.h"

namespace mav {
namespace {

std::string DoubleText(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

template <typename T>
std::string NumberText(T v) {
  if constexpr (std::is_floating_point_v<T>) {
    return DoubleText(v);
  } else {
    return std::to_string(v);
  }
}

// "[min, max]", ">= min" or "<= max"; "" when the range is the type's whole range.
template <typename T>
std::string RangeText(T min, T max, T lowest, T highest) {
  std::string out;
  if (min == lowest && max == highest) return out;
  if (max == highest) {
    out = ">= ";
    out += NumberText(min);
  } else if (min == lowest) {
    out = "<= ";
    out += NumberText(max);
  } else {
    out = "[";
    out += NumberText(min);
    out += ", ";
    out += NumberText(max);
    out += "]";
  }
  return out;
}

// "-123" or "123": an integer, whether or not it fits in 64 bits.
bool IsIntegerLiteral(std::string_view text) {
  text = Trim(text);
  if (!text.empty() && text.front() == '-') text.remove_prefix(1);
  return !text.empty() && text.find_first_not_of("0123456789") == std::string_view::npos;
}

}  // namespace

FlagParser::Flag FlagParser::MakeFlag(const std::string& name, Kind kind, void* target,
                                      const std::string& help, const std::string& default_text) {
  Flag flag;
  flag.name = name;
  flag.kind = kind;
  flag.target = target;
  flag.help = help;
  flag.default_text = default_text;
  return flag;
}

void FlagParser::AddString(const std::string& name, std::string* target, const std::string& help) {
  Flag flag = MakeFlag(name, Kind::kString, target, help, *target);
  flags_.push_back(flag);
}
template <typename T>
void FlagParser::AddNumber(const std::string& name, Kind kind, T* target, const std::string& help,
                           T min, T max) {
  MAV_CHECK(min <= max) << "--" << name;  // also false for a NaN bound
  Flag flag = MakeFlag(name, kind, target, help, NumberText(*target));
  flag.range_text =
      RangeText(min, max, std::numeric_limits<T>::lowest(), std::numeric_limits<T>::max());
  if constexpr (std::is_same_v<T, int64_t>) {
    flag.int_min = min;
    flag.int_max = max;
  } else if constexpr (std::is_same_v<T, uint64_t>) {
    flag.uint_min = min;
    flag.uint_max = max;
  } else {
    flag.double_min = min;
    flag.double_max = max;
  }
  flags_.push_back(flag);
}

void FlagParser::AddInt64(const std::string& name, int64_t* target, const std::string& help,
                          int64_t min, int64_t max) {
  AddNumber(name, Kind::kInt64, target, help, min, max);
}
void FlagParser::AddUint64(const std::string& name, uint64_t* target, const std::string& help,
                           uint64_t min, uint64_t max) {
  AddNumber(name, Kind::kUint64, target, help, min, max);
}
void FlagParser::AddDouble(const std::string& name, double* target, const std::string& help,
                           double min, double max) {
  AddNumber(name, Kind::kDouble, target, help, min, max);
}
void FlagParser::AddBool(const std::string& name, bool* target, const std::string& help) {
  Flag flag = MakeFlag(name, Kind::kBool, target, help, *target ? "true" : "false");
  flags_.push_back(flag);
}

FlagParser::Flag* FlagParser::Find(const std::string& name) {
  for (Flag& f : flags_) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

bool FlagParser::WasSet(const std::string& name) const {
  for (const Flag& f : flags_) {
    if (f.name == name) return f.set;
  }
  return false;
}

Status FlagParser::Assign(Flag* flag, const std::string& value) {
  const std::string what = "--" + flag->name;
  // A number that parses but lies outside the flag's own range; ranges are closed intervals.
  const auto out_of_range = [&] {
    const std::string range = flag->range_text;
    return Status::InvalidArgument(what + ": " + QuoteForError(Trim(value)) + " is out of range " +
                                   (range.front() == '[' ? range : "(must be " + range + ")"));
  };
  switch (flag->kind) {
    case Kind::kString:
      if (value.empty()) return Status::InvalidArgument(what + ": empty value");
      *static_cast<std::string*>(flag->target) = value;
      break;
    case Kind::kInt64: {
      const Result<int64_t> v = ParseInt64(value, what);
      // An integer beyond 64 bits is out of the flag's own range, if it has one.
      if (!v.ok() && !flag->range_text.empty() && IsIntegerLiteral(value)) return out_of_range();
      if (!v.ok()) return v.status();
      if (*v < flag->int_min || *v > flag->int_max) return out_of_range();
      *static_cast<int64_t*>(flag->target) = *v;
      break;
    }
    case Kind::kUint64: {
      const Result<uint64_t> v = ParseUint64(value, what);
      if (!v.ok() && !flag->range_text.empty() && IsIntegerLiteral(value)) return out_of_range();
      if (!v.ok()) return v.status();
      if (*v < flag->uint_min || *v > flag->uint_max) return out_of_range();
      *static_cast<uint64_t*>(flag->target) = *v;
      break;
    }
    case Kind::kDouble: {
      MAV_ASSIGN_OR_RETURN(const double v, ParseDouble(value, what));
      if (v < flag->double_min || v > flag->double_max) return out_of_range();
      *static_cast<double*>(flag->target) = v;
      break;
    }
    case Kind::kBool:
      if (value == "true" || value == "1") {
        *static_cast<bool*>(flag->target) = true;
      } else if (value == "false" || value == "0") {
        *static_cast<bool*>(flag->target) = false;
      } else {
        return Status::InvalidArgument(what + ": expected true or false, got " +
                                       QuoteForError(value));
      }
      break;
  }
  flag->set = true;
  return Status::Ok();
}

Status FlagParser::Parse(const std::vector<std::string>& args, std::vector<std::string>* positional,
                         bool* help) {
  if (help != nullptr) *help = false;
  const auto add_positional = [&](const std::string& arg) {
    if (positional == nullptr) {
      return Status::InvalidArgument("unexpected argument " + QuoteForError(arg) +
                                     " (this takes flags only)");
    }
    positional->push_back(arg);
    return Status::Ok();
  };
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      if (help != nullptr) *help = true;
      continue;
    }
    if (arg == "--") {
      for (size_t k = i + 1; k < args.size(); ++k) MAV_RETURN_IF_ERROR(add_positional(args[k]));
      break;
    }
    if (arg.size() < 2 || arg[0] != '-') {
      MAV_RETURN_IF_ERROR(add_positional(arg));
      continue;
    }
    if (arg.rfind("--", 0) != 0) {
      return Status::InvalidArgument("unknown flag " + QuoteForError(arg) +
                                     " (flags are spelled --name)");
    }
    const size_t eq = arg.find('=');
    const std::string name = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    Flag* flag = Find(name);
    if (flag == nullptr) {
      // A plain name is shown as typed ("unknown flag --prot"); anything else quoted.
      const std::string quoted = QuoteForError(name);
      const std::string shown = quoted == "'" + name + "'" ? "--" + name : QuoteForError(arg);
      return Status::InvalidArgument("unknown flag " + shown + " (see --help)");
    }
    if (eq != std::string::npos) {
      MAV_RETURN_IF_ERROR(Assign(flag, arg.substr(eq + 1)));
    } else if (flag->kind == Kind::kBool) {
      MAV_RETURN_IF_ERROR(Assign(flag, "true"));
    } else {
      if (i + 1 >= args.size()) {
        return Status::InvalidArgument("--" + name + ": missing value");
      }
      const std::string& value = args[++i];
      // "--out --frames 3": a flag where a value should be is almost surely a forgotten value.
      if (value.rfind("--", 0) == 0) {
        return Status::InvalidArgument("--" + name + ": missing value (got flag " +
                                       QuoteForError(value) + ")");
      }
      MAV_RETURN_IF_ERROR(Assign(flag, value));
    }
  }
  return Status::Ok();
}

std::vector<std::string> FlagParser::ParseOrExit(int argc, char** argv, int first,
                                                 bool allow_positional) {
  const std::vector<std::string> args(argv + std::min(first, argc), argv + argc);
  std::vector<std::string> positional;
  bool help = false;
  const Status s = Parse(args, allow_positional ? &positional : nullptr, &help);
  const std::string program = program_.empty() ? std::string(argv[0]) : program_;
  if (!s.ok()) {
    std::fprintf(stderr, "%s: %s\n%s", program.c_str(), s.message().c_str(), Help().c_str());
    std::exit(2);
  }
  if (help) {
    std::fputs(Help().c_str(), stdout);
    std::exit(0);
  }
  return positional;
}

std::string FlagParser::Help() const {
  std::ostringstream out;
  out << "usage: " << usage_ << "\n";
  if (!flags_.empty()) out << "\nflags:\n";
  size_t width = 0;
  for (const Flag& f : flags_) width = std::max(width, f.name.size() + 2);
  for (const Flag& f : flags_) {
    out << "  --" << f.name << std::string(width - f.name.size(), ' ') << f.help;
    if (!f.default_text.empty() && f.kind != Kind::kBool) {
      out << " (default: " << f.default_text;
      if (!f.range_text.empty()) out << ", " << f.range_text;
      out << ")";
    }
    out << "\n";
  }
  out << "  --help" << std::string(width - 4, ' ') << "show this help\n";
  return out.str();
}

}  // namespace mav
