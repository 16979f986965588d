#!/usr/bin/env bash
# Byte-for-byte comparison of two builds' offline outputs (issue 13: an optimisation must not change any
# result). Simulates recordings with BEFORE, then trains and monitors them with both builds and compares
# the baseline files, the JSONL of every method and the printed tables.
#   - the paper jobs (config/examples/<job>.toml): train on <job>_healthy, monitor <job>_faulty;
#   - gfd_like at 25.6 kHz with windows of 12800 in all four WAV sample formats (pcm16, pcm24, pcm32,
#     float32), and with `scale` != 1 in recording.toml (the monitor's scaling path).
# Usage: scripts/compare_builds.sh BEFORE_BUILD_DIR AFTER_BUILD_DIR [OUT_DIR]
# Exit status 1 when any output differs. Cost: ~3 min on the 2-core development host.
set -euo pipefail
before=${1:?before build dir}/cli/ptda
after=${2:?after build dir}/cli/ptda
out=${3:-$(mktemp -d)}
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
fail=0
same() {  # $1 $2 = files, $3 = label
  if cmp -s "$1" "$2"; then echo "same      $3"; else echo "DIFFERENT $3"; fail=1; fi
}
check() {  # $1 = tag, $2 = config, $3 = training recording, $4 = monitored recording
  local tag=$1 cfg=$2 train=$3 mon=$4
  for b in before after; do
    local bin=$before
    [[ $b == after ]] && bin=$after
    "$bin" train --recording "$train" --config "$cfg" --out "$out/$tag.$b.bin" >"$out/$tag.train.$b.txt"
    sed -i "s/$tag\.$b\.bin/$tag.BUILD.bin/" "$out/$tag.train.$b.txt"  # the only intended difference
    for m in raw tda ptda; do
      # Both builds monitor with BEFORE's baseline, so a monitor difference is not a training one.
      "$bin" monitor --recording "$mon" --config "$cfg" --baseline "$out/$tag.before.bin" --method "$m" \
        --jsonl "$out/$tag.$m.$b.jsonl" >"$out/$tag.$m.$b.txt"
    done
  done
  same "$out/$tag.before.bin" "$out/$tag.after.bin" "$tag: baseline file"
  same "$out/$tag.train.before.txt" "$out/$tag.train.after.txt" "$tag: train output"
  for m in raw tda ptda; do
    same "$out/$tag.$m.before.jsonl" "$out/$tag.$m.after.jsonl" "$tag: monitor --method $m JSONL ($(wc -l <"$out/$tag.$m.after.jsonl") windows)"
    same "$out/$tag.$m.before.txt" "$out/$tag.$m.after.txt" "$tag: monitor --method $m table"
  done
}

for job in joint_rotation arc_welding spot_welding; do
  for kind in healthy faulty; do
    [[ -d $out/${job}_$kind ]] ||
      "$before" simulate --scenario "$root/config/scenarios/${job}_$kind.toml" --out "$out/${job}_$kind" >/dev/null
  done
  check "$job" "$root/config/examples/$job.toml" "$out/${job}_healthy" "$out/${job}_faulty"
done

cfg=$out/gfd12800.toml
sed -e 's/^window_len *=.*/window_len = 12800/' -e 's/^hop *=.*/hop = 12800/' "$root/config/examples/gfd.toml" >"$cfg"
for fmt in pcm16 pcm24 pcm32 float32; do
  for seed in 21 22; do
    rec=$out/gfd_${fmt}_$seed
    if [[ ! -d $rec ]]; then
      sed -e "s/^seed *=.*/seed = $seed/" -e "s/^duration_s *=.*/duration_s = 60.0/" \
        -e "s/^fs_hz = 64500/fs_hz = 25600/" -e "s/^format *=.*/format = \"$fmt\"/" \
        "$root/config/scenarios/gfd_like.toml" >"$rec.toml"
      "$before" simulate --scenario "$rec.toml" --out "$rec" >/dev/null
    fi
  done
  check "gfd_$fmt" "$cfg" "$out/gfd_${fmt}_21" "$out/gfd_${fmt}_22"
done
# scale != 1: the same samples read as a quarter of their value (train and monitor alike).
for seed in 21 22; do
  rec=$out/gfd_scaled_$seed
  rm -rf "$rec"
  cp -r "$out/gfd_pcm24_$seed" "$rec"
  sed -i 's/^scale *=.*/scale = 0.25/' "$rec/recording.toml"
done
check gfd_scaled "$cfg" "$out/gfd_scaled_21" "$out/gfd_scaled_22"
exit $fail
