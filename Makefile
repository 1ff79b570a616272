# crom — continuous reduced-order modeling of elastic solids.
#
#   make            build every program into bin/ (crom-<stage>)
#   make test       build and run the whole test suite
#   make test SANITIZE=1   the same suite under ASan + UBSan (build-san/)
#   make demo       the built-in default run, mesh to pictures
#   make live       the demo body live in the browser (crom-live + crom-view)
#   make bench      timing tables (bench/)
#   make deps       install the Debian packages the build and tests need
#   make fuzz       libFuzzer harnesses of every reader (build-fuzz/), a seed
#                   corpus from the programs, FUZZ_SECONDS (10) per harness
#   make install PREFIX=/usr/local
#
# WERROR=1 turns warnings into errors (CI does this).
#
# lib/ is built in layers, each a folder, each including only itself and the
# layers below it: base < io < mesh < phys < nn < rom < datafree < view < cli
# (lib/README.md says what each holds; tests/prog/layers.sh keeps the order).

VERSION := 0.1.0
PREFIX  ?= /usr/local
SHELL   := /bin/bash

CC      ?= cc
OPT     ?= -O2 -march=x86-64-v2
WARN    := -Wall -Wextra -Wpedantic -Wshadow=local -Wno-unused-parameter
ifeq ($(WERROR),1)
WARN    += -Werror
endif
DEPINC  := -I/usr/include/hdf5/serial -I/usr/include/suitesparse
CPPFLAGS := -Ilib $(DEPINC) -D_DEFAULT_SOURCE -DCROM_VERSION='"$(VERSION)"'
CFLAGS  ?= -g $(OPT)
CFLAGS  += -std=c17 $(WARN) -fopenmp
# --as-needed: a program links only the libraries it calls, so the ones that
# never mesh do not load gmsh and its ~90 libraries at every start (0.29 s ->
# 0.12 s per start under ASan, where the tests start programs thousands of times)
LDFLAGS += -Wl,--as-needed
LDLIBS  := -L/usr/lib/x86_64-linux-gnu/hdf5/serial -lhdf5_hl -lhdf5 -lgmsh -lmetis \
           -lcholmod -lsuitesparseconfig -larpack -llapacke -lopenblas -lpng -lm

ifeq ($(SANITIZE),1)
BUILD   := build-san
BINDIR  := build-san/bin
CFLAGS  := -g -O1 -std=c17 $(WARN) -fopenmp -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
LDFLAGS += -fsanitize=address,undefined
else
BUILD   := build
BINDIR  := bin
endif

LIB_SRC  := $(wildcard lib/*.c lib/*/*.c)
LIB_OBJ  := $(patsubst lib/%.c,$(BUILD)/lib/%.o,$(LIB_SRC))
LIBA     := $(BUILD)/libcrom.a
PROG_SRC := $(wildcard bin/crom-*.c)
PROGS    := $(patsubst bin/%.c,$(BINDIR)/%,$(PROG_SRC))
TEST_SRC := $(wildcard tests/unit/test_*.c)
UNIT_TESTS := $(patsubst tests/unit/%.c,$(BUILD)/tests/%,$(TEST_SRC))
BENCHES  := $(patsubst tests/unit/%.c,$(BUILD)/tests/%,$(wildcard tests/unit/bench_*.c))
MANPAGES := $(patsubst bin/%.c,man/%.1,$(PROG_SRC))

.PHONY: all test check demo live bench deps install uninstall clean distclean man fuzz fuzz-build
.DELETE_ON_ERROR:

all: $(PROGS) $(MANPAGES)

# A fresh machine has no compiler and no libraries: missing Debian packages
# are installed before anything is compiled. Every rule that compiles or
# links waits for $(DEPSTAMP) (order-only), and nothing else comes first, so
# the package check is the first command of every target that builds
# (tests/prog/makefile.sh checks this with make -n in a clean clone).
# tests/deps.sh is idempotent and quick when everything is present.
DEPSTAMP := $(BUILD)/.deps-ok
$(DEPSTAMP): tests/deps.sh
	@mkdir -p $(@D) && tests/deps.sh && touch $@

