#!/usr/bin/env bash
# tests/run.sh: runs every Check suite binary given on the command line, then prints one closing line
# "N passed, N failed" counted over all test cases of all suites.
set -u
# A failing suite's every failed assertion and error (Check's "file:line:F:case:test:i: message" and ":E:"
# lines, wherever they fall in its output), then its last lines (a crash, a timeout, what it printed last).
show_failure() {
  echo "$1" | grep -E '^[^ ]+:[0-9]+:[FE]:'
  echo "  ... last lines:"
  echo "$1" | grep -vE '^[0-9]+%: Checks|^[^ ]+:[0-9]+:[FE]:' | tail -n 15 | sed 's/^/  /'
}
passed=0; failed=0; bad_suites=()
for t in "$@"; do
  name=$(basename "$t")
  start=$(date +%s.%N)
  out=$("$t" 2>&1); rc=$?
  secs=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}')
  echo "$out" | grep -E '^[0-9]+%: Checks' | sed "s/^/$name: /; s/\$/ (${secs} s)/"
  # Check's summary: "NN%: Checks: C, Failures: F, Errors: E"
  line=$(echo "$out" | grep -E '^[0-9]+%: Checks' | tail -n 1)
  if [ -z "$line" ]; then
    show_failure "$out"
    echo "$name: no Check summary (exit $rc)"; failed=$((failed + 1)); bad_suites+=("$name"); continue
  fi
  c=$(echo "$line" | sed -E 's/.*Checks: ([0-9]+).*/\1/')
  f=$(echo "$line" | sed -E 's/.*Failures: ([0-9]+).*/\1/')
  e=$(echo "$line" | sed -E 's/.*Errors: ([0-9]+).*/\1/')
  passed=$((passed + c - f - e)); failed=$((failed + f + e))
  if [ "$f" != 0 ] || [ "$e" != 0 ] || [ "$rc" != 0 ]; then
    show_failure "$out"
    bad_suites+=("$name")
    [ "$f" = 0 ] && [ "$e" = 0 ] && failed=$((failed + 1))
  fi
done
[ ${#bad_suites[@]} -gt 0 ] && echo "failing suites: ${bad_suites[*]}"
echo "${passed} passed, ${failed} failed"
[ "$failed" = 0 ]
