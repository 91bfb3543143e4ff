#pragma once
// Assertions on gRPC statuses shared by the contract tests: INVALID_ARGUMENT messages start with
// the field path as the request spells it (docs/contracts.md, "Errors").

#include <string>

#include <grpcpp/support/status.h>
#include <gtest/gtest.h>

namespace mav::test_support {

inline bool StartsWith(const std::string& text, const std::string& prefix) {
  return text.rfind(prefix, 0) == 0;
}

// INVALID_ARGUMENT whose message starts with `field`.
inline void ExpectInvalidArgument(const grpc::Status& status, const std::string& field) {
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_TRUE(StartsWith(status.error_message(), field))
      << "'" << status.error_message() << "' should start with '" << field << "'";
}

}  // namespace mav::test_support
