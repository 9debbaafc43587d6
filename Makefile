# wavetomo — top-level build.  `make` installs missing Debian packages (as root), builds
# build/libwavetomo.a, build/libwavetomo.so and bin/wavetomo.  `make test`, `make demo`, `make bench`,
# `make debug`, `make install PREFIX=/usr/local DESTDIR=...`, `make uninstall`.

DEB_PACKAGES := build-essential pkg-config libopenblas-dev liblapacke-dev libsuitesparse-dev \
                libhdf5-dev libfftw3-dev libconfig-dev libcfitsio-dev libplplot-dev plplot-driver-cairo fonts-dejavu-core check \
                openmpi-bin libopenmpi-dev python3-numpy python3-h5py python3-pytest \
                python3-pip python3-setuptools python3-wheel python3-venv

CC      ?= gcc
PKGS    := openblas lapacke hdf5-serial fftw3 fftw3f libconfig cfitsio plplot
# -march=native is opt-in (`make NATIVE=1`): a binary built on one machine must run on another, and
# the instruction set (FMA contraction) changes floating-point results, so the bit-identity reference
# tests/regress/commands.sha256 is recorded without it.
OPT     ?= -O3 -fno-math-errno
NATIVE  ?= 0
ARCH    := $(if $(filter 1,$(NATIVE)),-march=native,)
WARN    := -Wall -Wextra -Werror -Wno-unknown-pragmas -Wshadow -Wmissing-prototypes -Wstrict-prototypes
# -fPIC: the same objects make libwavetomo.a and libwavetomo.so. -fno-semantic-interposition keeps the
# optimiser's freedom of a non-PIC build (inlining of the library's own global functions): nobody
# interposes them, and the shared library exports only the public API anyway (core/wavetomo.map).
PIC     := -fPIC -fno-semantic-interposition
# include/: the public headers (wavetomo/*.h), which core/base/base.h includes too
CFLAGS  += -std=c11 -D_DEFAULT_SOURCE $(OPT) $(ARCH) $(WARN) $(PIC) -fopenmp -I. -Iinclude -I/usr/include/suitesparse
LDLIBS  += -lcholmod -lsuitesparseconfig -lm -fopenmp

BUILD   ?= build
BIN     ?= bin

