#!/usr/bin/env bash
# The README's test command: installs what is missing (apt), builds with warnings as errors and runs
# the whole suite in three configurations:
#   release - every test (RelWithDebInfo)
#   asan    - every test under AddressSanitizer + UndefinedBehaviorSanitizer
#   tsan    - the threaded daemon tests (ring, pipeline) under ThreadSanitizer
# Usage: scripts/test.sh [all|release|asan|tsan]   (default: all)
set -euo pipefail
cd "$(dirname "$0")/.."
what="${1:-all}"
scripts/bootstrap.sh
scripts/lint.sh   # clang-format gate (naming: scripts/lint.sh <build_dir>)
jobs="$(nproc 2>/dev/null || echo 2)"

run_preset() {  # preset [build target] [ctest label]
  local preset="$1" target="${2:-all}" label="${3:-}"
  echo "=== ${preset}: configure + build (${target}) ==="
  cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset" -j "$jobs" --target "$target"
  echo "=== ${preset}: ctest ${label:+-L $label} ==="
  if [ -n "$label" ]; then
    ctest --preset "$preset" -j "$jobs" -L "$label"
  else
    ctest --preset "$preset" -j "$jobs"
  fi
}

case "$what" in
  release) run_preset release ;;
  asan) run_preset asan ;;
  tsan) run_preset tsan tests_daemon daemon ;;
  all)
    run_preset release
    run_preset asan
    run_preset tsan tests_daemon daemon
    ;;
  *) echo "usage: scripts/test.sh [all|release|asan|tsan]" >&2; exit 2 ;;
esac
