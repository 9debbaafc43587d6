#!/bin/bash
# tests/fuzz/config_seeds.sh SANDBOX SEEDS: the include sandbox and the seed corpus of fuzz_config
# (`make fuzz`; the sandbox holds copies of the presets, a fragment, a directory, a self-include, an
# empty file, a file with a NUL byte and a FIFO). Seeds: the presets; the demo with each --set case of the bad-input suite
# (tests/test_badinput.c, ov_cases) as "TEXT\0override\0override"; texts that @include sandbox files.
set -e
sb=$1 seeds=$2
mkdir -p "$sb/sub" "$seeds"
cp data/presets/*.cfg "$sb/"
printf 'loop = { frames = 5; rate_hz = 500.0; };\n' > "$sb/frag.cfg"
printf '@include "self.cfg"\n' > "$sb/self.cfg"
: > "$sb/empty.cfg"
printf 'a = 1;\0b = 2;\n' > "$sb/nul.cfg"
mkfifo "$sb/pipe" # nobody writes it: an @include must not wait for one
for p in data/presets/*.cfg; do cp "$p" "$seeds/preset-$(basename "$p")"; done
n=0
# each row {{"k=v"[, "k=v"]}, {...}} of ov_cases: the overrides, NUL-separated after the demo text
sed -n 's/^    {{\("[^}]*"\)}, {.*/\1/p' tests/test_badinput.c | while IFS= read -r row; do
    n=$((n + 1))
    { cat data/presets/demo.cfg
      echo "$row" | sed 's/", "/"\n"/g' | sed 's/^"\(.*\)"$/\1/' | while IFS= read -r ov; do printf '\0%s' "$ov"; done
    } > "$seeds/set-$n"
done
printf '@include "demo.cfg"\noverrides = ["loop.frames=4294967317"];\n' > "$seeds/inc-override"
printf '@include "eelt-mcao-nea20.cfg"\n' > "$seeds/inc-nested"
printf '# a comment\n@include "sub"\n' > "$seeds/inc-dir"
printf '@include "missing.cfg"\n' > "$seeds/inc-missing"
printf '@include "self.cfg"\n' > "$seeds/inc-self"
printf '@include "nul.cfg"\n' > "$seeds/inc-nul"
printf '@include "empty.cfg"\n@include "frag.cfg"\n' > "$seeds/inc-frag"
printf '@include missing.cfg\n' > "$seeds/inc-unquoted"
printf '@include "pipe"\n' > "$seeds/inc-fifo"
