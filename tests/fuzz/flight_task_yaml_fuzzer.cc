// libFuzzer target: contest task files (dataset::ParseFlightTaskYaml, what `mav-eval control
// --task-file`, mav-simulator's LoadFlightTask{yaml} and mav-control read). The resolver hands
// out a plain built-in-like task for any name, so the fuzzer reaches every key.

#include <string>

#include "fuzz_checks.h"
#include "mav/dataset/flight_task_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  const std::string text(fuzz::AsText(data, size));
  const dataset::FlightTaskResolver resolve =
      [](const std::string& name) -> Result<dataset::FlightTask> {
    if (name != "t3_1" && name != "t4_1") return Status::NotFound("no built-in task " + name);
    dataset::FlightTask task;
    task.name = name;
    return task;
  };
  const Result<dataset::FlightTask> task =
      dataset::ParseFlightTaskYaml(text, fuzz::kName, resolve, "t3_1");
  if (!task.ok()) {
    // An unknown base is the resolver's NotFound, passed on.
    if (task.status().code() == StatusCode::kNotFound) return 0;
    fuzz::CheckFailure(task.status());
    return 0;
  }
  std::string why;
  MAV_CHECK(task->IsValid(&why)) << why.substr(0, 300);
  return 0;
}
