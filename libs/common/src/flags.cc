#include "mav/common/flags.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "mav/common/parse.h"

namespace mav {
namespace {

std::string DoubleText(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

}  // namespace

void FlagParser::AddString(const std::string& name, std::string* target, const std::string& help) {
  flags_.push_back({name, Kind::kString, target, help, *target});
}
void FlagParser::AddInt64(const std::string& name, int64_t* target, const std::string& help) {
  flags_.push_back({name, Kind::kInt64, target, help, std::to_string(*target)});
}
void FlagParser::AddUint64(const std::string& name, uint64_t* target, const std::string& help) {
  flags_.push_back({name, Kind::kUint64, target, help, std::to_string(*target)});
}
void FlagParser::AddDouble(const std::string& name, double* target, const std::string& help) {
  flags_.push_back({name, Kind::kDouble, target, help, DoubleText(*target)});
}
void FlagParser::AddBool(const std::string& name, bool* target, const std::string& help) {
  flags_.push_back({name, Kind::kBool, target, help, *target ? "true" : "false"});
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
  switch (flag->kind) {
    case Kind::kString:
      if (value.empty()) return Status::InvalidArgument(what + ": empty value");
      *static_cast<std::string*>(flag->target) = value;
      break;
    case Kind::kInt64: {
      MAV_ASSIGN_OR_RETURN(*static_cast<int64_t*>(flag->target), ParseInt64(value, what));
      break;
    }
    case Kind::kUint64: {
      MAV_ASSIGN_OR_RETURN(const int64_t v, ParseInt64(value, what));
      if (v < 0) return Status::InvalidArgument(what + ": must be >= 0, got " + value);
      *static_cast<uint64_t*>(flag->target) = static_cast<uint64_t>(v);
      break;
    }
    case Kind::kDouble: {
      MAV_ASSIGN_OR_RETURN(*static_cast<double*>(flag->target), ParseDouble(value, what));
      break;
    }
    case Kind::kBool:
      if (value == "true" || value == "1") {
        *static_cast<bool*>(flag->target) = true;
      } else if (value == "false" || value == "0") {
        *static_cast<bool*>(flag->target) = false;
      } else {
        return Status::InvalidArgument(what + ": expected true or false, got '" + value + "'");
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
      return Status::InvalidArgument("unexpected argument '" + arg + "' (this takes flags only)");
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
      return Status::InvalidArgument("unknown flag '" + arg + "' (flags are spelled --name)");
    }
    const size_t eq = arg.find('=');
    const std::string name = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    Flag* flag = Find(name);
    if (flag == nullptr) {
      return Status::InvalidArgument("unknown flag --" + name + " (see --help)");
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
        return Status::InvalidArgument("--" + name + ": missing value (got flag '" + value + "')");
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
    if (!f.default_text.empty() && f.kind != Kind::kBool)
      out << " (default: " << f.default_text << ")";
    out << "\n";
  }
  out << "  --help" << std::string(width - 4, ' ') << "show this help\n";
  return out.str();
}

}  // namespace mav
