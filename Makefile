# crom — continuous reduced-order modeling of elastic solids.
#
#   make            build every program into bin/ (crom-<stage>)
#   make test       build and run the whole test suite
#   make test SANITIZE=1   the same suite under ASan + UBSan (build-san/)
#   make demo       the built-in default run, mesh to pictures
#   make bench      timing tables (bench/)
#   make deps       install the Debian packages the build and tests need
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

.PHONY: all test check demo bench deps install uninstall clean distclean man
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

$(BUILD)/tests/test_%: $(BUILD)/tests/test_%.o $(LIBA) | $(DEPSTAMP)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

# micro-benchmarks of lib/ (not part of the suite; make bench builds and runs them)
$(BUILD)/tests/bench_%: $(BUILD)/tests/bench_%.o $(LIBA) | $(DEPSTAMP)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

# The whole suite: unit tests of lib/, then program and pipeline tests.
test: $(PROGS) $(UNIT_TESTS) | $(DEPSTAMP)
	@tests/run.sh $(BUILD) $(BINDIR)
check: test

man: $(MANPAGES)
man/%.1: $(BINDIR)/% tests/mkman.sh
	@mkdir -p man && tests/mkman.sh $< > $@

demo: $(PROGS) | $(DEPSTAMP)
	@$(MAKE) --no-print-directory -f pipelines/demo.mk BINDIR=$(abspath $(BINDIR))

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
	rm -rf build build-san man/*.1 $(patsubst bin/%.c,bin/%,$(PROG_SRC))

# clean, plus everything the experiments, the demo and the benchmarks wrote
distclean: clean
	rm -rf runs out bench/results

-include $(wildcard $(BUILD)/*/*.d $(BUILD)/*/*/*.d)
