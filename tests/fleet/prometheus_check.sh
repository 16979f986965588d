#!/bin/sh
# The fleet view's Prometheus files (issue 15 item 5), checked with Debian's promtool (package
# prometheus, scripts/bootstrap.sh):
#   1. `promtool check rules` on packaging/prometheus/ptda-alerts.yml;
#   2. `promtool test rules` on ptda-alerts.test.yml (every alert fires and clears where it should);
#   3. the rule tests can fail: with the alarm rule's level changed they must;
#   4. `promtool check metrics` on the textfiles the status writer renders (monitoring and field
#      training, with the joint label), written by the FleetFiles gtest run here.
# Usage: prometheus_check.sh SOURCE_DIR STATUS_WRITER_TEST_BINARY
set -eu
src="$1"
gtest="$2"
command -v promtool >/dev/null || { echo "FAIL: promtool not found (apt install prometheus; scripts/bootstrap.sh)"; exit 1; }
dir="$src/packaging/prometheus"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

promtool check rules "$dir/ptda-alerts.yml"
(cd "$dir" && promtool test rules ptda-alerts.test.yml)

cp "$dir/ptda-alerts.test.yml" "$tmp/"
sed 's/expr: ptda_alarm_level == 2$/expr: ptda_alarm_level >= 1/' "$dir/ptda-alerts.yml" >"$tmp/ptda-alerts.yml"
if cmp -s "$dir/ptda-alerts.yml" "$tmp/ptda-alerts.yml"; then
  echo "FAIL: the mutation did not apply (the alarm rule's expression changed?)"
  exit 1
fi
if (cd "$tmp" && promtool test rules ptda-alerts.test.yml >"$tmp/mutant.log" 2>&1); then
  echo "FAIL: the rule tests pass with an alarm rule that also fires on warnings: they cannot fail"
  exit 1
fi
echo "ok: the rule tests fail on a mutated alarm rule"

PTDA_TEST_TMP="$tmp/gtest" "$gtest" --gtest_filter=FleetFiles.RulesAndDashboardUseOnlyMetricsTheDaemonWrites >"$tmp/gtest.log" 2>&1 || {
  cat "$tmp/gtest.log"
  echo "FAIL: the FleetFiles test failed"
  exit 1
}
for f in monitoring training; do
  prom="$tmp/gtest/status_writer_test/fleet/$f.prom"
  [ -s "$prom" ] || { echo "FAIL: $prom was not written"; exit 1; }
  if ! out=$(promtool check metrics <"$prom" 2>&1); then
    echo "$out"
    echo "FAIL: promtool check metrics: $f.prom"
    exit 1
  fi
  echo "ok: promtool check metrics $f.prom ($(grep -c -v '^#' "$prom") samples)"
done
