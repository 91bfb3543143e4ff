# Sourced by the measurement scripts that run the data plane in shared memory (--dds-shm):
#
#   start_roudi_unless_running PROGRAM LOG
#
# Uses the RouDi that answers at /tmp/roudi if there is one (roudi_pid empty); otherwise starts
# iox-roudi with deploy/roudi.toml (output in LOG), waits until it answers and sets roudi_pid for
# the caller to stop at the end. Exits 1 naming PROGRAM when iox-roudi is missing or does not
# come up.
roudi_answers() {
  python3 -c 'import socket; socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM).connect("/tmp/roudi")' \
    2> /dev/null
}

start_roudi_unless_running() {  # $1: program name for errors, $2: log file
  roudi_pid=""
  roudi_answers && return 0
  command -v iox-roudi > /dev/null || { echo "$1: iox-roudi not found (Debian's iceoryx)" >&2; exit 1; }
  iox-roudi -c "$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/deploy/roudi.toml" > "$2" 2>&1 &
  roudi_pid=$!
  for _ in $(seq 50); do roudi_answers && return 0; sleep 0.1; done
  echo "$1: iox-roudi did not come up (log: $2)" >&2
  exit 1
}
