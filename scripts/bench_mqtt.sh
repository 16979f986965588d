#!/usr/bin/env bash
# Broker load of a plant's ptdad MQTT traffic (issue 15 item 6; results in docs/fleet.md "Broker load").
# Starts a local mosquitto (Debian's, scripts/bootstrap.sh) on a free port, runs
# build/.../daemon/bench/mqtt_load_bench with JOINTS connections for SECONDS, and reports the broker's CPU
# time (utime + stime from /proc/<pid>/stat, in ms per s of run) and peak RSS (VmHWM).
# Usage: scripts/bench_mqtt.sh [build_dir] [joints...]     (default build/release, joints 50 500)
# Environment: SECONDS_RUN (default 60), SUMMARY_S (10), CHANGE_S (60: one level change per joint a minute,
#              a pessimistic rate).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-${here}/build/release}"
shift || true
joints=("$@")
[[ ${#joints[@]} -gt 0 ]] || joints=(50 500)
bench="${build}/daemon/bench/mqtt_load_bench"
[[ -x "$bench" ]] || { echo "bench_mqtt: $bench not built (cmake --build $build --target mqtt_load_bench)" >&2; exit 1; }
command -v mosquitto >/dev/null || { echo "bench_mqtt: mosquitto not installed (scripts/bootstrap.sh)" >&2; exit 1; }
run_s="${SECONDS_RUN:-60}"
work="$(mktemp -d)"
trap 'kill "${broker_pid:-}" 2>/dev/null || true; rm -rf "$work"' EXIT
port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')"
ulimit -n 4096 2>/dev/null || true
{
  echo "listener ${port} 127.0.0.1"
  echo "allow_anonymous true"
  echo "persistence false"
  echo "max_queued_messages 10000"
  echo "max_inflight_messages ${MAX_INFLIGHT:-20}"
  [[ "$(id -u)" -eq 0 ]] && echo "user root"
} >"$work/m.conf"
tick="$(getconf CLK_TCK)"
echo "| joints | run s | messages/s sent | payload B/s sent | received by the dashboard | broker CPU ms per s | broker peak RSS |"
echo "|---|---|---|---|---|---|---|"
for n in "${joints[@]}"; do
  mosquitto -c "$work/m.conf" >"$work/broker.log" 2>&1 &
  broker_pid=$!
  for _ in $(seq 50); do (echo >"/dev/tcp/127.0.0.1/${port}") 2>/dev/null && break; sleep 0.1; done
  read -r -a st0 < <(cut -d' ' -f14,15 "/proc/${broker_pid}/stat")
  t0=$(date +%s.%N)
  # At most 250 joints per process (libmosquitto's select() loop: mqtt_load_bench.cpp); process 0 also
  # runs the dashboard subscriber.
  pids=() first=0 k=0
  while (( first < n )); do
    c=$(( n - first < 250 ? n - first : 250 ))
    "$bench" --port "$port" --joints "$c" --first "$first" --dashboard $(( k == 0 ? 1 : 0 )) --seconds "$run_s" \
      --summary-s "${SUMMARY_S:-10}" --change-s "${CHANGE_S:-60}" >"$work/out.$k" &
    pids+=($!)
    first=$(( first + c )); k=$(( k + 1 ))
  done
  for p in "${pids[@]}"; do wait "$p"; done
  line="$(awk '{ for (i = 1; i <= NF; ++i) { split($i, kv, "="); if (kv[1] ~ /^sent/) s[kv[1]] += kv[2]; else if (NR == 1 || kv[1] == "joints") v[kv[1]] = (kv[1] == "joints" ? v[kv[1]] + kv[2] : kv[2]) } }
    END { printf "joints=%d seconds=%s sent=%d sent_qos1=%d sent_bytes=%d received=%s received_qos1=%s received_bytes=%s msg_per_s=%.1f bytes_per_s=%.0f\n",
      v["joints"], v["seconds"], s["sent"], s["sent_qos1"], s["sent_bytes"], v["received"], v["received_qos1"], v["received_bytes"], s["sent"] / v["seconds"], s["sent_bytes"] / v["seconds"] }' "$work"/out.*)"
  t1=$(date +%s.%N)
  read -r -a st1 < <(cut -d' ' -f14,15 "/proc/${broker_pid}/stat")
  hwm="$(awk '/VmHWM/ {print $2, $3}' "/proc/${broker_pid}/status")"
  kill "$broker_pid"; wait "$broker_pid" 2>/dev/null || true
  ticks=$(( (st1[0] + st1[1]) - (st0[0] + st0[1]) ))
  awk -v line="$line" -v ticks="$ticks" -v tick="$tick" -v t0="$t0" -v t1="$t1" -v hwm="$hwm" 'BEGIN {
    n = split(line, f, " ");
    for (i = 1; i <= n; ++i) { split(f[i], kv, "="); v[kv[1]] = kv[2]; }
    printf "| %s | %s | %s | %s | %s of %s | %.2f | %s |\n", v["joints"], v["seconds"], v["msg_per_s"],
      v["bytes_per_s"], v["received"], v["sent"], 1000.0 * ticks / tick / (t1 - t0), hwm
  }'
  echo "  raw: $line" >&2
done