# The compile and link flags in force: $(FLAGSTAMP) is rewritten (when make
# reads this file) only when they differ from the last build's, and every
# object depends on it, so changing CFLAGS, OPT, WERROR, CC ... rebuilds what
# they affect. SANITIZE=1 builds into its own tree.
FLAGSTAMP := $(BUILD)/.flags
FLAGS_NOW := $(CC) $(CPPFLAGS) $(CFLAGS) | $(LDFLAGS) $(LDLIBS)
ifneq ($(filter-out clean distclean deps uninstall,$(or $(MAKECMDGOALS),all)),)
$(shell mkdir -p $(BUILD) && { printf '%s\n' '$(subst ','\'',$(FLAGS_NOW))' | cmp -s - $(FLAGSTAMP) || printf '%s\n' '$(subst ','\'',$(FLAGS_NOW))' > $(FLAGSTAMP); })
endif

$(FLAGSTAMP): ;

$(BUILD)/lib/%.o: lib/%.c $(FLAGSTAMP) | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/bin/%.o: bin/%.c $(FLAGSTAMP) | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/tests/%.o: tests/unit/%.c $(FLAGSTAMP) | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) -Itests/unit $(CFLAGS) -MMD -MP -c $< -o $@

$(LIBA): $(LIB_OBJ)
	rm -f $@ && ar rcs $@ $^

$(BINDIR)/crom-%: $(BUILD)/bin/crom-%.o $(LIBA) | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

# MPI: crom-fitfield alone is built with -DCROM_MPI and Open MPI's flags
# (mpicc --showme:compile / --showme:link) when mpicc is found, unless MPI=0
# or SANITIZE=1 (the sanitized build stays MPI-free; tests/unit/test_fit.c
# runs the sharded training under ASan); then `mpirun -n P crom-fitfield` trains
# data-parallel. lib/ and the other programs never see MPI, and without it
# crom-fitfield is the serial program. The recipes ask for mpicc when they
# run, after the package step has installed it on a new machine (make reads
# this file before that); $(MPISTAMP) holds what was found when make read it,
# so that a change (MPI=0, mpicc installed or removed) rebuilds crom-fitfield.
MPI     ?= 1
MPI_WANTED := $(if $(filter 1,$(SANITIZE)),,$(if $(filter 0,$(MPI)),,1))
MPISTAMP := $(BUILD)/.mpi
ifneq ($(filter-out clean distclean deps uninstall,$(or $(MAKECMDGOALS),all)),)
MPI_NOW := $(if $(MPI_WANTED),$(shell command -v mpicc >/dev/null 2>&1 && mpicc --showme:compile && mpicc --showme:link))
$(shell mkdir -p $(BUILD) && { printf '%s\n' '$(MPI_WANTED) $(MPI_NOW)' | cmp -s - $(MPISTAMP) || printf '%s\n' '$(MPI_WANTED) $(MPI_NOW)' > $(MPISTAMP); })
endif
$(MPISTAMP): ;
# $(call mpi_flags,compile|link): shell text the recipe expands
mpi_flags = $(if $(MPI_WANTED),$$(if command -v mpicc >/dev/null 2>&1; then $(if $(filter compile,$(1)),echo -DCROM_MPI;) mpicc --showme:$(1); fi))
$(BUILD)/bin/crom-fitfield.o: bin/crom-fitfield.c $(FLAGSTAMP) $(MPISTAMP) | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(call mpi_flags,compile) $(CFLAGS) -MMD -MP -c $< -o $@
$(BINDIR)/crom-fitfield: $(BUILD)/bin/crom-fitfield.o $(LIBA) | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) $(call mpi_flags,link) -o $@

# crom-view: libwebsockets and a thread, and its page (bin/crom-view.html)
# compiled in as bytes (od; a string literal that long is beyond ISO C's limit)
$(BUILD)/gen/viewer_page.h: bin/crom-view.html
	@mkdir -p $(@D)
	{ echo '/* bin/crom-view.html as bytes, made by the Makefile */'; \
	  echo 'static const char crom_viewer_page[] = {'; \
	  od -An -v -tx1 $< | sed 's/ *\([0-9a-f][0-9a-f]\)/0x\1,/g'; echo '0};'; } > $@.tmp && mv $@.tmp $@
$(BUILD)/bin/crom-view.o: bin/crom-view.c $(BUILD)/gen/viewer_page.h $(FLAGSTAMP) | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) -I$(BUILD)/gen $(CFLAGS) -MMD -MP -c $< -o $@
$(BINDIR)/crom-view: $(BUILD)/bin/crom-view.o $(LIBA) | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -lwebsockets -lpthread -o $@

$(BUILD)/tests/test_%: $(BUILD)/tests/test_%.o $(LIBA) | $(DEPSTAMP)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

# micro-benchmarks of lib/ (not part of the suite; make bench builds and runs them)
$(BUILD)/tests/bench_%: $(BUILD)/tests/bench_%.o $(LIBA) | $(DEPSTAMP)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

