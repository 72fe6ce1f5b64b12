#!/usr/bin/env bash
# Counts the results in a gtest console log: one line per test as gtest prints it when the
# test ends, "[       OK ] Suite.Name (12 ms)", "[  SKIPPED ] ..." or "[  FAILED  ] ..." (the
# summary at the end lists skipped and failed tests again, without a time: not counted).
#   tools/gpu/gtest_counts.sh LOG                 prints "P passed, S skipped, F failed"
#   tools/gpu/gtest_counts.sh --self-test BINARY  runs BINARY's RunbookSelfTest.* cases (one
#                                                 passes, one skips, one fails on purpose) and
#                                                 exits 0 only if they count as 1, 1 and 1
set -uo pipefail

count() {
  local ok skip fail
  ok=$(grep -cE '^\[ +OK \] .* \([0-9]+ ms\)$' "$1")
  skip=$(grep -cE '^\[ +SKIPPED \] .* \([0-9]+ ms\)$' "$1")
  fail=$(grep -cE '^\[ +FAILED +\] .* \([0-9]+ ms\)$' "$1")
  echo "$ok passed, $skip skipped, $fail failed"
}

if [ "${1:-}" = --self-test ]; then
  log=$(mktemp)
  trap 'rm -f "$log"' EXIT
  TANDEM_RUNBOOK_SELFTEST=1 "$2" --gtest_filter='RunbookSelfTest.*' >"$log" 2>&1
  rc=$?
  got=$(count "$log")
  echo "gtest_counts: $got (exit $rc)"
  [ "$got" = "1 passed, 1 skipped, 1 failed" ] && [ "$rc" -ne 0 ]
  exit
fi
[ -f "${1:-}" ] || { echo "usage: gtest_counts.sh LOG | --self-test BINARY" >&2; exit 2; }
count "$1"
