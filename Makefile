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

LIB_SRC  := $(wildcard lib/*.c)
LIB_OBJ  := $(patsubst lib/%.c,$(BUILD)/lib/%.o,$(LIB_SRC))
LIBA     := $(BUILD)/libcrom.a
PROG_SRC := $(wildcard bin/crom-*.c)
PROGS    := $(patsubst bin/%.c,$(BINDIR)/%,$(PROG_SRC))
TEST_SRC := $(wildcard tests/unit/test_*.c)
TESTS    := $(patsubst tests/unit/%.c,$(BUILD)/tests/%,$(TEST_SRC))
MANPAGES := $(patsubst bin/%.c,man/%.1,$(PROG_SRC))

.PHONY: all test check demo bench deps install clean distclean man
.DELETE_ON_ERROR:
.SECONDARY:

all: $(PROGS) $(MANPAGES)

# Missing Debian packages are installed before the first compile (tests/deps.sh
# is idempotent and quick when everything is present).
DEPSTAMP := $(BUILD)/.deps-ok
$(DEPSTAMP): tests/deps.sh
	@mkdir -p $(BUILD) && tests/deps.sh && touch $@
$(LIB_OBJ) $(PROGS) $(TESTS): | $(DEPSTAMP)

$(BUILD)/lib/%.o: lib/%.c | $(BUILD)/lib
	$(CC) $(CPPFLAGS) $(CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/bin/%.o: bin/%.c | $(BUILD)/bin
	$(CC) $(CPPFLAGS) $(CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/tests/%.o: tests/unit/%.c | $(BUILD)/tests
	$(CC) $(CPPFLAGS) -Itests/unit $(CFLAGS) -MMD -MP -c $< -o $@

$(LIBA): $(LIB_OBJ)
	rm -f $@ && ar rcs $@ $^

$(BINDIR)/crom-%: $(BUILD)/bin/crom-%.o $(LIBA) | $(BINDIR)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

$(BUILD)/tests/test_%: $(BUILD)/tests/test_%.o $(LIBA)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

# micro-benchmarks of lib/ (not part of the suite; make bench runs them)
$(BUILD)/tests/bench_%: $(BUILD)/tests/bench_%.o $(LIBA)
	$(CC) $(CFLAGS) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

$(BUILD)/lib $(BUILD)/bin $(BUILD)/tests:
	mkdir -p $@
ifneq ($(BINDIR),$(BUILD)/bin)
$(BINDIR):
	mkdir -p $@
endif

# The whole suite: unit tests of lib/, then program and pipeline tests.
test: $(PROGS) $(TESTS) | $(DEPSTAMP)
	@tests/run.sh $(BUILD) $(BINDIR)
check: test

man: $(MANPAGES)
man/%.1: $(BINDIR)/%
	@mkdir -p man && tests/mkman.sh $< > $@

demo: $(PROGS) | $(DEPSTAMP)
	@$(MAKE) --no-print-directory -f pipelines/demo.mk BINDIR=$(abspath $(BINDIR))

bench: $(PROGS)
	@$(MAKE) --no-print-directory -f pipelines/bench.mk BINDIR=$(abspath $(BINDIR))

# Install the Debian packages the build and the tests need (idempotent,
# non-interactive, sudo only when not root).
deps:
	@tests/deps.sh

install: $(PROGS)
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/share/man/man1
	install -m 755 $(PROGS) $(DESTDIR)$(PREFIX)/bin
	install -m 644 man/*.1 $(DESTDIR)$(PREFIX)/share/man/man1

clean:
	rm -rf build build-san man/*.1 $(patsubst bin/%.c,bin/%,$(PROG_SRC))

-include $(wildcard $(BUILD)/*/*.d)
