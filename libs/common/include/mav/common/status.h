#pragma once
// Status and Result<T>: expected failures as values (a bad file, an unknown preset, a lost track).
//
// A Status carries a code and a human message that names the offending file, line or field, e.g.
// "mav0/imu0/data.csv:17: expected 7 columns, got 5". Library APIs never throw across their
// boundary; the services translate Status codes to their RPC status codes one to one
// (see docs/contracts.md).

#include <optional>
#include <string>
#include <utility>
#include <variant>

#include "mav/common/check.h"

namespace mav {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,     // the caller passed something malformed (field named in the message)
  kNotFound,            // a file, directory, preset or id does not exist
  kFailedPrecondition,  // the call is valid but not in the current state
  kOutOfRange,          // a time or index outside the valid span
  kDataLoss,            // a file exists but is corrupt or truncated
  kIoError,             // reading or writing failed at the OS level
  kUnavailable,         // a resource or peer is temporarily unavailable (retry later)
  kInternal,            // an invariant failed that we could not prove at compile time
  kResourceExhausted,   // a configured limit (queue, memory, samples) would be exceeded
  kDeadlineExceeded,    // the caller's deadline passed before the work completed
  kCancelled,           // the caller (or a shutdown) cancelled the work
};

const char* StatusCodeName(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return {}; }
  static Status InvalidArgument(std::string m) {
    return {StatusCode::kInvalidArgument, std::move(m)};
  }
  static Status NotFound(std::string m) { return {StatusCode::kNotFound, std::move(m)}; }
  static Status FailedPrecondition(std::string m) {
    return {StatusCode::kFailedPrecondition, std::move(m)};
  }
  static Status OutOfRange(std::string m) { return {StatusCode::kOutOfRange, std::move(m)}; }
  static Status DataLoss(std::string m) { return {StatusCode::kDataLoss, std::move(m)}; }
  static Status IoError(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
  static Status Unavailable(std::string m) { return {StatusCode::kUnavailable, std::move(m)}; }
  static Status Internal(std::string m) { return {StatusCode::kInternal, std::move(m)}; }
  static Status ResourceExhausted(std::string m) {
    return {StatusCode::kResourceExhausted, std::move(m)};
  }
  static Status DeadlineExceeded(std::string m) {
    return {StatusCode::kDeadlineExceeded, std::move(m)};
  }
  static Status Cancelled(std::string m) { return {StatusCode::kCancelled, std::move(m)}; }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "INVALID_ARGUMENT: preset: unknown preset 'rom-easy' (known: room-easy, ...)"
  std::string ToString() const;

  // Returns a copy whose message is prefixed with `context` + ": ".
  Status WithContext(const std::string& context) const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

// Holds either a value or a non-OK Status.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : data_(std::move(value)) {}        // NOLINT(google-explicit-constructor)
  Result(Status status) : data_(std::move(status)) {  // NOLINT(google-explicit-constructor)
    MAV_CHECK(!std::get<Status>(data_).ok()) << "Result constructed from an OK status";
  }

  bool ok() const { return std::holds_alternative<T>(data_); }
  const Status& status() const {
    static const Status kOkStatus;
    return ok() ? kOkStatus : std::get<Status>(data_);
  }

  T& value() & {
    CheckOk();
    return std::get<T>(data_);
  }
  const T& value() const& {
    CheckOk();
    return std::get<T>(data_);
  }
  T&& value() && {
    CheckOk();
    return std::get<T>(std::move(data_));
  }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T&& operator*() && { return std::move(*this).value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }

 private:
  void CheckOk() const {
    MAV_CHECK(ok()) << "value() on a failed Result: " << std::get<Status>(data_).ToString();
  }
  std::variant<T, Status> data_;
};

}  // namespace mav

#define MAV_STATUS_CONCAT_INNER(a, b) a##b
#define MAV_STATUS_CONCAT(a, b) MAV_STATUS_CONCAT_INNER(a, b)

// Returns the Status from the enclosing function if `expr` (a Status) is not OK.
#define MAV_RETURN_IF_ERROR(expr)              \
  do {                                         \
    ::mav::Status mav_status_ = (expr);        \
    if (!mav_status_.ok()) return mav_status_; \
  } while (false)

// `MAV_ASSIGN_OR_RETURN(auto x, ReadThing())`: unwraps a Result or returns its Status.
#define MAV_ASSIGN_OR_RETURN(lhs, expr) \
  MAV_ASSIGN_OR_RETURN_IMPL(MAV_STATUS_CONCAT(mav_result_, __LINE__), lhs, expr)
#define MAV_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                              \
  if (!tmp.ok()) return tmp.status();             \
  lhs = std::move(tmp).value()
