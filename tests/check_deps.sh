#!/usr/bin/env bash
# tests/check_deps.sh: `make check-deps` (part of `make test`): the one-way module order of docs/design.md,
# checked from the compiler's own dependency lists (gcc -MM), and no include circle between files.
#
#   base ← config        (the configuration layer: libconfig text -> wt_config, the schema)
#   base ← io            (the file layer: HDF5, plain data only, no configuration, no numerical module)
#   base ← la ← op ← solve ← model ← {builder, runtime ← sim ← compare}   (the library: core/*/, then the top folders)
#   base ← la ← optics   (diffractive sensing: sodium profile, spot images, centroiders, their noise)
#   solve and above may use config and io; model and above may use optics.
#   the executable: cli (the commands' shared plumbing, over core/ only) ← driver (the commands: every cmd_*.c,
#   compare's reports report*.c) ← app (main's dispatcher and its inspection commands)
#   public (include/wavetomo/*.h: the installed headers) ← every module; they include only each other
#
# Every source and header of the library and the executable is passed to `$CC -MM`; every project file in its
# (transitive) dependency list must belong to its own module or one the table below allows. Circles:
# the direct #include edges between files (and between modules) go through tsort, which refuses a loop;
# so do the calls between the library's object files (nm: a symbol one file uses and another defines), and
# each of those calls, like each call between the executable's objects, must go to a module the table allows.
# No .c, .h or .inc of the library over 800 lines (WT_MAX_LINES).
set -uo pipefail
cd "$(dirname "$0")/.."
CC=${CC:-gcc}
CPPFLAGS_EXTRA=${CPPFLAGS_EXTRA:-}
declare -A ALLOW=(
  [public]="public"
  [base]="public base"
  [config]="public base config"
  [io]="public base io"
  [la]="public base la"
  [op]="public base la op"
  [solve]="public base la op config io solve"
  [optics]="public base la optics"
  [model]="public base la op config io solve optics model"
  [builder]="public base la op config io solve optics model builder"
  [runtime]="public base la op config io solve optics model runtime"
  [sim]="public base la op config io solve optics model runtime sim"
  [compare]="public base la op config io solve optics model runtime sim compare"
  [cli]="public base la op config io solve optics model cli"
  [driver]="public base la op config io solve optics model builder runtime sim compare cli driver"
  [app]="public base la op config io solve optics model builder runtime sim compare cli driver app"
)
# the top folders: each holds a library part and its commands (cmd_*.c; compare's reports, report*.c)
LIB_DIRS="builder runtime sim compare"
module() { # path relative to the root -> module name
  case "$1" in
    include/wavetomo/*) echo public ;;
    core/*/*) local m=${1#core/}; echo "${m%%/*}" ;;
    cli/*) echo cli ;;
    app/*) echo app ;;
    */cmd_* | compare/report*) echo driver ;;
    */*) local d=${1%%/*}
         case " $LIB_DIRS " in *" $d "*) echo "$d"; return ;; esac
         echo external ;;
    *) echo external ;;
  esac
}
DIRS="cli app $LIB_DIRS"
# the library's sources (core/*/ and the library parts of LIB_DIRS) and the executable's
LIB_C=$(for c in core/*/*.c $(for d in $LIB_DIRS; do echo $d/*.c; done); do [ "$(module "$c")" = driver ] || echo "$c"; done | tr '\n' ' ')
EXE_C=$(for d in $DIRS; do for c in $d/*.c; do case " $LIB_C " in *" $c "*) ;; *) echo "$c" ;; esac; done; done)
bad=0
files=$(ls include/wavetomo/*.h core/*/*.c core/*/*.h $(for d in $DIRS; do echo $d/*.c $d/*.h; done) 2>/dev/null)
for f in $files; do
  mf=$(module "$f")
  [ -n "${ALLOW[$mf]:-}" ] || { echo "check-deps: $f: unknown module '$mf'"; bad=1; continue; }
  deps=$($CC -MM -std=c11 -D_DEFAULT_SOURCE -I. $CPPFLAGS_EXTRA "$f" 2>&1) || { echo "check-deps: $CC -MM $f failed: $deps"; bad=1; continue; }
  rels=$(echo "$deps" | tr -d '\\' | tr ' ' '\n' | grep -v ':$' | grep -v '^$' | grep -v '^/' | xargs -r realpath -m --relative-to=.)
  for rel in $rels; do
    [ "$rel" = "$f" ] && continue
    md=$(module "$rel")
    [ "$md" = external ] && continue
    case " ${ALLOW[$mf]} " in
      *" $md "*) ;;
      *) echo "check-deps: $f ($mf) depends on $rel ($md): against the order of docs/design.md"; bad=1 ;;
    esac
  done
done
# direct include edges, file level and module level, through tsort (a loop is an error)
edges=$(for f in $files; do
  for i in $(grep -o '^#include "[^"]*"' "$f" | sed 's/#include "//; s/"$//'); do
    if [ -e "$(dirname "$f")/$i" ]; then t=$(realpath -m --relative-to=. "$(dirname "$f")/$i")
    elif [ -e "include/$i" ]; then t=include/$i; else t=$i; fi
    echo "$f $t"
  done
done)
if ! echo "$edges" | tsort >/dev/null 2>/tmp/check_deps.$$; then
  echo "check-deps: include circle between files:"; cat /tmp/check_deps.$$; bad=1
fi
medges=$(echo "$edges" | while read -r a b; do ma=$(module "$a"); mb=$(module "$b"); [ "$ma" != "$mb" ] && [ "$mb" != external ] && echo "$ma $mb"; done | sort -u)
if [ -n "$medges" ] && ! echo "$medges" | tsort >/dev/null 2>/tmp/check_deps.$$; then
  echo "check-deps: circle between modules:"; cat /tmp/check_deps.$$; bad=1
fi
# calls between the object files of the library (nm): a function of one file calling into another and
# back is one module in two files (STYLE.md); the file-level call graph must go through tsort too. A
# function cloned per CPU (WT_CPU_CLONES) is defined as an indirect function (nm's "i"): it counts too.
OBJ=$(for c in $LIB_C; do o=${BUILD:-build}/${c%.c}.o; [ -f "$o" ] && echo "$o"; done)
if [ -n "$OBJ" ]; then
  defs=$(nm -A --defined-only $OBJ 2>/dev/null | awk '$2 ~ /^[TDRBi]$/ {split($1, a, ":"); print a[1], $3}')
  cedges=$(nm -A -u $OBJ 2>/dev/null | awk '{split($1, a, ":"); print a[1], $NF}' |
    awk 'NR == FNR {def[$2] = $1; next} ($2 in def) && def[$2] != $1 {print $1, def[$2]}' <(echo "$defs") - | sort -u)
  if [ -n "$cedges" ] && ! echo "$cedges" | tsort >/dev/null 2>/tmp/check_deps.$$; then
    echo "check-deps: call circle between files of the library:"; cat /tmp/check_deps.$$; bad=1
  fi
  # and each call goes to a module the table allows (a declaration written by hand includes nothing)
  while read -r a b; do
    [ -n "$a" ] || continue
    ma=$(module "${a#${BUILD:-build}/}"); mb=$(module "${b#${BUILD:-build}/}")
    case " ${ALLOW[$ma]} " in
      *" $mb "*) ;;
      *) echo "check-deps: ${a#${BUILD:-build}/} ($ma) calls into ${b#${BUILD:-build}/} ($mb): a call running back up"; bad=1 ;;
    esac
  done <<< "$cedges"
else
  echo "check-deps: the library (${BUILD:-build}/core) not built, call circles not checked"
fi
# calls between the executable's objects (cli, drivers, app) and into them: each must go to a module the
# table allows (the dispatcher above the commands, the plumbing below them: no call runs back up)
DOBJ=$(for c in $EXE_C; do o=${BUILD:-build}/${c%.c}.o; [ -f "$o" ] && echo "$o"; done)
if [ -n "$DOBJ" ]; then
  ddefs=$(nm -A --defined-only $DOBJ 2>/dev/null | awk '$2 ~ /^[TDRBi]$/ {split($1, a, ":"); print a[1], $3}')
  dedges=$(nm -A -u $DOBJ 2>/dev/null | awk '{split($1, a, ":"); print a[1], $NF}' |
    awk 'NR == FNR {def[$2] = $1; next} ($2 in def) && def[$2] != $1 {print $1, def[$2], $2}' <(echo "$ddefs") - | sort -u)
  while read -r a b name; do
    [ -n "$a" ] || continue
    ma=$(module "${a#${BUILD:-build}/}"); mb=$(module "${b#${BUILD:-build}/}")
    case " ${ALLOW[$ma]} " in
      *" $mb "*) ;;
      *) echo "check-deps: ${a#${BUILD:-build}/} ($ma) calls $name of ${b#${BUILD:-build}/} ($mb): a call running back up"; bad=1 ;;
    esac
  done <<< "$dedges"
fi
# STYLE.md's size rule: a library file over WT_MAX_LINES lines is usually two modules (split it by responsibility)
WT_MAX_LINES=${WT_MAX_LINES:-800}
for f in core/*/*.c core/*/*.h core/*/*.inc $(for d in $LIB_DIRS; do echo $d/*.c $d/*.h $d/*.inc; done); do
  [ -e "$f" ] || continue
  [ "$(module "$f")" = driver ] && continue
  n=$(wc -l < "$f")
  if [ "$n" -gt "$WT_MAX_LINES" ]; then
    echo "check-deps: $f has $n lines, over $WT_MAX_LINES: split it by responsibility (STYLE.md)"; bad=1
  fi
done
rm -f /tmp/check_deps.$$
if [ $bad = 0 ]; then echo "check-deps: $(echo "$files" | wc -w) files follow public ← base ← la ← op ← solve ← model ← {builder, runtime ← sim ← compare}; cli ← drivers ← app; config and io on base only; no include or call circle, no call running back up, no library file over $WT_MAX_LINES lines"; fi
exit $bad
