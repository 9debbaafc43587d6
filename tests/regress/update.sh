#!/usr/bin/env bash
# tests/regress/update.sh: regenerate tests/regress/strehl.tsv, the closed-loop regression table that
# tests/test_regress.c checks in `make test`.
#
# For every case below: the reference values come from the case's own seed (1); the tolerances from the
# realisation scatter of the same case over seeds 1..NSEEDS (one sample standard deviation of each
# metric, floored at the printed resolution). A change of the code that moves a case by more than one
# realisation sigma on the same seed is a real change of the physics or numerics, and must be explained
# in the commit that updates this table (docs/testing.md "Regression table").
#
# usage: bash tests/regress/update.sh [NSEEDS]      (from the repository root, after `make`)
#        ONLY=id1,id2 bash tests/regress/update.sh   recompute only those cases; the other rows are kept
set -euo pipefail
cd "$(dirname "$0")/../.."
NSEEDS=${1:-8}
BIN=${BIN:-bin}/wavetomo
OUT=tests/regress/strehl.tsv
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
PRESET=data/presets/demo.cfg
FRAMES=60
SETTLE=20
LOW="lgs.wfs.nea_mas=20.0;ngs.wfs.nea_mas=0.05;lgs.sodium_fwhm_m=0.0;lgs.tt_jitter_arcsec=0.0"
P42=data/presets/eelt-mcao-nea20-42.cfg
# case id, overrides (";"-separated), recon[, preset (default $PRESET)]
CASES=(
  "none-paper||none"
  "pcg3-paper||pcg3"
  "cg9-paper||cg9"
  "mvm-paper||mvm"
  "pcg3-low|$LOW|pcg3"
  "cg9-low|$LOW|cg9"
  "mvm-low|$LOW|mvm"
  "pcg3-42||pcg3|$P42"
  "cg9-42||cg9|$P42"
)
machine="$(uname -m) $(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | sed 's/.*: //; s/ \{2,\}/ /g' | cut -c1-40)"
today=$(date -u +%F)
printf 'case\tpreset\toverrides\trecon\tframes\tsettle\tseed\tfield_sr\tonaxis_sr\tfield_wfe_nm\ttol_field_sr\ttol_onaxis_sr\ttol_wfe_nm\tdate\tmachine\tnote\n' > "$TMP/table"
for c in "${CASES[@]}"; do
  IFS='|' read -r id ov recon preset <<< "$c"
  PRE=${preset:-$PRESET}
  if [ -n "${ONLY:-}" ] && [[ ",$ONLY," != *",$id,"* ]]; then
    awk -F'\t' -v id="$id" '$1 == id' "$OUT" >> "$TMP/table"
    continue
  fi
  sets=(--set "loop.frames=$FRAMES" --set "evaluation.settle_frames=$SETTLE")
  if [ -n "$ov" ]; then IFS=';' read -ra kv <<< "$ov"; for x in "${kv[@]}"; do sets+=(--set "$x"); done; fi
  extra=()
  if [ "$recon" = mvm ]; then
    "$BIN" build --config "$PRE" "${sets[@]}" --out "$TMP/$id.M.h5" --quiet > /dev/null
    extra=(--matrix "$TMP/$id.M.h5")
  fi
  : > "$TMP/$id.vals"
  for s in $(seq 1 "$NSEEDS"); do
    "$BIN" sim --config "$PRE" "${sets[@]}" --recon "$recon" "${extra[@]}" --seed "$s" --out "$TMP/$id.$s.h5" \
      --quiet --threads 1 > "$TMP/$id.$s.txt"
    awk '/LE Strehl/ {on=$4; fa=$7} /residual WFE/ {w=$(NF-1)} END {printf "%s %s %s\n", fa, on, w}' \
      "$TMP/$id.$s.txt" >> "$TMP/$id.vals"
  done
  awk -v id="$id" -v pre="$PRE" -v ov="$ov" -v rec="$recon" -v fr="$FRAMES" -v se="$SETTLE" -v d="$today" \
      -v m="$machine" -v n="$NSEEDS" '
    { for (k = 1; k <= 3; k++) { x[NR, k] = $k; s[k] += $k; q[k] += $k * $k } }
    END {
      floor[1] = 1e-4; floor[2] = 1e-4; floor[3] = 0.1
      for (k = 1; k <= 3; k++) { mu = s[k] / NR; sd = sqrt((q[k] - NR * mu * mu) / (NR - 1)); t[k] = sd > floor[k] ? sd : floor[k] }
      printf "%s\t%s\t%s\t%s\t%d\t%d\t1\t%s\t%s\t%s\t%.4f\t%.4f\t%.1f\t%s\t%s\tseed scatter over %d seeds\n",
        id, pre, ov, rec, fr, se, x[1, 1], x[1, 2], x[1, 3], t[1], t[2], t[3], d, m, n
    }' "$TMP/$id.vals" >> "$TMP/table"
  echo "  $id: $(sed -n 1p "$TMP/$id.vals")" >&2
done
mv "$TMP/table" "$OUT"
echo "wrote $OUT" >&2
