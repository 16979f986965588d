#!/usr/bin/env bash
# Instructions per second of signal on aarch64 (issue 13 item 5), counted under qemu-user, and the
# channels one Cortex-A53 core could hold at 25.6 kHz (docs/benchmarks.md §9).
#
# Usage: scripts/bench_aarch64.sh [HOST_BUILD] [AARCH64_BUILD] [OUT]
#   HOST_BUILD     default build/release (its cli/ptda simulates and trains)
#   AARCH64_BUILD  default build/aarch64-release (its cli/ptda is counted; build it with
#                  `cmake --build build/aarch64-release --target ptda` after scripts/cross_test.sh aarch64
#                  made the sysroot and configured the preset)
#   OUT            default out/bench-aarch64
# Environment: PTDA_SYSROOT (default build/sysroots/aarch64-linux-gnu), LONG_S / SHORT_S (recording
#              lengths, default 30 and 10 s).
#
# How it counts: qemu-aarch64 -d in_asm,exec,nochain logs every translated block's instructions once and
# every executed block's guest pc; scripts/count_tb_insns.py sums the instructions of the executed blocks
# (exact for user-mode code; the kernel's work in system calls is not counted). `ptda monitor` (the
# engine ptdad runs, plus WAV decoding and candump parsing) runs on two recordings of the same job,
# SHORT_S and LONG_S long: the difference divided by LONG_S - SHORT_S is the cost per second of signal
# without start-up (reading the baseline, the line groups).
#
# Recording: the gfd_like preset at 25.6 kHz, constant speed, cut into back-to-back windows of
# N = 12800 (2 windows per second), as scripts/bench.sh.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
host=${1:-$root/build/release}
a64=${2:-$root/build/aarch64-release}
out=${3:-$root/out/bench-aarch64}
sysroot=${PTDA_SYSROOT:-$root/build/sysroots/aarch64-linux-gnu}
long_s=${LONG_S:-30}
short_s=${SHORT_S:-10}
ptda=$host/cli/ptda
ptda_a64=$a64/cli/ptda
for f in "$ptda" "$ptda_a64"; do [[ -x $f ]] || { echo "bench_aarch64: no $f (build it first)" >&2; exit 1; }; done
[[ -d $sysroot ]] || { echo "bench_aarch64: no sysroot $sysroot (scripts/sysroot.sh arm64)" >&2; exit 1; }
command -v qemu-aarch64 >/dev/null || { echo "bench_aarch64: qemu-aarch64 missing (apt install qemu-user)" >&2; exit 1; }
file "$ptda_a64" | grep -q aarch64 || { echo "bench_aarch64: $ptda_a64 is not an aarch64 binary" >&2; exit 1; }
mkdir -p "$out"

scen() {  # SEED DURATION_S OUT_TOML
  sed -e "s/^seed *=.*/seed = $1/" -e "s/^duration_s *=.*/duration_s = $2/" -e "s/^cycles *=.*/cycles = ${2%.*}/" \
    -e "s/^fs_hz = 64500/fs_hz = 25600/" "$root/config/scenarios/gfd_like.toml" >"$3"
}
cfg=$out/config.toml
sed -e 's/^window_len *=.*/window_len = 12800/' -e 's/^hop *=.*/hop = 12800/' "$root/config/examples/gfd.toml" >"$cfg"
if [[ ! -f $out/baseline.bin ]]; then
  scen 11 120.0 "$out/train.toml"
  "$ptda" simulate --scenario "$out/train.toml" --out "$out/train" >/dev/null
  "$ptda" train --recording "$out/train" --config "$cfg" --out "$out/baseline.bin" >/dev/null
fi
for s in "$short_s" "$long_s"; do
  if [[ ! -d $out/rec$s ]]; then
    scen 12 "$s.0" "$out/rec$s.toml"
    "$ptda" simulate --scenario "$out/rec$s.toml" --out "$out/rec$s" >/dev/null
  fi
done

count() {  # LENGTH_S -> prints "instructions windows"
  local fifo=$out/qemu.fifo
  rm -f "$fifo"
  mkfifo "$fifo"
  /usr/bin/python3 "$root/scripts/count_tb_insns.py" <"$fifo" >"$out/count$1.txt" &
  local counter=$!
  qemu-aarch64 -L "$sysroot" -d in_asm,exec,nochain -D "$fifo" "$ptda_a64" monitor --recording "$out/rec$1" \
    --config "$cfg" --baseline "$out/baseline.bin" --jsonl "$out/monitor$1.jsonl" --quiet >/dev/null
  wait "$counter"
  rm -f "$fifo"
  echo "$(cat "$out/count$1.txt") $(grep -c . "$out/monitor$1.jsonl")"
}
read -r ins_short win_short < <(count "$short_s")
read -r ins_long win_long < <(count "$long_s")
# The same windows as the host build judges (the aarch64 build's features are checked by the unit
# suite under qemu; here only the counts).
"$ptda" monitor --recording "$out/rec$long_s" --config "$cfg" --baseline "$out/baseline.bin" \
  --jsonl "$out/host$long_s.jsonl" --quiet >/dev/null
win_host=$(grep -c . "$out/host$long_s.jsonl")
[[ $win_host == "$win_long" ]] || { echo "bench_aarch64: aarch64 judged $win_long windows, host $win_host" >&2; exit 1; }

awk -v a="$ins_short" -v b="$ins_long" -v sa="$short_s" -v sb="$long_s" -v wa="$win_short" -v wb="$win_long" '
BEGIN {
  per_s = (b - a) / (sb - sa); per_w = (b - a) / (wb - wa)
  printf "| quantity | value |\n|---|---:|\n"
  printf "| instructions, `ptda monitor` on %d s / %d s of signal | %.4g / %.4g |\n", sa, sb, a, b
  printf "| windows judged (N = 12800) | %d / %d |\n", wa, wb
  printf "| instructions per second of signal (difference) | %.4g |\n", per_s
  printf "| instructions per window (difference) | %.4g |\n", per_w
  printf "| start-up (the %d s run minus %d s x per second) | %.4g |\n", sa, sa, a - sa * per_s
  # Cortex-A53 at 1.2 GHz; IPC 0.6 (in-order, dual-issue; DSP loops with NEON) to 1.0: the range below.
  for (ipc = 0.6; ipc <= 1.01; ipc += 0.4)
    printf "| channels per A53 core at 1.2 GHz, IPC %.1f, 50 %% of the core | %.0f |\n", ipc, 0.5 * 1.2e9 * ipc / per_s
}' | tee "$out/summary.md"
