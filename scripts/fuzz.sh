#!/usr/bin/env bash
# Builds the libFuzzer harnesses (tests/fuzz, clang-14, ASan+UBSan) in build/fuzz and runs each for a
# while, or only replays the committed corpora (docs/reliability.md).
# Usage: scripts/fuzz.sh [SECONDS_PER_TARGET]   (default 60; 0 = replay the seed corpora only)
#        PTDA_FUZZ_TARGETS="wav baseline" scripts/fuzz.sh 600   (a subset)
# New inputs go to build/fuzz/corpus/<target> (seeded from tests/fuzz/corpus/<target>), crashes to
# build/fuzz/artifacts/<target>/. Exit status 1 when any target crashed. Needs clang-14 and
# libclang-rt-14-dev (scripts/bootstrap.sh fuzz).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
targets=(${PTDA_FUZZ_TARGETS:-candump_line wav recording_toml baseline scenario iio_scan_type daemon_config can_frame iio_sysfs
  status_escape})
build=build/fuzz

if [ ! -f "$build/CMakeCache.txt" ]; then
  CC=clang-14 CXX=clang++-14 cmake -S . -B "$build" -DPTDA_FUZZ=ON -DPTDA_BUILD_TESTS=OFF \
    -DPTDA_WERROR=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
fi
cmake --build "$build" -j2 --target "${targets[@]/#/fuzz_}"

failed=0
for t in "${targets[@]}"; do
  bin="$build/tests/fuzz/fuzz_$t"
  seeds="tests/fuzz/corpus/$t"
  dict=()
  case "$t" in recording_toml | scenario | daemon_config) dict=(-dict=tests/fuzz/dict_toml.txt) ;; esac
  if [ "$seconds" = 0 ]; then
    echo "== replay $t ($(ls "$seeds" | wc -l) seeds)"
    "$bin" -runs=0 "$seeds" 2>&1 | tail -n 2 || failed=1
    continue
  fi
  work="$build/corpus/$t"
  art="$build/artifacts/$t"
  mkdir -p "$work" "$art"
  echo "== fuzz $t for ${seconds}s"
  if ! "$bin" "${dict[@]}" -max_len=65536 -rss_limit_mb=2048 -timeout=10 -max_total_time="$seconds" \
    -print_final_stats=1 -artifact_prefix="$art/" "$work" "$seeds" \
    >"$build/fuzz-$t.log" 2>&1; then
    echo "   CRASH: see $build/fuzz-$t.log and $art/" >&2
    failed=1
  fi
  grep -E 'stat::number_of_executed_units|cov:' "$build/fuzz-$t.log" | tail -n 2 || true
done
exit $failed
