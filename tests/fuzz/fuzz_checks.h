#pragma once
// What every fuzz target asserts besides "no crash, no sanitizer report": an error is a
// readable value (InvalidArgument/DataLoss naming the input, a bounded message whatever the
// input's size: issue 8 defect 4), never an exception or an abort. MAV_CHECK failures abort,
// which libFuzzer reports as a crash with the input that caused it.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mav/common/check.h"
#include "mav/common/status.h"
#include "mav/dataset/read_options.h"

namespace mav::fuzz {

// The name the targets give their input in messages.
inline constexpr const char* kName = "fuzz-input";

inline std::string_view AsText(const uint8_t* data, size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// A failure names the input, has one of the expected codes, and stays short: quoted values are
// truncated (QuoteForError), so 1 KiB is plenty for any message.
inline void CheckFailure(const Status& status) {
  MAV_CHECK(!status.ok());
  MAV_CHECK(status.code() == StatusCode::kInvalidArgument || status.code() == StatusCode::kDataLoss)
      << status.ToString().substr(0, 300);
  MAV_CHECK(status.message().size() <= 1024) << status.message().substr(0, 300);
  MAV_CHECK(status.message().find(kName) != std::string_view::npos)
      << status.message().substr(0, 300);
}

// The targets of the stamped text files (IMU CSV, TUM trajectories): `parse(text, name, options)`
// returns the rows or a failure. A lenient read either fails as CheckFailure wants or gives rows
// with strictly increasing stamps (`t_ns`) that each pass `check_row`; a strict read (repeated
// stamps rejected) accepts exactly the lenient reads that dropped nothing.
template <typename Parse, typename CheckRow>
void CheckLenientAndStrictReads(std::string_view text, const Parse& parse,
                                const CheckRow& check_row) {
  std::vector<std::string> warnings;
  dataset::ReadOptions options;
  options.warnings = &warnings;
  const auto rows = parse(text, kName, options);
  if (!rows.ok()) {
    CheckFailure(rows.status());
  } else {
    for (size_t i = 0; i < rows->size(); ++i) {
      MAV_CHECK(i == 0 || (*rows)[i].t_ns > (*rows)[i - 1].t_ns) << "stamps strictly increase";
      check_row((*rows)[i]);
    }
  }
  dataset::ReadOptions strict;
  strict.repeated_stamps = dataset::RepeatedStamps::kReject;
  MAV_CHECK(parse(text, kName, strict).ok() == (rows.ok() && warnings.empty()));
}

}  // namespace mav::fuzz
