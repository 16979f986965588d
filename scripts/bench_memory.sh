#!/usr/bin/env bash
# Peak RSS against recording length (issue 13 item 4; docs/benchmarks.md, "Memory at any length"):
# a long recording is made by repeating the arc-welding job's faulty recording (63.4 s; daemon_bench's
# cached one, see scripts/bench_daemon.sh) back to back, WAV samples and CAN frames shifted by the
# recording's duration, then
#   replay   ptdad --exit-at-end on it (WAV + candump replay, pace "fast"),
#   monitor  ptda monitor on it,
#   fieldtrain  ptdad --train --exit-at-end on it (field training from the same replay),
#   train    ptda train on it,
#   simulate ptda simulate of the same job (config/scenarios/arc_welding_faulty.toml, seed 3003) with
#            its cycle count scaled to HOURS (written to out_dir, deleted at the end),
# each under GNU time: %M is the peak RSS (ru_maxrss of the child) in KiB; spill_peak_mib is the
# largest total size of the command's unlinked spill files seen (polled every 0.2 s; ptda train's lists
# beyond 256 KiB, ptdad --train's windows).
#
# Usage: scripts/bench_memory.sh HOURS [build_dir] [out_dir]
#   HOURS      length of the long recording (fractions allowed; 1 h = 278 MB of WAV + 44 MB of log; at
#              most 12.9 h: a WAV holds at most 4 GiB)
#   build_dir  default build/release (daemon/ptdad, cli/ptda, and the recording in bench-data/)
#   out_dir    default out/bench-memory: the recording (deleted at the end), results.tsv, logs
# Environment: PTDAD, PTDA (other binaries, e.g. copies of an older build), KEEP=1 keeps the recording,
#   SKIP="train" skips commands (space separated), TRAIN_COPIES=N gives `ptda train` the long recording N
#   times (N recordings, N x HOURS of signal: 24 h of training data are two 12 h recordings, as a WAV
#   holds at most 12.9 h). Without the cached recording (scripts/bench_daemon.sh)
#   it is prepared here as daemon_bench does: ptda simulate of the healthy (seed 1001) and faulty (seed
#   3003) scenarios, ptda train on the healthy one.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
hours=${1:?usage: bench_memory.sh HOURS [build_dir] [out_dir]}
build=$(realpath "${2:-$root/build/release}")
out=$(realpath -m "${3:-$root/out/bench-memory}")
ptdad=${PTDAD:-$build/daemon/ptdad}
ptda=${PTDA:-$build/cli/ptda}
data=$(realpath -m "${PTDA_BENCH_DIR:-$build/bench-data}")
src=$data/arc_welding/faulty
if [[ ! -f $src/recording.toml || ! -f $data/arc_welding/baseline.bin ]]; then
  echo "bench_memory.sh: preparing $data/arc_welding (as daemon_bench does)" >&2
  mkdir -p "$data/arc_welding"
  "$ptda" simulate --scenario "$root/config/scenarios/arc_welding_healthy.toml" --out "$data/arc_welding/train" \
    --seed 1001 >/dev/null
  "$ptda" simulate --scenario "$root/config/scenarios/arc_welding_faulty.toml" --out "$src" --seed 3003 >/dev/null
  "$ptda" train --recording "$data/arc_welding/train" --config "$root/config/examples/arc_welding.toml" \
    --out "$data/arc_welding/baseline.bin" >/dev/null
fi
rec=$out/long-${hours}h
mkdir -p "$out"
need_rec=0
for c in replay monitor fieldtrain train; do [[ " ${SKIP:-} " == *" $c "* ]] || need_rec=1; done
if [[ $need_rec == 1 && ! -f $rec/recording.toml ]]; then
  mkdir -p "$rec"
  /usr/bin/python3 - "$src" "$rec" "$hours" <<'EOF'
import pathlib, re, shutil, struct, sys
src, dst, hours = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]), float(sys.argv[3])
data = (src / "vibration.wav").read_bytes()
pos, fmt, body = 12, None, None
while pos + 8 <= len(data):
    cid, size = data[pos:pos + 4], struct.unpack("<I", data[pos + 4:pos + 8])[0]
    if cid == b"fmt ":
        fmt = data[pos:pos + 8 + size + (size & 1)]
    elif cid == b"data":
        body = data[pos + 8:pos + 8 + size]
    pos += 8 + size + (size & 1)
