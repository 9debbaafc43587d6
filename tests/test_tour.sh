#!/usr/bin/env bash
# tests/test_tour.sh: the README's and the guide's commands as a newcomer types them. Every command line of
# their ```sh blocks (default README.md then docs/guide.md; or the documents given as arguments) runs in order, as
# written, in order (a block's variable assignments carry over to its later lines) inside a temporary directory where bin/ is this
# build's ($BIN, as make test passes it) and data/ the source tree's; a command that exits non-zero fails.
# Reported as a Check suite's summary line ("NN%: Checks: C, Failures: F, Errors: E") so that tests/run.sh
# counts each command, with a Check-style "FILE:LINE:F:tour:..." line per failure.
# Commands at E-ELT size (they name an eelt-* preset, directly or through a variable set to one: minutes and
# gigabytes each) run with --dry-run added: their arguments and configuration are checked, not the run
# (bench, which has no --dry-run, is skipped). Skipped, and listed as skipped: mpirun lines (tests/test_mpi.c runs MPI with the
# launcher's options for this machine) and make targets (`make test` is what runs this; `make demo` is the
# tour's compare with its output in the source tree). The README's demo-size tour takes 40–90 s on 2 cores, the
# guide's ~60 s more.
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root" || exit 1
abs() { case "$1" in /*) echo "$1" ;; *) echo "$root/$1" ;; esac; }
BIN=$(abs "${BIN:-bin}")
[ $# -gt 0 ] || set -- README.md docs/guide.md
tmp=$(mktemp -d /tmp/wt-tour.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
ln -s "$BIN" "$tmp/bin"
ln -s "$root/data" "$tmp/data"
export OMP_WAIT_POLICY=passive

checks=0; failures=0
for doc in "$@"; do
  # the blocks' logical lines (backslash continuations joined) as "BLOCK<TAB>LINE<TAB>text"
  lines=$(awk '
    /^```sh[[:space:]]*$/ { inblock = 1; block++; next }
    /^```/ { inblock = 0; next }
    inblock {
      if (cont != "") { text = cont " " $0; } else { text = $0; start = NR }
      if (text ~ /\\[[:space:]]*$/) { sub(/\\[[:space:]]*$/, "", text); cont = text; next }
      cont = ""
      if (text !~ /^[[:space:]]*(#|$)/) print block "\t" start "\t" text
    }' "$doc")
  eelt_vars=""
  while IFS=$'\t' read -r block line text; do
    [ -n "$block" ] || continue
    name=$(printf '%s' "$text" | sed -E 's/[[:space:]]+#.*$//')
    if [[ "$name" =~ ^[[:space:]]*([A-Za-z_][A-Za-z_0-9]*)= ]]; then # a variable: always kept
      [[ "$name" == *eelt* ]] && eelt_vars="$eelt_vars ${BASH_REMATCH[1]}"
      echo "$text" >> "$tmp/vars.$block"
      continue
    fi
    eelt=""; skip=""; cmd=$text
    [[ "$name" == *eelt-* ]] && eelt="E-ELT size"
    for v in $eelt_vars; do [[ "$name" == *"\$$v"* ]] && eelt="E-ELT size (\$$v)"; done
    if [ -n "$eelt" ]; then # the arguments and the configuration checked, not the run
      cmd="$name --dry-run"
      [[ "$name" == *" bench "* ]] && skip="$eelt, bench has no --dry-run"
    fi
    [[ "$name" =~ ^[[:space:]]*mpirun ]] && skip="mpirun (tests/test_mpi.c)"
    [[ "$name" =~ ^[[:space:]]*make ]] && skip="a make target (make test runs this; make demo writes into out/)"
    if [ -n "$skip" ]; then
      echo "$doc:$line: skipped, $skip: $name"
      continue
    fi
    checks=$((checks + 1))
    start=$(date +%s.%N)
    (cd "$tmp" && { [ -f "vars.$block" ] && . "./vars.$block"; eval "$cmd"; }) > "$tmp/out.txt" 2>&1
    rc=$?
    secs=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}')
    if [ "$rc" != 0 ]; then
      failures=$((failures + 1))
      echo "$doc:$line:F:tour:command:0: exit $rc: $name${eelt:+ --dry-run ($eelt)}"
      tail -n 8 "$tmp/out.txt" | sed 's/^/    /'
    else
      echo "$doc:$line: ok (${secs} s${eelt:+, $eelt: --dry-run only}): $name"
    fi
  done <<< "$lines"
done
pass=$((checks - failures))
echo "$((checks > 0 ? 100 * pass / checks : 0))%: Checks: $checks, Failures: $failures, Errors: 0"
[ "$failures" = 0 ] && [ "$checks" -gt 0 ]
