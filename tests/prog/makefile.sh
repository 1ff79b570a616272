#!/usr/bin/env bash
# makefile.sh — the top-level Makefile on a machine with nothing installed.
#
# In a clean copy of the source tree (what a fresh clone holds), `make -n`
# of every target that compiles must start with the package check
# (tests/deps.sh): on a bare machine anything compiled before it fails for
# want of a compiler or of hdf5.h. Nothing is uninstalled: make -n shows the
# order in which make would run the commands. Also: a change of CFLAGS (or
# OPT, WERROR, ...) rebuilds the objects it affects, SANITIZE=1 builds
# elsewhere, install puts the manual pages it builds, the scripts and the
# schemas under PREFIX, and distclean has a recipe.
source "$(dirname "$0")/common.bash"
cd "$CROM_TOP"
# run as a user would, not as a sub-make of `make test` (whose flags and
# "Entering directory" lines would leak in)
unset MAKEFLAGS MFLAGS MAKELEVEL MAKEOVERRIDES SANITIZE WERROR CFLAGS OPT CC

src="$TMP/src"
mkdir -p "$src"
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  # tracked files and new ones not yet committed, as they are now
  git ls-files -co --exclude-standard -z | tar --null -cf - -T - 2>/dev/null | tar -xf - -C "$src"
else
  tar -cf - --exclude=./build --exclude=./build-san --exclude=./runs --exclude=./man \
    --exclude='./bin/crom-*[a-z]' . | tar -xf - -C "$src"
fi
[ -f "$src/Makefile" ] && [ -f "$src/tests/deps.sh" ] || fail "could not copy the source tree"
[ ! -e "$src/build" ] || fail "the copy already has a build/ directory"
ok

# 1. the package check is the first command of every target that builds
for t in all demo test bench install fuzz "all SANITIZE=1" "test SANITIZE=1" ""; do
  # shellcheck disable=SC2086
  (cd "$src" && make -n $t >"$TMP/n.log" 2>&1) || fail "make -n $t failed in a clean tree: $(tail -2 "$TMP/n.log")"
  first=$(head -n 1 "$TMP/n.log")
  case "$first" in
    *tests/deps.sh*) ok ;;
    *) fail "make -n $t in a clean tree starts with '$first', not the package check" ;;
  esac
done
# make fuzz builds its harnesses with clang into build-fuzz/, over a library
# compiled there with coverage, then makes the corpus and runs them
fz=$(cd "$src" && make -n fuzz FUZZ_SECONDS=3)
grep -q 'clang .*-fsanitize=fuzzer-no-link.* -c lib/io/io.c -o build-fuzz/lib/io/io.o' <<<"$fz" \
  || fail "make -n fuzz does not compile lib/ with clang -fsanitize=fuzzer-no-link into build-fuzz/"; ok
grep -q 'clang .*-fsanitize=fuzzer .*build-fuzz/libcrom.a.* -o build-fuzz/fuzz_flags' <<<"$fz" \
  || fail "make -n fuzz does not link the harnesses with -fsanitize=fuzzer"; ok
[ "$(grep -n 'tests/fuzz/corpus.sh' <<<"$fz" | cut -d: -f1)" -lt "$(grep -n 'tests/fuzz/run.sh build-fuzz 3' <<<"$fz" | cut -d: -f1)" ] \
  || fail "make -n fuzz does not make the corpus and then run the harnesses for FUZZ_SECONDS"; ok
# ... and nothing was compiled or installed by make -n
[ -z "$(find "$src" -name '*.o' -o -name '.deps-ok' | head -1)" ] || fail "make -n built something"; ok

# 2. changing the flags rebuilds; the same flags do not (the package check is
#    pretended done: the packages are on this machine, the suite runs after a build)
( cd "$src" && mkdir -p build && touch build/.deps-ok && make -s build/lib/base/err.o >/dev/null ) \
  || fail "could not compile lib/base/err.c in the copy"
( cd "$src" && make -q build/lib/base/err.o ) || fail "build/lib/base/err.o is out of date right after building it"; ok
rc=0; ( cd "$src" && make -q build/lib/base/err.o OPT=-O1 ) || rc=$?
[ $rc -eq 1 ] || fail "changing OPT does not rebuild build/lib/base/err.o (make -q exited $rc)"; ok
( cd "$src" && make -s build/lib/base/err.o OPT=-O1 >/dev/null && make -q build/lib/base/err.o OPT=-O1 ) \
  || fail "build/lib/base/err.o is out of date after rebuilding it with OPT=-O1"; ok
rc=0; ( cd "$src" && make -q build/lib/base/err.o CFLAGS='-g -O0' ) || rc=$?
[ $rc -eq 1 ] || fail "changing CFLAGS does not rebuild build/lib/base/err.o (make -q exited $rc)"; ok
san=$(cd "$src" && make -n SANITIZE=1 build-san/lib/base/err.o | grep -c 'fsanitize=address' || true)
[ "$san" -ge 1 ] || fail "SANITIZE=1 does not compile with -fsanitize=address into build-san/"; ok

# 3. distclean and install have recipes; install ships what the README names
dc=$(cd "$src" && make -n distclean)
grep -q 'rm -rf build' <<<"$dc" && grep -q 'runs' <<<"$dc" || fail "make -n distclean: '$dc'"; ok
inst=$(cd "$src" && make -n install PREFIX=/opt/crom)
for want in 'man/crom-mesh.1' 'crom-plot' 'crom-table' 'schemas/\*.md' 'share/man/man1'; do
  grep -q "$want" <<<"$inst" || fail "make -n install does not install $want"
  ok
done
# the man pages it installs are built by it (a rule makes man/%.1 from the program)
grep -q 'mkman.sh' <<<"$inst" || fail "make -n install does not build the manual pages"; ok

# 4. every manual page has one Options heading
for p in "$CROM_BINDIR"/crom-*; do
  [ -f "$p" ] && [ -x "$p" ] || continue   # build-san/bin also holds .d and .o files
  n=$("$p" --help-man | grep -ciE '^\.S[HS] +options$' || true)
  [ "$n" -eq 1 ] || fail "$(basename "$p") --help-man has $n Options headings"
  ok
done
done_checks