ch, fs, _, block = struct.unpack("<HIIH", fmt[10:22])
frames = len(body) // block
period_us = frames * 1_000_000 // fs  # whole microseconds (the log's resolution)
reps = max(1, round(hours * 3600 * fs / frames))
with open(dst / "vibration.wav", "wb") as f:
    f.write(b"RIFF" + struct.pack("<I", 4 + len(fmt) + 8 + len(body) * reps) + b"WAVE" + fmt)
    f.write(b"data" + struct.pack("<I", len(body) * reps))
    for _ in range(reps):
        f.write(body)
lines = (src / "can.log").read_text().splitlines()
stamp = re.compile(r"^\((\d+)\.(\d{6})\)(.*)$")
parsed = []
for l in lines:
    m = stamp.match(l)
    if m:
        parsed.append((int(m.group(1)) * 1_000_000 + int(m.group(2)), m.group(3)))
with open(dst / "can.log", "w") as f:
    for r in range(reps):
        off = r * period_us
        f.write("".join(f"({(t + off) // 1_000_000}.{(t + off) % 1_000_000:06d}){rest}\n" for t, rest in parsed))
shutil.copy(src / "recording.toml", dst / "recording.toml")
print(f"{reps} x {frames / fs:.3f} s = {reps * frames / fs / 3600:.3f} h", file=sys.stderr)
EOF
fi
signal_h=-
[[ $need_rec == 0 ]] || signal_h=$(/usr/bin/python3 - "$rec/vibration.wav" <<'PY'
import struct, sys
with open(sys.argv[1], "rb") as f:
    head = f.read(4096)
pos = 12
while pos + 8 <= len(head):
    cid, size = head[pos:pos + 4], struct.unpack("<I", head[pos + 4:pos + 8])[0]
    if cid == b"fmt ":
        _, fs, _, block = struct.unpack("<HIIH", head[pos + 10:pos + 22])
    elif cid == b"data":
        print(f"{size / block / fs / 3600:.3f}")
        break
    pos += 8 + size + (size & 1)
PY
)
cfg=$root/config/examples/arc_welding.toml
base=$data/arc_welding/baseline.bin
mkdir -p "$out/ptdad"
{
  printf '[daemon]\nbaseline = "%s"\nstatus_dir = "%s"\nlog_level = "warn"\nstatus_period_s = 0.05\n\n' "$base" "$out/ptdad/status"
  printf '[adc]\nbackend = "wav"\nrecording = "%s"\npace = "fast"\nblock_len = 256\n\n' "$rec"
  printf '[can]\nbackend = "candump"\npace = "fast"\nspeed_latency_s = 0.0\n\n'
  awk '/^\[/{skip = ($0 == "[can]")} !skip' "$cfg"
} >"$out/ptdad/ptdad.toml"

