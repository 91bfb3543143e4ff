#!/usr/bin/env python3
"""The load tests' tables (deploy/stack-test.sh, stage 7), from mav-load's --json files.

  deploy/load-table.py DIR            markdown tables of DIR/<mode>-<service>-c<C>[-backoff|-async].json
  deploy/load-table.py --replicas SPREAD.json KILL.json
                                      one line on the round_robin spread and the killed replica;
                                      exit 1 when a replica's share is off a third by more than
                                      10 % or the kill lost more calls than were in flight

Targets (issue 24, "load tests at two cores") and the memory caps of docker-compose.yml are
checked here; every verdict is printed, met or not.
"""
import json
import os
import re
import sys

# service: (call, calls/s at least, p99 at most in ms, memory cap in MiB from docker-compose.yml)
TARGETS = {
    "planning": ("PlanPath, power_plant.bt, 33 t4_3-like queries", 400, 50, 3072),
    "localization": ("ProcessStereoPair 752 x 480, sparse", 60, 50, 1024),
    "mapping": ("QueryCollision, 12-keyframe room map", 20000, 5, 3072),
    "control": ("GetState", 20000, 5, 1024),
}
SWEEP = [1, 2, 4, 8]
OVERLOAD = 32
SHED_CODES = {"RESOURCE_EXHAUSTED", "DEADLINE_EXCEEDED"}


RUN_NAME = re.compile(r"^(container|bare)-([a-z]+)-c([0-9]+)(-backoff|-async)?\.json$")


def load(directory):
    """{(mode, service, clients): run}, {(mode, service): the overload run with backoff} and
    {(mode, service, clients): run with mav-load's asynchronous client}."""
    runs, backoff, async_runs = {}, {}, {}
    for name in os.listdir(directory):
        m = RUN_NAME.match(name)
        if not m:
            continue
        with open(os.path.join(directory, name)) as f:
            run = json.load(f)
        if m.group(4) == "-backoff":
            backoff[(m.group(1), m.group(2))] = run
        elif m.group(4) == "-async":
            async_runs[(m.group(1), m.group(2), int(m.group(3)))] = run
        else:
            runs[(m.group(1), m.group(2), int(m.group(3)))] = run
    return runs, backoff, async_runs


def cpu_and_memory(run):
    server = (run.get("servers") or [{}])[0]
    cpu = server.get("cpu_s")
    cpu_text = "-" if cpu is None else "%.0f %%" % (100.0 * cpu / run["duration_s"])
    hwm = server.get("vm_hwm_kb")
    return cpu_text, (None if hwm is None else hwm / 1024.0)


def row(service, mode, c, run):
    lat = run["latency_ms"]
    cpu, hwm = cpu_and_memory(run)
    errors = ", ".join("%s %d" % kv for kv in sorted(run["errors"].items())) or "0"
    return "| %s | %s | %d | %.0f | %.2f | %.2f | %s | %s | %s |" % (
        service, mode, c, run["answered_per_s"], lat["p50"], lat["p99"], errors, cpu,
        "-" if hwm is None else "%.0f MiB" % hwm)


def best(runs, mode, service):
    """The sweep's run with the most answered calls per second and no error."""
    candidates = [(runs[(mode, service, c)]["answered_per_s"], c) for c in SWEEP
                  if (mode, service, c) in runs and runs[(mode, service, c)]["error_count"] == 0]
    return max(candidates)[1] if candidates else None


def async_table(async_runs):
    """The runs with mav-load --client async (no client thread per call): what the service
    answers when the client on the same cores costs less."""
    if not async_runs:
        return []
    out = ["", "The same calls from mav-load's asynchronous client (`--client async`: gRPC's "
           "callback API, no client thread per call):", "",
           "| service | mode | calls in flight | answered/s | p50 ms | p99 ms | errors | server CPU | peak RSS "
           "| server CPU per call | target |", "|---|---|---:|---:|---:|---:|---|---:|---:|---:|---|"]
    for (mode, service, c), run in sorted(async_runs.items(), key=lambda kv: (
            list(TARGETS).index(kv[0][1]), kv[0][0] != "container", kv[0][2])):
        _, rate, p99, _ = TARGETS[service]
        server = (run.get("servers") or [{}])[0]
        per_call = "-" if server.get("cpu_s") is None else "%.1f us" % (
            1e6 * server["cpu_s"] / max(1, run["calls"]))
        met = (run["answered_per_s"] >= rate and run["latency_ms"]["p99"] <= p99 and
               run["error_count"] == 0)
        out.append(row(service, mode, c, run) + " %s | %s |" % (per_call, "met" if met else "NOT met"))
    return out


