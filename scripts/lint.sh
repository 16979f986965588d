#!/usr/bin/env bash
# Style gate: clang-format (layout) on every C++ file, and clang-tidy's naming check on the project's
# sources (types UpperCamel, functions/variables snake_case, members_, kConstants; see .clang-tidy).
# Usage: scripts/lint.sh [build_dir_with_compile_commands]   (format only when no build dir is given)
set -euo pipefail
cd "$(dirname "$0")/.."
mapfile -t files < <(git ls-files '*.cpp' '*.hpp')
echo "lint: clang-format on ${#files[@]} files"
clang-format --dry-run -Werror "${files[@]}"
build="${1:-}"
if [ -n "$build" ]; then
  mapfile -t srcs < <(git ls-files '*.cpp' | grep -v -e '^tests/' -e '/bench/')
  echo "lint: clang-tidy naming on ${#srcs[@]} sources"
  out=$(printf '%s\n' "${srcs[@]}" | xargs -P "$(nproc)" -n 6 clang-tidy -p "$build" --quiet \
        --checks='-*,readability-identifier-naming' 2>/dev/null | grep -E 'warning:' || true)
  if [ -n "$out" ]; then
    echo "$out"
    echo "lint: naming violations found" >&2
    exit 1
  fi
fi
echo "lint: ok"
