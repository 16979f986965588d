#!/usr/bin/env bash
# The daemon at real-time pace (issue 13 item 3; docs/benchmarks.md, "A daemon that sleeps"): CPU time per
# second of signal and the latency from the end of a window to its verdict, for one channel at 25.6 kHz.
#
# 1. `ptdad` (the real binary) replays the arc-welding job's faulty recording (WAV + candump replay,
#    pace "realtime", the production 1 s status period, [alarm.can] frames every 0.1 s) from start to
#    end (--exit-at-end; 63 s of signal). Its CPU time is user + system from getrusage(RUSAGE_CHILDREN)
#    after it exited (GNU time's %U + %S), start-up included, divided by the seconds of signal; and the
#    steady state ("steady"): the CPU time of all its threads (schedstat) from 10 s after its start to
#    5 s before the replay's end, per second of wall time (= of signal). Status files go to a tmpfs as
#    in production (/run/ptda).
# 2. daemon_bench's in-process real-time run (BM_DaemonLatency/job:0/realtime:1) on the same recording
#    and configuration, WINDOWS windows: "after_last_sample" = the window's hand-off to the alarm
#    manager - the acquisition time of the window's last sample (p50/p99/max), and the process CPU time
#    per second of signal over activate()..run().
# Both runs are repeated RUNS times (default 1); every figure is printed per run.
#
# Usage: scripts/bench_daemon.sh [build_dir] [out_dir]
#   build_dir  default build/release (needs daemon/ptdad and daemon/bench/daemon_bench; daemon_bench
#              simulates and trains the recording on its first run into $PTDA_BENCH_DIR, default
#              <build_dir>/bench-data)
#   out_dir    default out/bench-daemon: results.tsv, the logs
# Environment: PTDA_BENCH_RT_WINDOWS (default 100, about 62 s), RUNS (default 1), PTDAD and DAEMON_BENCH
# (other binaries, e.g. copies of an older build to compare), CAN_TIMER ("auto", the default: the
# kernel re-sends the verdict frame, emulated by the replay; "daemon": the daemon sends every frame) for
# the ptdad runs (daemon_bench keeps the default).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$(realpath "${1:-$root/build/release}")
out=$(realpath -m "${2:-$root/out/bench-daemon}")
runs=${RUNS:-1}
windows=${PTDA_BENCH_RT_WINDOWS:-100}
ptdad=${PTDAD:-$build/daemon/ptdad}
bench=${DAEMON_BENCH:-$build/daemon/bench/daemon_bench}
data=$(realpath -m "${PTDA_BENCH_DIR:-$build/bench-data}")
for f in "$ptdad" "$bench"; do
  [[ -x $f ]] || { echo "bench_daemon.sh: $f not built (cmake --build $build --target ptdad daemon_bench)" >&2; exit 2; }
done
mkdir -p "$out"
export PTDA_BENCH_DIR=$data
# status.json goes to a tmpfs, as in production (status_dir defaults to /run/ptda, systemd's
# RuntimeDirectory): replacing it on this VM's ext4 costs about twice as much (docs/benchmarks.md,
# session 16). PTDA_BENCH_STATUS_ROOT overrides; a root that is not a tmpfs is used as given, and said.
status_root=${PTDA_BENCH_STATUS_ROOT:-/dev/shm}
[[ -d $status_root ]] || status_root=$out
# One fixed directory per user (a few KB), kept: scripts/sched_daemon.sh reuses the configuration.
status_root=$status_root/ptda-bench-status-$(id -u)
mkdir -p "$status_root"
status_fs=$(stat -f -c %T "$status_root")
export PTDA_BENCH_STATUS_ROOT=$status_root

# daemon_bench prepares (simulates, trains) the job on its first run; a fast replay does it cheaply.
"$bench" --benchmark_filter='BM_DaemonLatency/job:0/realtime:0' >"$out/prepare.log" 2>&1