measure() {  # name, command...
  local name=$1
  shift
  if [[ " ${SKIP:-} " == *" $name "* ]]; then return; fi
  /usr/bin/time -f '%M %e %U %S' -o "$out/$name.time" "$@" >"$out/$name.log" 2>&1 &
  local tpid=$! spill=0 child now f l
  # Peak size of the child's unlinked (spill) files, polled from /proc every 0.2 s: O_TMPFILE and
  # unlinked files show as "... (deleted)" links; their bytes are on disk, not in the RSS.
  while kill -0 "$tpid" 2>/dev/null; do
    child=$(pgrep -P "$tpid" | head -n 1 || true)
    if [[ -n $child ]]; then
      now=0
      for f in /proc/"$child"/fd/*; do
        l=$(readlink "$f" 2>/dev/null || true)
        [[ $l == *"(deleted)"* ]] && now=$((now + $(stat -L -c %s "$f" 2>/dev/null || echo 0)))
      done
      ((now > spill)) && spill=$now
    fi
    sleep 0.2
  done
  wait "$tpid" || echo "$name exited $?" >&2
  read -r rss wall user sys <"$out/$name.time"
  printf '%s\t%s\t%.1f\t%.1f\t%.1f\t%.1f\n' "$name" "$signal_h" "$(echo "$rss / 1024" | bc -l)" "$wall" \
    "$(echo "$user + $sys" | bc -l)" "$(echo "$spill / 1048576" | bc -l)" >>"$out/results.tsv"
}
printf 'command\thours\tpeak_rss_mib\twall_s\tcpu_s\tspill_peak_mib\n' >"$out/results.tsv"
measure replay "$ptdad" --config "$out/ptdad/ptdad.toml" --config-dir '' --exit-at-end --foreground
measure monitor "$ptda" monitor --recording "$rec" --config "$cfg" --baseline "$base" --quiet
# fieldtrain: ptdad --train on the same replay; it collects every window (max_windows = FIELD_MAX_WINDOWS,
# default 8192: 1 h of this job cuts 5757), trains at the end of the replay and exits.
{
  sed -n '1,/^\[can\]/p' "$out/ptdad/ptdad.toml" | sed '$d'
  printf '[can]\nbackend = "candump"\npace = "fast"\nspeed_latency_s = 0.0\n\n'
  printf '[training]\ntarget_cycles = 100000\nmax_duration_s = 1e7\noutput = "%s"\nmax_windows = %s\nmax_regions = %s\n\n' \
    "$out/ptdad/field.bin" "${FIELD_MAX_WINDOWS:-8192}" "${FIELD_MAX_WINDOWS:-8192}"
  awk '/^\[/{skip = ($0 == "[can]")} !skip' "$cfg"
} >"$out/ptdad/fieldtrain.toml"
measure fieldtrain "$ptdad" --config "$out/ptdad/fieldtrain.toml" --config-dir '' --train --exit-at-end --foreground
train_args=()
for ((i = 0; i < ${TRAIN_COPIES:-1}; ++i)); do train_args+=(--recording "$rec"); done
signal_h_one=$signal_h
[[ $signal_h == - ]] || signal_h=$(echo "$signal_h * ${TRAIN_COPIES:-1}" | bc -l | sed 's/^\./0./')
measure train "$ptda" train "${train_args[@]}" --config "$cfg" --out "$out/train.bin"
signal_h=$signal_h_one
[[ ${KEEP:-0} == 1 ]] || rm -rf "$rec"

# simulate: the faulty scenario with as many job cycles as make HOURS (its 20 cycles = the 63.4 s
# recording). A WAV holds at most 4 GiB: 12.9 h of 24-bit samples at 25.6 kHz.
if [[ " ${SKIP:-} " != *" simulate "* ]]; then
  scen=$out/sim-${hours}h.toml
  /usr/bin/python3 - "$root/config/scenarios/arc_welding_faulty.toml" "$src" "$hours" "$scen" <<'PY'
import pathlib, re, struct, sys
text = pathlib.Path(sys.argv[1]).read_text()
data = (pathlib.Path(sys.argv[2]) / "vibration.wav").read_bytes()[:4096]
pos = 12
while pos + 8 <= len(data):
    cid, size = data[pos:pos + 4], struct.unpack("<I", data[pos + 4:pos + 8])[0]
    if cid == b"fmt ":
        _, fs, _, block = struct.unpack("<HIIH", data[pos + 10:pos + 22])
    elif cid == b"data":
        seconds = size / block / fs
        break
    pos += 8 + size + (size & 1)
base = int(re.search(r"^cycles = (\d+)", text, re.M).group(1))
cycles = max(1, round(float(sys.argv[3]) * 3600 / (seconds / base)))
pathlib.Path(sys.argv[4]).write_text(re.sub(r"^cycles = \d+", f"cycles = {cycles}", text, count=1, flags=re.M))
print(f"simulate: {cycles} cycles", file=sys.stderr)
PY
  sim_out=$out/sim-${hours}h
  rm -rf "$sim_out"
  /usr/bin/time -f '%M %e %U %S' -o "$out/simulate.time" "$ptda" simulate --scenario "$scen" --out "$sim_out" \
    --seed 3003 >"$out/simulate.log" 2>&1 || echo "simulate exited $?" >&2
  read -r rss wall user sys <"$out/simulate.time"
  sim_h=$(awk '$1 == "duration" {printf "%.3f", $2 / 3600}' "$out/simulate.log")
  printf '%s\t%s\t%.1f\t%.1f\t%.1f\t-\n' simulate "$sim_h" "$(echo "$rss / 1024" | bc -l)" "$wall" \
    "$(echo "$user + $sys" | bc -l)" >>"$out/results.tsv"
  [[ ${KEEP:-0} == 1 ]] || rm -rf "$sim_out"
fi
column -t "$out/results.tsv"
