# wavetomo — top-level build.  `make` installs missing Debian packages (as root), builds
# build/libwavetomo.a and bin/wavetomo.  `make test`, `make demo`, `make bench`, `make debug`.

DEB_PACKAGES := build-essential pkg-config libopenblas-dev liblapacke-dev libsuitesparse-dev \
                libhdf5-dev libfftw3-dev libconfig-dev libplplot-dev plplot-driver-cairo fonts-dejavu-core check \
                openmpi-bin libopenmpi-dev

CC      ?= gcc
PKGS    := openblas lapacke hdf5-serial fftw3 fftw3f libconfig plplot
# -march=native is opt-in (`make NATIVE=1`): a binary built on one machine must run on another, and
# the instruction set (FMA contraction) changes floating-point results, so the bit-identity reference
# tests/regress/commands.sha256 is recorded without it.
OPT     ?= -O3 -fno-math-errno
NATIVE  ?= 0
ARCH    := $(if $(filter 1,$(NATIVE)),-march=native,)
WARN    := -Wall -Wextra -Werror -Wno-unknown-pragmas -Wshadow -Wmissing-prototypes -Wstrict-prototypes
# include/: the public headers (wavetomo/*.h), which core/base/base.h includes too
CFLAGS  += -std=c11 -D_DEFAULT_SOURCE $(OPT) $(ARCH) $(WARN) -fopenmp -I. -Iinclude -I/usr/include/suitesparse
LDLIBS  += -lcholmod -lsuitesparseconfig -lm -fopenmp

BUILD   ?= build
BIN     ?= bin

