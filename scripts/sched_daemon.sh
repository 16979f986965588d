#!/usr/bin/env bash
# Per-thread CPU of ptdad at real-time pace (docs/benchmarks.md section 7, the schedstat method): starts
# PTDAD with CONFIG (e.g. the ptdad.toml that scripts/bench_daemon.sh writes into its out_dir/ptdad-rt),
# waits WARM seconds, then sums the run time and run count of /proc/<pid>/task/*/schedstat per thread
# name over SPAN seconds and prints ms of CPU per second of wall time (= per second of signal at
# real-time pace), runs per second and µs per run, and the load average at both ends.
# Usage: scripts/sched_daemon.sh PTDAD CONFIG [WARM=15] [SPAN=20]
set -euo pipefail
ptdad=$1
cfg=$2
warm=${3:-15}
span=${4:-20}
log=$(mktemp)
trap 'rm -f "$log"' EXIT
(exec "$ptdad" --config "$cfg" --config-dir '' --foreground >"$log" 2>&1) &
pid=$!
sleep "$warm"
snap() {
  for t in /proc/"$pid"/task/*; do
    printf '%s %s\n' "$(tr ' ' _ <"$t/comm")" "$(cut -d' ' -f1,3 "$t/schedstat")"
  done | sort
}
a=$(snap)
l1=$(cut -d' ' -f1 /proc/loadavg)
sleep "$span"
b=$(snap)
l2=$(cut -d' ' -f1 /proc/loadavg)
kill -TERM "$pid"
wait "$pid" || true
join <(echo "$a") <(echo "$b") | awk -v s="$span" -v l1="$l1" -v l2="$l2" '
  { ms = ($4 - $2) / 1e6 / s; r = ($5 - $3) / s; tot += ms
    printf "%-12s %6.3f ms/s %6.1f runs/s %7.1f us/run\n", $1, ms, r, (r > 0 ? ms * 1e3 / r : 0) }
  END { printf "total        %6.3f ms/s   load %s .. %s\n", tot, l1, l2 }'
