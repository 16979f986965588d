#!/usr/bin/env bash
# The README's test command: installs what is missing, builds with warnings as errors and runs the
# whole suite. Usage: scripts/test.sh [preset]   (presets: release (default), asan, tsan)
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
scripts/bootstrap.sh
jobs="$(nproc 2>/dev/null || echo 2)"
cmake --preset "$preset"
cmake --build --preset "$preset" -j "$jobs"
ctest --preset "$preset" -j "$jobs"