# The whole suite: unit tests of lib/, then program and pipeline tests
# (the fuzz harnesses replay tests/fuzz/regress/ in tests/prog/fuzz_regress.sh).
test: $(PROGS) $(UNIT_TESTS) | $(DEPSTAMP)
	@CROM_SANITIZE=$(SANITIZE) tests/run.sh $(BUILD) $(BINDIR)
check: test

man: $(MANPAGES)
man/%.1: $(BINDIR)/% tests/mkman.sh
	@mkdir -p man && tests/mkman.sh $< > $@

demo: $(PROGS) | $(DEPSTAMP)
	@$(MAKE) --no-print-directory -f pipelines/demo.mk BINDIR=$(abspath $(BINDIR))

# the demo's body live in the browser (pipelines/live.mk): crom-live and crom-view
live: $(PROGS) | $(DEPSTAMP)
	@$(MAKE) --no-print-directory -f pipelines/live.mk live BINDIR=$(abspath $(BINDIR))

bench: $(PROGS) $(BENCHES) | $(DEPSTAMP)
	@$(MAKE) --no-print-directory -f pipelines/bench.mk BINDIR=$(abspath $(BINDIR)) \
	  BENCHES="$(abspath $(BENCHES))"

# Install the Debian packages the build and the tests need (idempotent,
# non-interactive, sudo only when not root).
deps:
	@tests/deps.sh

