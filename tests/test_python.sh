#!/usr/bin/env bash
# tests/test_python.sh: the Python package's pytest suite (python/tests) for make test, reported as a Check
# suite's summary line ("NN%: Checks: C, Failures: F, Errors: E") so that tests/run.sh counts its tests in
# the closing "N passed, N failed". A skipped test counts as a failure (nothing here should skip), and so
# does a missing interpreter or module (no summary line: run.sh reports the suite as failing).
# Debian's /usr/bin/python3 with python3-numpy, python3-h5py and python3-pytest (make deps installs them);
# the library and executable of this build ($BUILD, $BIN as make test passes them); no bytecode or pytest
# cache is written into the tree.
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root" || exit 1
abs() { case "$1" in /*) echo "$1" ;; *) echo "$root/$1" ;; esac; }
BUILD=$(abs "${BUILD:-build}")
BIN=$(abs "${BIN:-bin}")
PY=/usr/bin/python3
major=$(sed -n 's/^#define WT_VERSION_MAJOR \([0-9]*\).*/\1/p' include/wavetomo/version.h)
export WAVETOMO_LIB="$BUILD/libwavetomo.so.$major" WAVETOMO_BIN="$BIN/wavetomo" PYTHONPATH="$root/python" \
       PYTHONDONTWRITEBYTECODE=1 OMP_WAIT_POLICY=passive
# a sanitized library (make debug-test) needs its runtimes loaded first into an interpreter built without
# them; the interpreter's own allocations are not the library's leaks
if ldd "$WAVETOMO_LIB" 2>/dev/null | grep -q libasan; then
  export LD_PRELOAD="$(gcc -print-file-name=libasan.so):$(gcc -print-file-name=libubsan.so)"
  export ASAN_OPTIONS="detect_leaks=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
fi
tmp=$(mktemp -d /tmp/wt-pytest.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
"$PY" -m pytest -q -rfEs -p no:cacheprovider --basetemp="$tmp/t" --junitxml="$tmp/junit.xml" python/tests > "$tmp/out.txt" 2>&1
rc=$?
summary=$("$PY" - "$tmp/junit.xml" <<'PYEOF' 2>/dev/null
import sys, xml.etree.ElementTree as ET
root = ET.parse(sys.argv[1]).getroot()
suites = [root] if root.tag == "testsuite" else list(root.iter("testsuite"))
n = sum(int(s.get("tests", 0)) for s in suites)
f = sum(int(s.get("failures", 0)) + int(s.get("skipped", 0)) for s in suites)
e = sum(int(s.get("errors", 0)) for s in suites)
print("%d%%: Checks: %d, Failures: %d, Errors: %d" % (100 * (n - f - e) // max(n, 1), n, f, e))
PYEOF
)
# the failures first (tests/run.sh shows the first lines of a failing suite), then pytest's own report
grep -E '^(FAILED|ERROR|SKIPPED)' "$tmp/out.txt"
cat "$tmp/out.txt"
if [ -z "$summary" ]; then
  echo "test_python.sh: pytest wrote no report (exit $rc): is $PY with numpy, h5py and pytest installed (make deps)?"
  exit 1
fi
echo "$summary"
[ "$rc" = 0 ]
