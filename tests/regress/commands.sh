#!/usr/bin/env bash
# tests/regress/commands.sh: `make regress-commands`: the bit-identity guard of a refactor (issue 8 §0).
#
# Runs short closed loops on the demo preset (FRAMES frames, seed SEED) of every reconstructor — none,
# pcg3, cg9, and the MVM of `wavetomo build` for pcg3 and for cg9 (sim --matrix, then the same frames
# through `wavetomo run --matrix`) — once through the wavetomo executable with --telemetry (SHA-256 of
# the stored float32 commands / reconstructions) and once in process
# (SHA-256 of the exact float64 commands, build/tests/regress_commands), and compares the hashes with
# tests/regress/commands.sha256. One thread everywhere (OpenMP, OpenBLAS), so that the reference does not
# depend on the machine's core count. A difference must be explained (which reduction order changed
# and why) in the commit that regenerates the reference:
#
# usage: bash tests/regress/commands.sh [--update]        (from the repository root, after `make`)
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN=${BIN:-bin}/wavetomo
TOOL=${BUILD:-build}/tests/regress_commands
REF=tests/regress/commands.sha256
PRESET=data/presets/demo.cfg
FRAMES=20
SEED=1
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
COMMON=(--config "$PRESET" --frames $FRAMES --seed $SEED --threads 1 --quiet)
{
  for r in none pcg3 cg9; do
    "$BIN" sim "${COMMON[@]}" --recon $r --out "$TMP/$r.h5" --telemetry "$TMP/tel-$r.h5" >/dev/null
  done
  # the preconditioners the presets and the README use beyond the demo's jacobi_ngs: pcg3 with coarse_ngs (the
  # E-ELT preset's), cg9 with fourier on the layers' values (every layer on one grid, as it needs)
  "$BIN" sim "${COMMON[@]}" --recon pcg3 --set 'recon.pcg3.preconditioner="coarse_ngs"' --out "$TMP/pcg3-coarse.h5" \
    --telemetry "$TMP/tel-pcg3-coarse_ngs.h5" >/dev/null
  "$BIN" sim "${COMMON[@]}" --recon cg9 --set 'recon.cg9.preconditioner="fourier"' --set recon.cg9.coarse_levels=0 \
    --set 'recon.cg9.layer_spacing_m=[1.0, 1.0, 1.0, 1.0, 1.0]' --out "$TMP/cg9-fourier.h5" \
    --telemetry "$TMP/tel-cg9-fourier.h5" >/dev/null
  # cg9's MVM with its default full prior is dense (174 GB at E-ELT size): the regression keeps the sparse
  # path that fits, with the paper's prior for its matrix and loop
  for v in pcg3 cg9; do
    P=(); [ $v = cg9 ] && P=(--set 'recon.cg9.prior="paper"')
    "$BIN" build --config "$PRESET" --recon $v "${P[@]}" --threads 1 --quiet --out "$TMP/matrix-$v.h5" >/dev/null
    "$BIN" sim "${COMMON[@]}" "${P[@]}" --recon mvm --matrix "$TMP/matrix-$v.h5" --out "$TMP/mvm-$v.h5" \
      --telemetry "$TMP/tel-mvm-$v.h5" >/dev/null
    # the same frames replayed by `wavetomo run` (R s + RA a from the telemetry)
    "$BIN" run --matrix "$TMP/matrix-$v.h5" --telemetry "$TMP/tel-mvm-$v.h5" --out "$TMP/run-mvm-$v.h5" \
      --threads 1 --quiet >/dev/null
  done
  "$TOOL" tel "$TMP"/tel-none.h5 "$TMP"/tel-pcg3.h5 "$TMP"/tel-cg9.h5 "$TMP"/tel-mvm-pcg3.h5 "$TMP"/tel-mvm-cg9.h5 \
    "$TMP"/run-mvm-pcg3.h5 "$TMP"/run-mvm-cg9.h5 "$TMP"/tel-pcg3-coarse_ngs.h5 "$TMP"/tel-cg9-fourier.h5
  "$TOOL" lib "$PRESET" $FRAMES $SEED
} >"$TMP/now.txt"
if [ "${1:-}" = --update ]; then
  cp "$TMP/now.txt" "$REF"
  echo "regress-commands: wrote $REF"
  cat "$REF"
  exit 0
fi
cat "$TMP/now.txt"
if diff -u "$REF" "$TMP/now.txt"; then
  echo "regress-commands: all $(wc -l <"$REF") command hashes identical to $REF"
else
  echo "regress-commands: FAILED: the commands differ from $REF (see the diff above)" >&2
  exit 1
fi