# The shared library (build/libwavetomo.{a,so}): the foundation core/*/ and the library part of each top
# folder (LIB_DIRS). The executable bin/wavetomo: its dispatcher (app/), the commands' shared plumbing (cli/),
# and in the top folders the commands (cmd_*.c) and compare's reports (report*.c, which draw with PLplot).
LIB_DIRS  := builder runtime sim compare
CMD_SRC   := $(wildcard $(LIB_DIRS:%=%/cmd_*.c) compare/report*.c)
CORE_SRC  := $(sort $(filter-out $(CMD_SRC),$(wildcard core/*/*.c $(LIB_DIRS:%=%/*.c))))
CLI_SRC   := $(sort $(wildcard cli/*.c app/*.c) $(CMD_SRC))
TEST_SRC  := $(sort $(wildcard tests/test_*.c))
CORE_OBJ  := $(CORE_SRC:%.c=$(BUILD)/%.o)
CLI_OBJ   := $(CLI_SRC:%.c=$(BUILD)/%.o)
TEST_BIN  := $(TEST_SRC:tests/%.c=$(BUILD)/tests/%)
LIB       := $(BUILD)/libwavetomo.a

# The version is the public header's (include/wavetomo/version.h); the soname carries the major number.
version_part = $(shell sed -n 's/^\#define WT_VERSION_$(1) \([0-9][0-9]*\).*/\1/p' include/wavetomo/version.h)
VERSION_MAJOR := $(call version_part,MAJOR)
VERSION   := $(VERSION_MAJOR).$(call version_part,MINOR).$(call version_part,PATCH)
SONAME    := libwavetomo.so.$(VERSION_MAJOR)
SHLIB     := $(BUILD)/libwavetomo.so.$(VERSION)
MAN       := $(BUILD)/wavetomo.1
PCFILE    := $(BUILD)/wavetomo.pc
# The public headers: the whole promise of the shared library (docs/c-api.md)
PUBLIC_H  := $(sort $(wildcard include/wavetomo/*.h))

.PHONY: all deps test test-run test-unit test-system demo bench debug debug-test clean regress-commands regress-commands-update check-deps fuzz fuzz-deps \
        install uninstall docs check-python-package
all: deps
	@$(MAKE) --no-print-directory $(BIN)/wavetomo $(SHLIB)

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

# -Wconversion where the code is clean of it today (core/base, config, io, la, solve; the runtime's library part;
# op, model, builder and sim are not yet: ~360 mostly int64 -> size_t index conversions)
$(BUILD)/core/base/%.o $(BUILD)/core/config/%.o $(BUILD)/core/io/%.o $(BUILD)/core/la/%.o \
$(BUILD)/core/solve/%.o $(BUILD)/runtime/rtc.o $(BUILD)/runtime/control.o: WARN += -Wconversion

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

# The shared library: the same objects, exporting only the public API (the version script; the executable
# and the tests link the archive, which keeps every symbol). -z defs: every dependency is linked in;
# --as-needed drops those the library does not use (PLplot is the report driver's).
$(SHLIB): $(CORE_OBJ) core/wavetomo.map
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  LD      $@")
	$(Q)$(CC) -shared $(CFLAGS) -Wl,-soname,$(SONAME) -Wl,--version-script=core/wavetomo.map -Wl,-z,defs \
	    -Wl,--as-needed -o $@ $(CORE_OBJ) $(PKG_LIBS) $(LDLIBS)
	$(Q)ln -sf $(notdir $@) $(BUILD)/$(SONAME) && ln -sf $(SONAME) $(BUILD)/libwavetomo.so

# The man page, from the commands' own --help (cli/man.sh; no help2man needed)
$(MAN): $(BIN)/wavetomo cli/man.sh
	@$(if $(V),,echo "  MAN     $@")
	$(Q)bash cli/man.sh $(BIN)/wavetomo $(VERSION) > $@.tmp && mv $@.tmp $@

# Suites of driver-level modules link those objects too (cli/plot.c is not in the library: PLplot
# is only for the report driver).
$(BUILD)/tests/test_plot: $(BUILD)/cli/plot.o $(BUILD)/cli/plot_maps.o $(BUILD)/cli/plot_pupil.o $(BUILD)/cli/plot_psf.o \
    $(BUILD)/cli/plot_series.o

$(BUILD)/tests/%: tests/%.c tests/testutil.h tests/testmodel.h tests/frozen_flow.h tests/tomography_fixture.h tests/config_fixture.h tests/precond_fixture.h tests/mvm_fixture.h $(LIB)
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

# make install [PREFIX=/usr/local] [DESTDIR=staging]: the C library (shared with its soname links, and
# static), the public headers, the pkg-config file, the executable, its man page, the presets and the
# data they read, the C and Python APIs' documentation and the C example, the Python package. make
# uninstall removes exactly these (and the bytecode Python may have written beside the package).
PREFIX     ?= /usr/local
BINDIR     ?= $(PREFIX)/bin
LIBDIR     ?= $(PREFIX)/lib
INCLUDEDIR ?= $(PREFIX)/include
DATADIR    ?= $(PREFIX)/share
MANDIR     ?= $(DATADIR)/man
PKGDATADIR := $(DATADIR)/wavetomo
DOCDIR     ?= $(DATADIR)/doc/wavetomo
# the Python package (python/wavetomo, ctypes over the shared library: nothing to compile) where Debian's
# interpreter looks for a prefix's modules: /usr/local/lib/python3.X/dist-packages; it finds the library
# and the executable relative to itself (docs/python-api.md). pip installs it (pyproject.toml), offline with
# Debian's setuptools and wheel, into exactly that directory: --target, because pip's --prefix follows
# Debian's scheme, which puts PREFIX/local/lib/... under any prefix. --no-deps: numpy is Debian's, and pip
# would not see it from a --target install.
PYTHON     ?= /usr/bin/python3
PYTHONDIR  ?= $(LIBDIR)/python$(shell $(PYTHON) -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null || echo 3)/dist-packages
PIP_OFFLINE := $(PYTHON) -m pip install -q --no-build-isolation --no-index --no-cache-dir --disable-pip-version-check \
               --root-user-action=ignore
PY_DIST    := wavetomo-$(VERSION).dist-info
PRESETS    := $(sort $(wildcard data/presets/*.cfg))
SODIUM     := $(sort $(wildcard data/sodium/*.txt))
ATMOSPHERE := $(sort $(wildcard data/atmosphere/*.txt))
NIGHTS     := $(sort $(wildcard data/nights/*.txt))
PC_REQUIRES := openblas lapacke hdf5-serial fftw3 fftw3f libconfig cfitsio

# the directories below the prefix are written relative to it (${prefix}/lib): `pkg-config --define-prefix`
# then finds a tree that was moved, or is still in its DESTDIR
pc_rel = $(patsubst $(PREFIX)/%,$${prefix}/%,$(1))
$(PCFILE): wavetomo.pc.in include/wavetomo/version.h Makefile
	@mkdir -p $(dir $@)
	$(Q)sed -e 's|@PREFIX@|$(PREFIX)|; s|@LIBDIR@|$(call pc_rel,$(LIBDIR))|; s|@INCLUDEDIR@|$(call pc_rel,$(INCLUDEDIR))|' \
	    -e 's|@PKGDATADIR@|$(call pc_rel,$(PKGDATADIR))|; s|@VERSION@|$(VERSION)|; s|@REQUIRES@|$(PC_REQUIRES)|' $< > $@
# always rewritten (a sed): the prefix of this install goes into it
.PHONY: $(PCFILE)

install: all
	@$(MAKE) --no-print-directory $(MAN) $(PCFILE)
	install -d $(DESTDIR)$(BINDIR) $(DESTDIR)$(LIBDIR)/pkgconfig $(DESTDIR)$(INCLUDEDIR)/wavetomo \
	    $(DESTDIR)$(MANDIR)/man1 $(DESTDIR)$(PKGDATADIR)/presets $(DESTDIR)$(PKGDATADIR)/sodium \
	    $(DESTDIR)$(PKGDATADIR)/atmosphere $(DESTDIR)$(PKGDATADIR)/nights \
	    $(DESTDIR)$(DOCDIR)/examples $(DESTDIR)$(PYTHONDIR)
	install -m 755 $(BIN)/wavetomo $(DESTDIR)$(BINDIR)/wavetomo
	install -m 755 $(SHLIB) $(DESTDIR)$(LIBDIR)/
	ln -sf $(notdir $(SHLIB)) $(DESTDIR)$(LIBDIR)/$(SONAME)
	ln -sf $(SONAME) $(DESTDIR)$(LIBDIR)/libwavetomo.so
	install -m 644 $(LIB) $(DESTDIR)$(LIBDIR)/libwavetomo.a
	install -m 644 $(PCFILE) $(DESTDIR)$(LIBDIR)/pkgconfig/wavetomo.pc
	install -m 644 $(PUBLIC_H) $(DESTDIR)$(INCLUDEDIR)/wavetomo/
	install -m 644 $(MAN) $(DESTDIR)$(MANDIR)/man1/wavetomo.1
	install -m 644 $(PRESETS) $(DESTDIR)$(PKGDATADIR)/presets/
	install -m 644 $(SODIUM) $(DESTDIR)$(PKGDATADIR)/sodium/
	install -m 644 $(ATMOSPHERE) $(DESTDIR)$(PKGDATADIR)/atmosphere/
	install -m 644 $(NIGHTS) $(DESTDIR)$(PKGDATADIR)/nights/
	install -m 644 docs/c-api.md docs/python-api.md $(DESTDIR)$(DOCDIR)/
	install -m 644 examples/rtc_loop.c examples/my-system.cfg $(DESTDIR)$(DOCDIR)/examples/
	$(PIP_OFFLINE) --no-deps --no-compile --upgrade --target $(DESTDIR)$(PYTHONDIR) $(CURDIR)
	@if [ -z "$(DESTDIR)" ] && [ "$$(id -u)" = 0 ] && command -v ldconfig >/dev/null; then ldconfig; fi

uninstall:
	rm -f $(DESTDIR)$(BINDIR)/wavetomo $(DESTDIR)$(LIBDIR)/libwavetomo.so.$(VERSION) \
	    $(DESTDIR)$(LIBDIR)/$(SONAME) $(DESTDIR)$(LIBDIR)/libwavetomo.so $(DESTDIR)$(LIBDIR)/libwavetomo.a \
	    $(DESTDIR)$(LIBDIR)/pkgconfig/wavetomo.pc $(DESTDIR)$(MANDIR)/man1/wavetomo.1 \
	    $(PUBLIC_H:include/wavetomo/%=$(DESTDIR)$(INCLUDEDIR)/wavetomo/%) \
	    $(PRESETS:data/presets/%=$(DESTDIR)$(PKGDATADIR)/presets/%) \
	    $(SODIUM:data/sodium/%=$(DESTDIR)$(PKGDATADIR)/sodium/%) \
	    $(ATMOSPHERE:data/atmosphere/%=$(DESTDIR)$(PKGDATADIR)/atmosphere/%) \
	    $(NIGHTS:data/nights/%=$(DESTDIR)$(PKGDATADIR)/nights/%) \
	    $(DESTDIR)$(DOCDIR)/c-api.md $(DESTDIR)$(DOCDIR)/python-api.md $(DESTDIR)$(DOCDIR)/examples/rtc_loop.c \
	    $(DESTDIR)$(DOCDIR)/examples/my-system.cfg
	@# the Python package: the files its RECORD lists (what pip uninstall would remove), and its bytecode
	if [ -f $(DESTDIR)$(PYTHONDIR)/$(PY_DIST)/RECORD ]; then \
	  cd $(DESTDIR)$(PYTHONDIR) && sed 's/,.*//' $(PY_DIST)/RECORD | xargs rm -f; fi
	rm -rf $(DESTDIR)$(PYTHONDIR)/wavetomo/__pycache__
	@rmdir $(DESTDIR)$(INCLUDEDIR)/wavetomo $(DESTDIR)$(PKGDATADIR)/presets $(DESTDIR)$(PKGDATADIR)/sodium \
	    $(DESTDIR)$(PKGDATADIR)/atmosphere $(DESTDIR)$(PKGDATADIR)/nights \
	    $(DESTDIR)$(PKGDATADIR) $(DESTDIR)$(DOCDIR)/examples $(DESTDIR)$(DOCDIR) $(DESTDIR)$(PYTHONDIR)/wavetomo \
	    $(DESTDIR)$(PYTHONDIR)/$(PY_DIST) \
	    2>/dev/null || true
	@if [ -z "$(DESTDIR)" ] && [ "$$(id -u)" = 0 ] && command -v ldconfig >/dev/null; then ldconfig; fi

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

# The suites, among them the Python package's pytest suite on the package pip-installed into a temporary venv
# (tests/test_python.sh reports it as a Check suite, so its tests count in the closing tally), the README's tour run as written (tests/test_tour.sh,
# reported the same way) and tests/test_install's checks of `make install` into a temporary DESTDIR made here
# (by this make, with its variables: a make run from inside a suite would not know them); the programs it
# builds against a sanitized library (make debug-test) need the sanitizers too (WT_INSTALL_CFLAGS).
# `make test` builds on every core unless given its own -j, and says how long it took (test-run is the same
# without the clock).
NPROC := $(shell nproc 2>/dev/null || echo 1)
JOBS   = $(if $(filter -j%,$(MAKEFLAGS)),,-j$(NPROC))
test:
	@start=$$(date +%s); $(MAKE) --no-print-directory $(JOBS) test-run; rc=$$?; \
	s=$$(( $$(date +%s) - start )); echo "make test took $$((s / 60)) min $$((s % 60)) s (build and suites)"; exit $$rc

test-run: deps check-deps
	@$(MAKE) --no-print-directory $(BIN)/wavetomo $(SHLIB) $(TEST_BIN)
	$(call run_installed,$(UNIT_BIN) $(SYSTEM_BIN) $(SYSTEM_SH))

# Unit suites test one module through its interface (a few end with the command that reads the module's file);
# system suites run the closed loop, the executable, the install or the documentation's commands end to end
# (docs/testing.md). `make test` runs both, the units first; these two run one kind each.
SYSTEM_SUITES := adapt badinput badinput_process bench budget cli docs docs_figures install loop mpi record regress \
                 rtc sensing
SYSTEM_BIN    := $(SYSTEM_SUITES:%=$(BUILD)/tests/test_%)
UNIT_BIN      := $(filter-out $(SYSTEM_BIN),$(TEST_BIN))
SYSTEM_SH     := tests/test_python.sh tests/test_tour.sh
test-unit: deps
	@$(MAKE) --no-print-directory $(JOBS) $(BIN)/wavetomo $(UNIT_BIN)
	@BUILD=$(BUILD) BIN=$(BIN) bash tests/run.sh $(UNIT_BIN)
test-system: deps check-deps
	@$(MAKE) --no-print-directory $(JOBS) $(BIN)/wavetomo $(SHLIB) $(SYSTEM_BIN)
	$(call run_installed,$(SYSTEM_BIN) $(SYSTEM_SH))

# tests/run.sh on the suites $(1), with `make install` done into a temporary DESTDIR for test_install
define run_installed
@d=$$(mktemp -d /tmp/wt-install.XXXXXX) && \
$(MAKE) --no-print-directory -s install DESTDIR=$$d PREFIX=/usr/local > $$d.log 2>&1 || { cat $$d.log; rm -rf $$d $$d.log; exit 1; }; \
rm -f $$d.log; BUILD=$(BUILD) BIN=$(BIN) WT_INSTALL_DESTDIR=$$d WT_INSTALL_PREFIX=/usr/local \
    WT_INSTALL_CFLAGS="$(filter -fsanitize=%,$(OPT))" bash tests/run.sh $(1); rc=$$?; \
    rm -rf $$d; exit $$rc
endef

# The Python package installed as the README says (the files of a fresh clone, pip offline into a new
# virtual environment with the system's site packages), then its pytest suite against this build: make test's
# test_python.sh alone.
check-python-package: all
	@BUILD=$(BUILD) BIN=$(BIN) bash tests/test_python.sh

# The main job: MVM, PCG-3 and CG-9 side by side in closed loop on the demo system, with the report.
demo: all
	$(BIN)/wavetomo compare --config data/presets/demo.cfg --recon mvm,pcg3,cg9 --out out/demo

# docs/config.md, the configuration reference, from the validator's own table (tests/test_docs.c checks it).
docs: all
	@bash docs/config.sh $(BIN)/wavetomo > docs/config.md.tmp && mv docs/config.md.tmp docs/config.md
	@echo "docs/config.md written from wavetomo info --keys"

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

# libFuzzer targets of the readers (tests/fuzz, docs/testing.md "Fuzzing"; not part of `make test`, which needs no
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
