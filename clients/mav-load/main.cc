// mav-load: a load generator for the stack's services (docs/services.md, "mav-load").
//
//   mav-load planning      [common flags] (--queries FILE | --map FILE.bt) [--require-success]
//   mav-load localization  [common flags] [--method M] [--frames N] [--euroc DIR] [--queue Q]
//   mav-load mapping       [common flags] [--build-room K] [--boxes N] [--half-extent M]
//   mav-load control       [common flags]
//
// common flags: [--address HOST:PORT | ipv4:H:P,H:P,... | H:P,H:P,... | dns:///HOST:PORT]
//   --concurrency C --duration S [--client sync|async] [--deadline-ms D] [--fail-on-errors]
//   [--max-p99-ms X] [--backoff-max-ms B] [--fail-fast] [--json FILE] [--cpu-pid PID[,PID...]]
//
// Every command: C calls in flight on one shared channel (C threads each a synchronous client,
// or with --client async gRPC's callback API), the command's RPC back to back for S seconds with
// a deadline of D ms per call (load.h); a target naming several backends is balanced call by call
// (round_robin; every channel retries UNAVAILABLE calls and reconnects within 0.5 s: channel.h)
// and the calls are counted per backend. A call made while the server is down waits for it until
// its deadline (wait_for_ready; --fail-fast: fails at once). Every second a line (answered and
// failed calls in that second, p50/p99 so far); at the end the rate, the latency p50/p95/p99/max
// (nearest rank, mav::SummarizeRuntimes: client-side wall time of each timed reply), the replies by
// what they said, the errors by gRPC code, the calls per backend, the server's CPU time and
// VmHWM/VmRSS
// (--cpu-pid). After the n-th failed call in a row (e.g. RESOURCE_EXHAUSTED) the next waits a
// random pause up to min(B, 10 ms x 2^(n-1)) (exponential backoff with full jitter; B = 1000 ms
// by default, 0: a fixed 1 ms; --backoff-base-ms changes the 10 ms).
// What each command calls, and how it prepares the server: the comment at the top of
// planning.cc, localization.cc, mapping.cc, control.cc.
// Exit status: 0; 1 when asked to fail (--fail-on-errors: any RPC error; --max-p99-ms: p99 above
// it; the command's own, e.g. planning --require-success), no call completed, or the server cannot
// be reached ("cannot connect to <address>") or set up; 2 usage error (the message names the flag).

#include <iostream>
#include <string>
#include <vector>

#include "clients/mav-load/commands.h"
#include "clients/mav-load/load.h"

namespace {

constexpr char kUsage[] =
    "Usage: mav-load planning|localization|mapping|control [--address HOST:PORT|TARGET]\n"
    "                --concurrency C --duration S [--deadline-ms D] [--fail-on-errors]\n"
    "                [--max-p99-ms X] [--backoff-max-ms B] [--fail-fast] [--client sync|async]\n"
    "                [--json FILE] [--cpu-pid PID[,PID...]] [command flags]\n"
    "       mav-load COMMAND --help   (the command's flags)\n";

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> words(argv + 1, argv + argc);
  const std::string command = words.empty() ? "" : words.front();
  const std::vector<std::string> rest(words.begin() + (words.empty() ? 0 : 1), words.end());
  if (command == "planning") return mav::load::RunPlanning(rest);
  if (command == "localization") return mav::load::RunLocalization(rest);
  if (command == "mapping") return mav::load::RunMapping(rest);
  if (command == "control") return mav::load::RunControl(rest);
  if (command == "--help" || command == "-h") {
    std::cout << kUsage;
    return 0;
  }
  std::cerr << kUsage;
  return command.empty() ? 2
                         : mav::load::Usage("unknown command '" + command +
                                            "' (known: planning, localization, mapping, control)");
}