def tables(runs, backoff, async_runs):
    out = ["| service | mode | clients | answered/s | p50 ms | p99 ms | errors | server CPU | peak RSS |",
           "|---|---|---:|---:|---:|---:|---|---:|---:|"]
    for service in TARGETS:
        for mode in ("container", "bare"):
            for c in SWEEP + [OVERLOAD]:
                if (mode, service, c) in runs:
                    out.append(row(service, mode, c, runs[(mode, service, c)]))
    out += ["", "| service call | target | container: best run | bare: best run | container / bare | "
            "verdict |", "|---|---|---|---|---:|---|"]
    for service, (call, rate, p99, _) in TARGETS.items():
        cells, rates, met = [], {}, []
        for mode in ("container", "bare"):
            c = best(runs, mode, service)
            if c is None:
                cells.append("no error-free run")
                continue
            r = runs[(mode, service, c)]
            rates[mode] = r["answered_per_s"]
            cells.append("%.0f/s, p99 %.2f ms (C=%d)" % (r["answered_per_s"], r["latency_ms"]["p99"], c))
            ok = any(runs[(mode, service, k)]["answered_per_s"] >= rate and
                     runs[(mode, service, k)]["latency_ms"]["p99"] <= p99 and
                     runs[(mode, service, k)]["error_count"] == 0
                     for k in SWEEP if (mode, service, k) in runs)
            met.append("%s %s" % (mode, "met" if ok else "NOT met"))
        ratio = "%.2f" % (rates["container"] / rates["bare"]) if len(rates) == 2 else "-"
        out.append("| %s | >= %d/s, p99 <= %g ms | %s | %s | %s | %s |" % (
            call, rate, p99, cells[0] if cells else "-", cells[1] if len(cells) > 1 else "-",
            ratio, "; ".join(met)))
    out += ["", "Overload: %d clients (4 x the sweep's top), against the sweep's best run; a refused "
            "client pauses 1 ms, or backs off (mav-load's default: full jitter, 10 ms doubling up "
            "to 1 s):" % OVERLOAD, "",
            "| service | mode | client | admitted/s | admitted p99 / best p99 | refused (codes) | "
            "refusal p99 | peak RSS / cap | verdict |", "|---|---|---|---:|---:|---|---:|---:|---|"]
    for service, (_, _, _, cap) in TARGETS.items():
        for mode, client in (("container", "1 ms"), ("container", "backoff"), ("bare", "1 ms"),
                             ("bare", "backoff")):
            c = best(runs, mode, service)
            o = runs.get((mode, service, OVERLOAD)) if client == "1 ms" else backoff.get((mode, service))
            if c is None or o is None:
                continue
            b = runs[(mode, service, c)]
            ratio = o["latency_ms"]["p99"] / max(b["latency_ms"]["p99"], 1e-9)
            codes = set(o["errors"])
            _, hwm = cpu_and_memory(o)
            verdict = []
            verdict.append("p99 within 2x" if ratio <= 2 else "p99 %.1fx" % ratio)
            if codes - SHED_CODES:
                verdict.append("other errors: %s" % ", ".join(sorted(codes - SHED_CODES)))
            if hwm is not None:
                verdict.append("memory under cap" if hwm <= cap else "memory OVER cap")
            refused = ", ".join("%s %d" % kv for kv in sorted(o["errors"].items())) or "none"
            out.append("| %s | %s | %s | %.0f | %.2f / %.2f ms = %.1fx | %s | %s | %s | %s |" % (
                service, mode, client, o["answered_per_s"], o["latency_ms"]["p99"], b["latency_ms"]["p99"],
                ratio, refused, "-" if not o["error_count"] else "%.2f ms" % o["error_latency_ms"]["p99"],
                "-" if hwm is None else "%.0f / %d MiB" % (hwm, cap), "; ".join(verdict)))
    return "\n".join(out + async_table(async_runs))


def replicas(spread_path, kill_path):
    with open(spread_path) as f:
        spread = json.load(f)
    with open(kill_path) as f:
        kill = json.load(f)
    calls = max(1, spread["calls"])
    shares = {peer: n / calls for peer, n in spread["per_backend"].items()}
    even = len(shares) == 3 and all(abs(s - 1 / 3) <= 0.1 / 3 for s in shares.values())
    lost = kill["error_count"]
    in_flight = kill["concurrency"]
    line = ("round_robin over %d replicas: %s of %d calls (%.0f/s, p99 %.1f ms); one killed "
            "mid-run: %d of %d calls failed%s (at most %d were in flight)" % (
                len(shares), " / ".join("%.1f %%" % (100 * s) for s in sorted(shares.values())),
                spread["calls"], spread["answered_per_s"], spread["latency_ms"]["p99"], lost,
                kill["calls"], (" (%s)" % ", ".join("%s %d" % kv for kv in kill["errors"].items()))
                if lost else "", in_flight))
    print(line)
    return 0 if even and lost <= in_flight else 1


def main(argv):
    if len(argv) == 4 and argv[1] == "--replicas":
        return replicas(argv[2], argv[3])
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    runs, backoff, async_runs = load(argv[1])
    if not runs:
        print("load-table.py: no mav-load JSON in %s" % argv[1], file=sys.stderr)
        return 1
    print(tables(runs, backoff, async_runs))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