CORE_SRC  := $(sort $(wildcard core/*/*.c))
CLI_SRC   := $(sort $(wildcard cli/*.c builder/*.c runtime/*.c compare/*.c))
TEST_SRC  := $(sort $(wildcard tests/test_*.c))
CORE_OBJ  := $(CORE_SRC:%.c=$(BUILD)/%.o)
CLI_OBJ   := $(CLI_SRC:%.c=$(BUILD)/%.o)
TEST_BIN  := $(TEST_SRC:tests/%.c=$(BUILD)/tests/%)
LIB       := $(BUILD)/libwavetomo.a

.PHONY: all deps test demo bench debug debug-test clean regress-commands regress-commands-update check-deps fuzz fuzz-deps
all: deps
	@$(MAKE) --no-print-directory $(BIN)/wavetomo

# Install what is missing, and nothing when everything is there (dpkg-query is the check).
deps:
	@missing=""; for p in $(DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing missing Debian packages:$$missing"; \
	  if [ "$$(id -u)" != 0 ]; then echo "error: need root to apt-get install:$$missing" >&2; exit 1; fi; \
	  export DEBIAN_FRONTEND=noninteractive; \
	  apt-get update -qq && apt-get install -y -qq --no-install-recommends $$missing >/dev/null || exit 1; \
	fi

PKG_CFLAGS = $(shell pkg-config --cflags $(PKGS))
PKG_LIBS   = $(shell pkg-config --libs $(PKGS))
# MPI (OpenMPI) only for cli/mpi.c and the executable: the library and the test suites stay MPI-free
MPI_CFLAGS = $(shell pkg-config --cflags ompi-c)
MPI_LIBS   = $(shell pkg-config --libs ompi-c)
$(BUILD)/cli/mpi.o: PKG_CFLAGS += $(MPI_CFLAGS)

# V=1 shows the full command lines
Q := $(if $(V),,@)

# Objects depend on the flags they were built with: a change of OPT, NATIVE or WARN rebuilds them.
# The text is expanded once, here: the per-directory WARN += -Wconversion below would otherwise reach the
# stamp through whichever object asks for it first and rewrite it (and rebuild everything) every time.
FLAGS_STAMP := $(BUILD)/.cflags
FLAGS_TEXT  := $(CC) $(CFLAGS)
$(FLAGS_STAMP): FORCE
	@mkdir -p $(dir $@)
	@echo '$(FLAGS_TEXT)' | cmp -s - $@ || echo '$(FLAGS_TEXT)' > $@
.PHONY: FORCE
FORCE:

# -Wconversion where the code is clean of it today (core/base, config, io, la, solve; op, model, build and
# sim are not yet: ~360 mostly int64 -> size_t index conversions)
$(BUILD)/core/base/%.o $(BUILD)/core/config/%.o $(BUILD)/core/io/%.o $(BUILD)/core/la/%.o \
$(BUILD)/core/solve/%.o $(BUILD)/core/rtc/%.o: WARN += -Wconversion

$(BUILD)/%.o: %.c $(FLAGS_STAMP)
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  CC      $<")
	$(Q)$(CC) $(CFLAGS) $(PKG_CFLAGS) -MMD -MP -c $< -o $@

$(LIB): $(CORE_OBJ)
	@mkdir -p $(dir $@)
	$(Q)rm -f $@ && ar rcs $@ $^

$(BIN)/wavetomo: $(CLI_OBJ) $(LIB)
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  LD      $@")
	$(Q)$(CC) $(CFLAGS) -o $@ $(CLI_OBJ) $(LIB) $(PKG_LIBS) $(MPI_LIBS) $(LDLIBS)

# Suites of driver-level modules link those objects too (compare/plot.c is not in the library: PLplot
# is only for the report driver).
$(BUILD)/tests/test_plot: $(BUILD)/compare/plot.o $(BUILD)/compare/plot_pupil.o

$(BUILD)/tests/%: tests/%.c tests/testutil.h tests/testmodel.h $(LIB)
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  CC/LD   $@")
	$(Q)$(CC) $(CFLAGS) $(PKG_CFLAGS) $(shell pkg-config --cflags check) -o $@ $< $(filter %.o,$^) $(LIB) \
	    $(PKG_LIBS) $(shell pkg-config --libs check) $(LDLIBS)

# The bit-identity guard of a refactor: SHA-256 of the exact per-frame commands of short closed loops of
# every reconstructor against tests/regress/commands.sha256 (tests/regress/commands.sh says how).
$(BUILD)/tests/regress_commands: tests/regress/commands.c $(LIB)
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  CC/LD   $@")
	$(Q)$(CC) $(CFLAGS) $(PKG_CFLAGS) -o $@ $< $(LIB) $(PKG_LIBS) $(LDLIBS)

regress-commands: deps
	@$(MAKE) --no-print-directory $(BIN)/wavetomo $(BUILD)/tests/regress_commands
	@BUILD=$(BUILD) BIN=$(BIN) bash tests/regress/commands.sh

regress-commands-update: deps
	@$(MAKE) --no-print-directory $(BIN)/wavetomo $(BUILD)/tests/regress_commands
	@BUILD=$(BUILD) BIN=$(BIN) bash tests/regress/commands.sh --update

# The one-way module order of docs/design.md and no include circle, from `$(CC) -MM`, and no call circle
# between the library's files, from `nm` of its objects (tests/check_deps.sh).
check-deps: deps
	@$(MAKE) --no-print-directory $(LIB)
	@CC="$(CC)" BUILD=$(BUILD) CPPFLAGS_EXTRA="-Iinclude $(PKG_CFLAGS) $(MPI_CFLAGS) -I/usr/include/suitesparse" bash tests/check_deps.sh

test: deps check-deps
	@$(MAKE) --no-print-directory $(BIN)/wavetomo $(TEST_BIN)
	@BUILD=$(BUILD) BIN=$(BIN) bash tests/run.sh $(TEST_BIN)

# The main job: MVM, PCG-3 and CG-9 side by side in closed loop on the demo system, with the report.
demo: all
	$(BIN)/wavetomo compare --config data/presets/demo.cfg --recon mvm,pcg3,cg9 --out out/demo

bench: all
	$(BIN)/wavetomo bench data/presets/eelt-mcao.cfg --sensing data/presets/eelt-mcao-diffractive.cfg

# AddressSanitizer + UBSan build in build-debug/ and bin-debug/; `make debug-test` runs the suites with it
# (UBSan findings abort, so a report fails the suite).
SAN := -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined
debug: deps
	@$(MAKE) --no-print-directory BUILD=build-debug BIN=bin-debug OPT="$(SAN)" \
	    LDLIBS="-lcholmod -lsuitesparseconfig -lm -fopenmp -fsanitize=address,undefined" bin-debug/wavetomo

# fontconfig/pango keep a process-lifetime font cache that LeakSanitizer reports when PLplot draws
debug-test: deps
	@LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp \
	$(MAKE) --no-print-directory BUILD=build-debug BIN=bin-debug OPT="$(SAN)" \
	    LDLIBS="-lcholmod -lsuitesparseconfig -lm -fopenmp -fsanitize=address,undefined" test

# libFuzzer targets of the readers (tests/fuzz, README "Fuzzing"; not part of `make test`, which needs no
# clang): the library is rebuilt with clang, coverage instrumentation, ASan and UBSan in build/fuzz/obj;
# each target runs FUZZ_SECONDS seconds on its corpus build/fuzz/corpus/NAME (seeded from build/fuzz/seeds);
# a crash, leak, UBSan report, input slower than 5 s or allocation above 512 MB is saved as
# build/fuzz/crashes/NAME-* and makes `make fuzz` fail.
FUZZ_PACKAGES := clang libclang-rt-14-dev libomp-14-dev
FUZZ_SECONDS ?= 60
FUZZ_TARGETS ?= config telemetry mvm h5_recipe
FUZZ     := $(BUILD)/fuzz
FUZZ_SAN := -O1 -g -fno-omit-frame-pointer -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined
FUZZ_LIBS = $(PKG_LIBS) -lcholmod -lsuitesparseconfig -lm -fopenmp

fuzz-deps:
	@$(MAKE) --no-print-directory DEB_PACKAGES="$(FUZZ_PACKAGES)" deps

$(FUZZ)/fuzz_%: tests/fuzz/fuzz_%.c tests/fuzz/fuzz.h $(FUZZ)/obj/libwavetomo.a
	@$(if $(V),,echo "  FUZZ/LD $@")
	$(Q)clang -std=c11 -D_DEFAULT_SOURCE -I. -Iinclude -DWT_FUZZ_ROOT='"$(CURDIR)"' $(FUZZ_SAN) -fsanitize=fuzzer $(PKG_CFLAGS) \
	    -o $@ $< $(FUZZ)/obj/libwavetomo.a $(FUZZ_LIBS)

$(FUZZ)/obj/libwavetomo.a: FORCE
	@$(MAKE) --no-print-directory BUILD=$(FUZZ)/obj CC=clang OPT="$(FUZZ_SAN)" $@

$(FUZZ)/make_seeds: tests/fuzz/make_seeds.c tests/fuzz/fuzz.h $(LIB)
	@mkdir -p $(dir $@)
	$(Q)$(CC) $(CFLAGS) $(PKG_CFLAGS) -o $@ $< $(LIB) $(PKG_LIBS) $(LDLIBS)

fuzz: deps fuzz-deps
	@$(MAKE) --no-print-directory $(BIN)/wavetomo $(FUZZ)/make_seeds $(FUZZ_TARGETS:%=$(FUZZ)/fuzz_%)
	@rm -rf $(FUZZ)/seeds $(FUZZ)/sandbox && mkdir -p $(FUZZ)/seeds/mvm $(FUZZ)/seeds/telemetry $(FUZZ)/seeds/h5_recipe \
	    $(FUZZ)/crashes && bash tests/fuzz/config_seeds.sh $(FUZZ)/sandbox $(FUZZ)/seeds/config && \
	    $(FUZZ)/make_seeds data/presets/demo.cfg $(FUZZ)/seeds && \
	    $(BIN)/wavetomo sim --config data/presets/demo.cfg --frames 2 --out $(FUZZ)/seeds/r.h5 \
	        --telemetry $(FUZZ)/seeds/telemetry/sim.h5 --force > /dev/null
	@fail=0; for t in $(FUZZ_TARGETS); do \
	  mkdir -p $(FUZZ)/corpus/$$t; rm -f $(FUZZ)/crashes/$$t-*; echo "fuzz_$$t: $(FUZZ_SECONDS) s (log $(FUZZ)/fuzz_$$t.log)"; \
	  WT_FUZZ_SANDBOX=$(CURDIR)/$(FUZZ)/sandbox LSAN_OPTIONS=suppressions=$(CURDIR)/tests/fuzz/lsan.supp:print_suppressions=0 \
	    nice -n 19 $(FUZZ)/fuzz_$$t $(CURDIR)/$(FUZZ)/corpus/$$t $(CURDIR)/$(FUZZ)/seeds/$$t \
	    -max_total_time=$(FUZZ_SECONDS) -timeout=5 -rss_limit_mb=2048 -malloc_limit_mb=512 -print_final_stats=1 \
	    -artifact_prefix=$(CURDIR)/$(FUZZ)/crashes/$$t- > $(FUZZ)/fuzz_$$t.log 2>&1 || fail=1; \
	  grep -E "^#[0-9]+.*(DONE|pulse|NEW)" $(FUZZ)/fuzz_$$t.log | tail -1; \
	  grep -E "^stat::number_of_executed_units" $(FUZZ)/fuzz_$$t.log; \
	 done; \
	 if [ -n "$$(ls $(FUZZ)/crashes)" ] || [ $$fail != 0 ]; then \
	   echo "fuzz: findings in $(FUZZ)/crashes:" >&2; ls $(FUZZ)/crashes >&2; exit 1; fi

clean:
	rm -rf build build-debug bin bin-debug

-include $(CORE_OBJ:.o=.d) $(CLI_OBJ:.o=.d)

# The diffractive LGS image bench (core/optics/spot.h): 6 E-ELT LGS sensors per frame on 2 threads.
$(BUILD)/tests/bench_spot: tests/bench_spot.c $(LIB)
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  CC/LD   $@")
	$(Q)$(CC) $(CFLAGS) $(PKG_CFLAGS) -o $@ $< $(LIB) $(PKG_LIBS) $(LDLIBS)

.PHONY: bench-spot
bench-spot: deps
	@$(MAKE) --no-print-directory $(BUILD)/tests/bench_spot
	@$(BUILD)/tests/bench_spot 2

# The diffractive NGS cost/accuracy sweep (issue 19: n_p, N, pixels, cells per pixel of the E-ELT NGS).
$(BUILD)/tests/bench_ngs: tests/bench_ngs.c $(LIB)
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  CC/LD   $@")
	$(Q)$(CC) $(CFLAGS) $(PKG_CFLAGS) -o $@ $< $(LIB) $(PKG_LIBS) $(LDLIBS)

.PHONY: bench-ngs
bench-ngs: deps
	@$(MAKE) --no-print-directory $(BUILD)/tests/bench_ngs
	@uptime; $(BUILD)/tests/bench_ngs 2
