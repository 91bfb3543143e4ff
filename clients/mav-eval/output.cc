#include "output.h"

#include <cstdio>
#include <iostream>

namespace mav::eval_cli {

int Fail(const std::string& command, const std::string& message, int code) {
  std::cerr << command << ": " << message << "\n";
  return code;
}

std::optional<int> ParseDataCommand(FlagParser& flags, const std::vector<std::string>& args,
                                    const std::string& command, const std::string& data) {
  std::vector<std::string> positional;
  bool help = false;
  if (Status s = flags.Parse(args, &positional, &help); !s.ok()) {
    return Fail(command, s.message(), 2);
  }
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (data.empty() || !positional.empty()) {
    std::cerr << command << ": --data DIR is required\n" << flags.Help();
    return 2;
  }
  return std::nullopt;
}

Status PrintReport(const eval::Report& report, const std::string& json_path) {
  std::fputs(eval::ReportText(report).c_str(), stdout);
  std::fflush(stdout);
  if (json_path.empty()) return Status::Ok();
  return eval::WriteReportJson(report, json_path);
}

eval::StepProgress ProgressPrinter::Callback() {
  return [bar = bar_](std::string_view stage, int64_t done, int64_t total) {
    if (*bar == nullptr) *bar = std::make_unique<ProgressBar>(std::string(stage), total);
    (*bar)->Update(done);
    if (done >= total) {
      (*bar)->Finish();
      bar->reset();
    }
  };
}

}  // namespace mav::eval_cli
