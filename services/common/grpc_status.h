#pragma once
// The one mapping between the library's Status codes and gRPC status codes, and the deadline of
// a call as a library Termination. Every service handler returns ToGrpcStatus(status); nothing
// builds a grpc::Status by hand (docs/contracts.md, "Errors").
//
//   kInvalidArgument    -> INVALID_ARGUMENT     kResourceExhausted -> RESOURCE_EXHAUSTED
//   kNotFound           -> NOT_FOUND            kDeadlineExceeded  -> DEADLINE_EXCEEDED
//   kFailedPrecondition -> FAILED_PRECONDITION  kCancelled         -> CANCELLED
//   kOutOfRange         -> OUT_OF_RANGE         kUnavailable       -> UNAVAILABLE
//   kDataLoss           -> DATA_LOSS            kIoError, kInternal -> INTERNAL
// FromGrpcStatus is the inverse (INTERNAL -> kInternal; codes without a library twin, e.g.
// UNKNOWN, ABORTED, UNAUTHENTICATED, also -> kInternal with the code's name in the message).
// Messages longer than kMaxMessageBytes are cut (gRPC refuses metadata above ~8 KB and would turn
// an INVALID_ARGUMENT into a RESOURCE_EXHAUSTED).

#include <cstddef>
#include <string>
#include <string_view>

#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>

#include "mav/common/status.h"
#include "mav/common/termination.h"

namespace mav::service_common {

inline constexpr size_t kMaxMessageBytes = 2048;

grpc::Status ToGrpcStatus(const Status& status);
Status FromGrpcStatus(const grpc::Status& status);

// "UNAVAILABLE", "DEADLINE_EXCEEDED", ... (gRPC's own names).
const char* GrpcCodeName(grpc::StatusCode code);
// The Status of a failed outgoing call, never with an empty reason:
//   "<what>: UNIMPLEMENTED: <message>" or, when the peer gave no message,
//   "<what>: UNIMPLEMENTED (no reason given: is <expected> serving at that address?)".
// The code maps as FromGrpcStatus, except that UNIMPLEMENTED (the peer is another service) and
// UNKNOWN become kUnavailable: for the caller the dependency is not there.
Status OutgoingCallStatus(const grpc::Status& status, const std::string& what,
                          const std::string& expected);

// OK, or DEADLINE_EXCEEDED "<what>: the client's deadline passed before the call was handled":
// every handler that changes state checks it first, so a late retry changes nothing.
Status CheckDeadline(const grpc::ServerContext& context, std::string_view what);

}  // namespace mav::service_common
