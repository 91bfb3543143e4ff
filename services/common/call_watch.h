#pragma once
// The one cancellation path of every long RPC: a CallWatch turns a call's deadline and its
// cancellation (the client cancelled, its connection dropped, or the server's shutdown grace
// period ended) into one Termination the libraries poll. A synchronous gRPC handler cannot be
// told that its client went away, only ask (ServerContext::IsCancelled), so one task per
// process, on a work queue of its own, asks for every watched call every kPollMs and raises the
// call's CancelFlag; a call costs no thread of its own.
//
//   grpc::Status Service::BuildMap(grpc::ServerContext* context, ...) {
//     const CallWatch call(context);
//     Result<Map> map = builder_->Build(request, call.termination());  // DEADLINE_EXCEEDED or
//     ...                                                            // CANCELLED when it stops
//
// The watch must not outlive the handler (the context dies with the call); the Termination may:
// work that runs on after the handler returned sees a flag that no one raises any more, and its
// deadline.

#include <cstdint>

#include "mav/common/termination.h"

namespace grpc {
class ServerContext;
}  // namespace grpc

namespace mav::service_common {

class CallWatch {
 public:
  // How often the watcher asks every watched call whether its client is still there.
  static constexpr int64_t kPollMs = 10;

  explicit CallWatch(grpc::ServerContext* context);
  ~CallWatch();
  CallWatch(const CallWatch&) = delete;
  CallWatch& operator=(const CallWatch&) = delete;

  // Stops at the client's deadline (none: never) or once the client is gone.
  const Termination& termination() const { return termination_; }
  // The call's own flag, raised when the client is gone.
  const CancelFlag& cancel_flag() const { return cancel_; }

  // How many calls are being watched (for tests and the status replies).
  static int Watched();

 private:
  friend class CallWatcher;
  grpc::ServerContext* context_;
  CancelFlag cancel_;
  Termination termination_;
};

// The client's deadline alone, as a Termination (Never when it set none). For short calls that
// only need the deadline; long calls take a CallWatch.
Termination DeadlineOf(const grpc::ServerContext& context);

}  // namespace mav::service_common
