#include "mav/transport/flags.h"

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>

#include "mav/common/parse.h"

namespace mav::transport {

FlagParser::FlagParser(std::string program, std::string description)
    : program_(std::move(program)), description_(std::move(description)) {}

void FlagParser::AddString(const std::string& name, std::string* value, const std::string& help) {
  flags_.push_back({name, Kind::kString, value, help, "\"" + *value + "\""});
}

void FlagParser::AddInt(const std::string& name, int64_t* value, const std::string& help) {
  flags_.push_back({name, Kind::kInt, value, help, std::to_string(*value)});
}

void FlagParser::AddDouble(const std::string& name, double* value, const std::string& help) {
  std::ostringstream text;
  text << *value;
  flags_.push_back({name, Kind::kDouble, value, help, text.str()});
}

void FlagParser::AddBool(const std::string& name, bool* value, const std::string& help) {
  flags_.push_back({name, Kind::kBool, value, help, *value ? "true" : "false"});
}

FlagParser::Flag* FlagParser::Find(const std::string& name) {
  for (Flag& flag : flags_) {
    if (flag.name == name) return &flag;
  }
  return nullptr;
}

bool FlagParser::WasSet(const std::string& name) const {
  for (const Flag& flag : flags_) {
    if (flag.name == name) return flag.set;
  }
  return false;
}

Status FlagParser::Assign(Flag* flag, const std::string& text) {
  const std::string what = "--" + flag->name;
  switch (flag->kind) {
    case Kind::kString:
      *static_cast<std::string*>(flag->value) = text;
      break;
    case Kind::kInt: {
      MAV_ASSIGN_OR_RETURN(int64_t v, ParseInt64(text, what));
      *static_cast<int64_t*>(flag->value) = v;
      break;
    }
    case Kind::kDouble: {
      MAV_ASSIGN_OR_RETURN(double v, ParseDouble(text, what));
      *static_cast<double*>(flag->value) = v;
      break;
    }
    case Kind::kBool:
      if (text == "true" || text == "1" || text == "yes") {
        *static_cast<bool*>(flag->value) = true;
      } else if (text == "false" || text == "0" || text == "no") {
        *static_cast<bool*>(flag->value) = false;
      } else {
        return Status::InvalidArgument(what + ": '" + text + "' is not a boolean (true|false)");
      }
      break;
  }
  flag->set = true;
  return Status::Ok();
}

Status FlagParser::Parse(const std::vector<std::string>& args, std::vector<std::string>* positional,
                         bool* help_requested) {
  if (help_requested != nullptr) *help_requested = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      if (help_requested != nullptr) *help_requested = true;
      return Status::Ok();
    }
    if (arg == "--") {
      for (size_t j = i + 1; j < args.size(); ++j) {
        if (positional == nullptr) {
          return Status::InvalidArgument("unexpected argument '" + args[j] + "'");
        }
        positional->push_back(args[j]);
      }
      return Status::Ok();
    }
    if (arg.rfind("--", 0) != 0 || arg.size() == 2) {
      if (positional == nullptr)
        return Status::InvalidArgument("unexpected argument '" + arg + "'");
      positional->push_back(arg);
      continue;
    }
    std::string name = arg.substr(2);
    std::string value;
    bool has_value = false;
    if (const size_t eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name.resize(eq);
      has_value = true;
    }
    Flag* flag = Find(name);
    if (flag == nullptr) {
      return Status::InvalidArgument("unknown flag --" + name + " (see --help)");
    }
    if (!has_value) {
      if (flag->kind == Kind::kBool) {
        value = "true";
      } else if (i + 1 < args.size()) {
        value = args[++i];
      } else {
        return Status::InvalidArgument("--" + name + ": missing value");
      }
    }
    MAV_RETURN_IF_ERROR(Assign(flag, value));
  }
  return Status::Ok();
}

std::vector<std::string> FlagParser::ParseOrExit(int argc, char** argv, int first,
                                                 bool allow_positional) {
  std::vector<std::string> args;
  for (int i = first; i < argc; ++i) args.emplace_back(argv[i]);
  std::vector<std::string> positional;
  bool help = false;
  const Status status = Parse(args, allow_positional ? &positional : nullptr, &help);
  if (help) {
    std::cout << Usage();
    std::exit(0);
  }
  if (!status.ok()) {
    std::cerr << program_ << ": " << status.message() << "\n\n" << Usage();
    std::exit(2);
  }
  return positional;
}

std::string FlagParser::Usage() const {
  std::ostringstream out;
  out << "Usage: " << program_ << " [flags]\n";
  if (!description_.empty()) out << description_ << "\n";
  out << "Flags:\n";
  for (const Flag& flag : flags_) {
    out << "  --" << flag.name;
    if (flag.kind != Kind::kBool) out << " VALUE";
    out << "\n      " << flag.help << " (default " << flag.default_text << ")\n";
  }
  return out.str();
}

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