job=arc_welding
rec=$data/$job/faulty
cfg_dir=$out/ptdad-rt
mkdir -p "$cfg_dir"
# The same configuration as daemon_bench's real-time run (write_replay_config), written here.
{
  printf '[daemon]\nbaseline = "%s"\nstatus_dir = "%s"\nlog_level = "warn"\nstatus_period_s = 1.0\n\n' \
    "$data/$job/baseline.bin" "$status_root/ptdad-rt/status"
  printf '[adc]\nbackend = "wav"\nrecording = "%s"\npace = "realtime"\nblock_len = 256\n\n' "$rec"
  printf '[can]\nbackend = "candump"\npace = "realtime"\nspeed_latency_s = 0.0\n\n'
  printf '[alarm]\nmin_hold_s = 0.0\nlatch = false\n\n[alarm.can]\nenabled = true\nperiod_s = 0.1\ntimer = "%s"\n\n' \
    "${CAN_TIMER:-auto}"
  printf '[monitor]\nmethod = "ptda"\n\n'
  awk '/^\[/{skip = ($0 == "[can]" || $0 == "[monitor]")} !skip' "$root/config/examples/$job.toml"
} >"$cfg_dir/ptdad.toml"
signal_s=$(/usr/bin/python3 - "$rec" <<'EOF'
import struct, sys, pathlib, tomllib
rec = pathlib.Path(sys.argv[1])
meta = tomllib.loads((rec / "recording.toml").read_text())
name = meta.get("vibration_file") or meta.get("vibration", {}).get("file")
data = (rec / name).read_bytes()
# RIFF/WAVE: walk the chunks for fmt and data.
pos, fs, block, frames = 12, 0, 0, 0
while pos + 8 <= len(data):
    cid, size = data[pos:pos + 4], struct.unpack("<I", data[pos + 4:pos + 8])[0]
    if cid == b"fmt ":
        ch, fs, _, block = struct.unpack("<HIIH", data[pos + 10:pos + 22])
    elif cid == b"data":
        frames = size // block
    pos += 8 + size + (size & 1)
print(f"{frames / fs:.3f}")
EOF
)

# The CPU time of all of a process's threads so far, in ns (schedstat: exact, unlike the 10 ms ticks of
# /proc/<pid>/stat).
task_cpu_ns() {
  local sum=0 t v
  for t in /proc/"$1"/task/*/schedstat; do
    read -r v _ <"$t" 2>/dev/null || continue
    sum=$((sum + v))
  done
  echo "$sum"
}

printf 'run\tptdad_cpu_ms_per_s\tsteady_cpu_ms_per_s\tptdad_peak_rss_mib\tinproc_cpu_ms_per_s\tafter_last_p50_ms\tafter_last_p99_ms\tafter_last_max_ms\twindows\n' \
  >"$out/results.tsv"
for ((r = 1; r <= runs; ++r)); do
  /usr/bin/time -f '%U %S %M' -o "$out/time.txt" \
    "$ptdad" --config "$cfg_dir/ptdad.toml" --config-dir '' --exit-at-end --foreground >"$out/ptdad.log" 2>&1 &
  time_pid=$!
  # The steady state: all threads' CPU time from 10 s after the start to 5 s before the replay's end
  # (start-up, about 15 ms of CPU, and the end are left out).
  sleep 0.5
  pid=$(pgrep -P "$time_pid" -x ptdad || true)
  steady=nan
  if [[ -n $pid ]]; then
    sleep 9.5
    c1=$(task_cpu_ns "$pid")
    t1=$(date +%s%N)
    span=$(/usr/bin/python3 -c "print(max(0.0, $signal_s - 15.0))")
    sleep "$span"
    c2=$(task_cpu_ns "$pid")
    t2=$(date +%s%N)
    steady=$(/usr/bin/python3 -c "print(f'{($c2 - $c1) / ($t2 - $t1) * 1e3:.2f}')")
  fi
  wait "$time_pid"
  read -r user sys rss_kib <"$out/time.txt"
  PTDA_BENCH_RT_WINDOWS=$windows "$bench" --benchmark_filter='BM_DaemonLatency/job:0/realtime:1' \
    --benchmark_out="$out/latency.json" --benchmark_out_format=json >"$out/latency.log" 2>&1
  /usr/bin/python3 - "$out/latency.json" "$user" "$sys" "$rss_kib" "$signal_s" "$r" "$steady" >>"$out/results.tsv" <<'EOF'
import json, sys
b = json.load(open(sys.argv[1]))["benchmarks"][0]
user, sys_s, rss_kib, signal_s, run = map(float, sys.argv[2:7])
print(f"{int(run)}\t{(user + sys_s) / signal_s * 1e3:.2f}\t{sys.argv[7]}\t{rss_kib / 1024:.1f}\t"
      f"{b['cpu_s_per_signal_s'] * 1e3:.2f}\t{b['after_last_sample_p50_us'] / 1e3:.1f}\t"
      f"{b['after_last_sample_p99_us'] / 1e3:.1f}\t{b['after_last_sample_max_us'] / 1e3:.1f}\t{int(b['windows'])}")
EOF
done
echo "signal: $signal_s s per ptdad run; $windows windows per in-process run; status files on $status_fs; $(nproc) CPUs, load $(cut -d' ' -f1-3 /proc/loadavg)"
column -t "$out/results.tsv"