# The programs and their manual pages, the plot and table scripts the README
# mentions (as crom-plot and crom-table), the experiment Makefiles and the
# file format specs.
SHARE := $(DESTDIR)$(PREFIX)/share/crom
install: $(PROGS) $(MANPAGES) | $(DEPSTAMP)
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/share/man/man1 $(SHARE)/pipelines $(SHARE)/schemas
	install -m 755 $(PROGS) $(DESTDIR)$(PREFIX)/bin
	install -m 755 pipelines/plot.sh $(DESTDIR)$(PREFIX)/bin/crom-plot
	install -m 755 pipelines/table.sh $(DESTDIR)$(PREFIX)/bin/crom-table
	install -m 644 $(MANPAGES) $(DESTDIR)$(PREFIX)/share/man/man1
	install -m 644 pipelines/*.mk pipelines/*.py $(SHARE)/pipelines
	install -m 755 pipelines/*.sh $(SHARE)/pipelines
	install -m 644 schemas/*.md $(SHARE)/schemas

uninstall:
	rm -f $(patsubst bin/%.c,$(DESTDIR)$(PREFIX)/bin/%,$(PROG_SRC)) \
	  $(DESTDIR)$(PREFIX)/bin/crom-plot $(DESTDIR)$(PREFIX)/bin/crom-table \
	  $(patsubst man/%,$(DESTDIR)$(PREFIX)/share/man/man1/%,$(MANPAGES))
	rm -rf $(SHARE)

clean:
	rm -rf build build-san build-fuzz man/*.1 $(patsubst bin/%.c,bin/%,$(PROG_SRC))

# clean, plus everything the experiments, the demo and the benchmarks wrote
distclean: clean
	rm -rf runs out bench/results

# ------------------------------------------------------------------ fuzzing
# libFuzzer harnesses (tests/fuzz/README.md), one per reader: clang with
# ASan + UBSan over the library compiled into build-fuzz/ with coverage
# (-fsanitize=fuzzer-no-link). `make fuzz` builds them, makes a seed corpus
# with the programs (tests/fuzz/corpus.sh) and runs each harness for
# FUZZ_SECONDS; any crash, hang (FUZZ_TIMEOUT s on one input), memory over
# FUZZ_RSS_MB or leak fails it (tests/fuzz/run.sh). The same harnesses, linked
# with tests/fuzz/replay.c by the normal compiler, replay the reproducers in
# tests/fuzz/regress/ in `make test`.
FUZZ        := build-fuzz
FUZZ_CC     := clang
FUZZ_SECONDS ?= 10
FUZZ_TIMEOUT ?= 10
FUZZ_RSS_MB ?= 2048
FUZZ_SAN    := -fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer
FUZZ_CFLAGS := -g -O1 -std=c17 -Wall -Wextra -Wpedantic -Wno-unused-parameter -Wno-pass-failed -fopenmp $(FUZZ_SAN)
FUZZ_LIB_OBJ := $(patsubst lib/%.c,$(FUZZ)/lib/%.o,$(LIB_SRC))
# harness name: its source and defines (-Wl,--wrap=exit: crom_cli_parse exits)
FUZZ_NAMES  := flags atfile stl obj cloud live frames stream mesh traj samples model cubature check
FUZZSRC_flags := tests/fuzz/fuzz_flags.c
FUZZDEF_flags := -Wl,--wrap=exit
FUZZSRC_atfile := tests/fuzz/fuzz_flags.c
FUZZDEF_atfile := -DFUZZ_ATFILE -Wl,--wrap=exit
FUZZSRC_stl := tests/fuzz/fuzz_surface.c
FUZZSRC_obj := tests/fuzz/fuzz_surface.c
FUZZDEF_obj := -DFUZZ_OBJ
FUZZSRC_cloud := tests/fuzz/fuzz_cloud.c
FUZZSRC_live := tests/fuzz/fuzz_live.c
FUZZSRC_frames := tests/fuzz/fuzz_stream.c
FUZZDEF_frames := -DFUZZ_FRAMES
FUZZSRC_stream := tests/fuzz/fuzz_stream.c
FUZZSRC_mesh := tests/fuzz/fuzz_h5.c
FUZZDEF_mesh := -DFUZZ_KIND=KIND_MESH
FUZZSRC_traj := tests/fuzz/fuzz_h5.c
FUZZDEF_traj := -DFUZZ_KIND=KIND_TRAJ
FUZZSRC_samples := tests/fuzz/fuzz_h5.c
FUZZDEF_samples := -DFUZZ_KIND=KIND_SAMPLES
FUZZSRC_model := tests/fuzz/fuzz_h5.c
FUZZDEF_model := -DFUZZ_KIND=KIND_MODEL
FUZZSRC_cubature := tests/fuzz/fuzz_h5.c
FUZZDEF_cubature := -DFUZZ_KIND=KIND_CUBATURE
FUZZSRC_check := tests/fuzz/fuzz_h5.c
FUZZDEF_check := -DFUZZ_KIND=KIND_CHECK
FUZZERS     := $(patsubst %,$(FUZZ)/fuzz_%,$(FUZZ_NAMES))
FUZZ_REPLAYS := $(patsubst %,$(BUILD)/fuzz/replay_%,$(FUZZ_NAMES))
test: $(FUZZ_REPLAYS)

# the fuzz tree's flags, kept as $(FLAGSTAMP) keeps the others
FUZZ_FLAGS_NOW := $(FUZZ_CC) $(CPPFLAGS) $(FUZZ_CFLAGS) | $(LDLIBS)
ifneq ($(filter fuzz fuzz-build $(FUZZ)/%,$(MAKECMDGOALS)),)
$(shell mkdir -p $(FUZZ) && { printf '%s\n' '$(subst ','\'',$(FUZZ_FLAGS_NOW))' | cmp -s - $(FUZZ)/.flags || printf '%s\n' '$(subst ','\'',$(FUZZ_FLAGS_NOW))' > $(FUZZ)/.flags; })
endif
$(FUZZ)/.flags: ;

$(FUZZ)/lib/%.o: lib/%.c $(FUZZ)/.flags | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(FUZZ_CC) $(CPPFLAGS) $(FUZZ_CFLAGS) -fsanitize=fuzzer-no-link -MMD -MP -c $< -o $@

$(FUZZ)/libcrom.a: $(FUZZ_LIB_OBJ)
	rm -f $@ && ar rcs $@ $^

fuzz-build: $(FUZZERS)

fuzz: $(FUZZERS) $(PROGS) | $(DEPSTAMP)
	@tests/fuzz/corpus.sh $(BINDIR) $(FUZZ)/corpus
	@FUZZ_TIMEOUT=$(FUZZ_TIMEOUT) FUZZ_RSS_MB=$(FUZZ_RSS_MB) tests/fuzz/run.sh $(FUZZ) $(FUZZ_SECONDS) $(FUZZ_NAMES)

.SECONDEXPANSION:
$(FUZZ)/fuzz_%: $$(FUZZSRC_$$*) tests/fuzz/fuzz.h $(FUZZ)/libcrom.a | $(DEPSTAMP)
	$(FUZZ_CC) $(CPPFLAGS) -Itests/fuzz $(FUZZ_CFLAGS) -fsanitize=fuzzer $(FUZZDEF_$*) $< $(FUZZ)/libcrom.a $(LDLIBS) -o $@

$(BUILD)/fuzz/replay_%: $$(FUZZSRC_$$*) tests/fuzz/fuzz.h tests/fuzz/replay.c $(LIBA) | $(DEPSTAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) -Itests/fuzz $(CFLAGS) $(LDFLAGS) $(FUZZDEF_$*) $< tests/fuzz/replay.c $(LIBA) $(LDLIBS) -o $@

-include $(wildcard $(BUILD)/*/*.d $(BUILD)/*/*/*.d)
-include $(wildcard $(FUZZ)/lib/*/*.d)
