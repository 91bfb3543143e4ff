#pragma once
// What every fuzz target asserts besides "no crash, no sanitizer report": an error is a
// readable value (InvalidArgument/DataLoss naming the input, a bounded message whatever the
// input's size: issue 8 defect 4), never an exception or an abort. MAV_CHECK failures abort,
// which libFuzzer reports as a crash with the input that caused it.

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "mav/common/check.h"
#include "mav/common/status.h"

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

}  // namespace mav::fuzz
