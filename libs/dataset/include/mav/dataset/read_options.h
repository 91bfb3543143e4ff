#pragma once
// How the readers of time-stamped files (EuRoC imu0 and ground-truth CSVs, TUM trajectories)
// treat a time stamp that repeats the previous row's.
//
// Real files from the field do this: TUM's own fr2/desk ground truth and an ORB-SLAM TUM output
// of EuRoC V1_02 each repeat one stamp. Refusing such a file helps nobody, so by default the
// readers keep the first row of a repeated stamp, drop the others and warn naming the file and
// line. Time going backwards is still an error: that is a broken file, not a rounding artefact.
// Our own writers never write a repeated stamp, so code that reads data we generated ourselves
// (round-trip tests, the simulator's outputs) asks for kReject to stay strict.

#include <string>
#include <vector>

namespace mav::dataset {

enum class RepeatedStamps {
  kKeepFirst,  // keep the first row with that stamp, drop the rest, warn (file:line)
  kReject,     // InvalidArgument "path:line: timestamp T is not after the previous one (T)"
};

struct ReadOptions {
  // Default kKeepFirst: the readers' callers are mostly users with files from other tools.
  RepeatedStamps repeated_stamps = RepeatedStamps::kKeepFirst;
  // Where the warnings go ("path:line: timestamp T repeats the previous row's; row dropped").
  // Null (the default): logged with MAV_LOG(kWarning), at most kMaxLoggedWarnings per file, then
  // one line with the count of the rest, so a file with thousands of repeats cannot flood the
  // log. Non-null: every warning is appended here instead (for a service that returns them, or a
  // test), and nothing is logged.
  std::vector<std::string>* warnings = nullptr;

  static constexpr int kMaxLoggedWarnings = 10;

  bool IsValid(std::string* why) const {
    if (repeated_stamps != RepeatedStamps::kKeepFirst &&
        repeated_stamps != RepeatedStamps::kReject) {
      if (why != nullptr) *why = "repeated_stamps: not a RepeatedStamps value";
      return false;
    }
    return true;
  }
};

}  // namespace mav::dataset
