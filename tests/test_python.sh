#!/usr/bin/env bash
# tests/test_python.sh: the Python package as a user installs it, then its pytest suite (python/tests), for
# make test and make check-python-package. Reported as a Check suite's summary line ("NN%: Checks: C,
# Failures: F, Errors: E") so that tests/run.sh counts its tests in the closing "N passed, N failed". A skipped
# test counts as a failure (nothing here should skip), and so does a failed install, a missing interpreter or
# module (no summary line: run.sh reports the suite as failing).
#
# The install is the README's: the files a fresh clone has (git's tracked and new unignored files, copied to a
# temporary directory: no build output), `pip install --no-build-isolation --no-index` of that copy into a
# new virtual environment made with --system-site-packages (Debian's numpy, h5py, pytest), offline. The
# venv is made --without-pip and Debian's pip installs into it (--python): ensurepip would add seconds and
# test nothing of ours. The suite then runs from that copy with the venv's interpreter, so it exercises the
# installed package, against the library and executable of this build ($BUILD, $BIN as make test passes
# them). Debian's /usr/bin/python3 with python3-venv, -pip, -setuptools, -wheel, -numpy, -h5py, -pytest
# (make deps installs them); no bytecode or pytest cache is written into the tree.
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root" || exit 1
abs() { case "$1" in /*) echo "$1" ;; *) echo "$root/$1" ;; esac; }
BUILD=$(abs "${BUILD:-build}")
BIN=$(abs "${BIN:-bin}")
PY=/usr/bin/python3
major=$(sed -n 's/^#define WT_VERSION_MAJOR \([0-9]*\).*/\1/p' include/wavetomo/version.h)
export WAVETOMO_LIB="$BUILD/libwavetomo.so.$major" WAVETOMO_BIN="$BIN/wavetomo" PYTHONDONTWRITEBYTECODE=1 \
       OMP_WAIT_POLICY=passive
unset PYTHONPATH
tmp=$(mktemp -d /tmp/wt-pytest.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
install() {
  mkdir -p "$tmp/src" || return 1
  if git -C "$root" rev-parse --git-dir > /dev/null 2>&1; then
    git -C "$root" ls-files -z --cached --others --exclude-standard |
      tar -C "$root" --null -T - --ignore-failed-read -cf - 2> /dev/null | tar -C "$tmp/src" -xf - || return 1
  else  # not a git checkout (a release tarball): what pip and the tests read
    cp -r pyproject.toml setup.py python include docs data "$tmp/src/" || return 1
  fi
  "$PY" -m venv --without-pip --system-site-packages "$tmp/venv" || return 1
  "$PY" -m pip --python "$tmp/venv/bin/python" install -q --no-build-isolation --no-index --no-cache-dir \
      --disable-pip-version-check --root-user-action=ignore "$tmp/src" || return 1
  # the package imported is the venv's, from a directory of nothing
  (cd "$tmp" && "$tmp/venv/bin/python" -c '
import sys, wavetomo
assert wavetomo.__file__.startswith(sys.argv[1]), "imported %s, not the installed package" % wavetomo.__file__
print("installed wavetomo", wavetomo.__version__, "as", wavetomo.__file__)' "$tmp/venv/")
}
if ! install > "$tmp/install.txt" 2>&1; then
  cat "$tmp/install.txt"
  echo "test_python.sh: installing the package into a virtual environment failed (are python3-venv, python3-pip," \
       "python3-setuptools and python3-wheel installed? make deps)"
  exit 1
fi
# a sanitized library (make debug-test) needs its runtimes loaded first into an interpreter built without
# them (pip ran without); the interpreter's own allocations are not the library's leaks
preload=""
if ldd "$WAVETOMO_LIB" 2>/dev/null | grep -q libasan; then
  preload="$(gcc -print-file-name=libasan.so):$(gcc -print-file-name=libubsan.so)"
  export ASAN_OPTIONS="detect_leaks=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
fi
(cd "$tmp" && LD_PRELOAD="$preload" "$tmp/venv/bin/python" -m pytest -q -rfEs -p no:cacheprovider \
   --basetemp="$tmp/t" --junitxml="$tmp/junit.xml" "$tmp/src/python/tests") > "$tmp/out.txt" 2>&1
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
cat "$tmp/install.txt" "$tmp/out.txt"
if [ -z "$summary" ]; then
  echo "test_python.sh: pytest wrote no report (exit $rc): is $PY with numpy, h5py and pytest installed (make deps)?"
  exit 1
fi
echo "$summary"
[ "$rc" = 0 ]
