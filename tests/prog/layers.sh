#!/usr/bin/env bash
# layers.sh — lib/ keeps the order of its layers (issue 13).
#
# The order is stated once, in lib/README.md ("Layers, bottom to top: ...").
# Every library file lives in lib/LAYER/, includes crom headers as
# "LAYER/name.h" and only from its own layer or the layers below; the
# headers include one another in no cycle; lib/cli/ is included by bin/ only;
# library code outside lib/cli/ prints nothing. Also: the Python checks of the
# program tests exit explicitly (an `assert` would vanish under
# PYTHONOPTIMIZE). Each violation is named, and the test fails.
set -euo pipefail
cd "${CROM_TOP:-$(dirname "$0")/../..}"

/usr/bin/python3 - <<'PYEOF'
import glob, os, re, sys

errors = []
readme = open("lib/README.md").read()
m = re.search(r"^Layers, bottom to top: (.+)$", readme, re.M)
if not m:
    sys.exit("lib/README.md does not state 'Layers, bottom to top: ...'")
order = [w.strip(" `.") for w in m.group(1).replace(",", " ").split()]
rank = {name: i for i, name in enumerate(order)}
for name in order:
    if not os.path.isdir(f"lib/{name}"):
        errors.append(f"lib/README.md names layer {name}, but lib/{name}/ does not exist")

INC = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
modules = {}   # "layer/name" -> set of included "layer/name"
for path in sorted(glob.glob("lib/**/*", recursive=True)):
    if os.path.isdir(path) or path.endswith(".md"):
        continue
    rel = os.path.relpath(path, "lib")
    parts = rel.split(os.sep)
    if len(parts) != 2 or parts[0] not in rank:
        errors.append(f"{path}: not in a layer folder (lib/LAYER/name with LAYER one of {' '.join(order)})")
        continue
    layer, fname = parts
    if not re.fullmatch(r"[a-z][a-z0-9_]*\.[ch]", fname):
        errors.append(f"{path}: not a .c or .h file")
        continue
    mod = f"{layer}/{fname}"
    deps = modules.setdefault(mod, set())
    for inc in INC.findall(open(path).read()):
        ip = inc.split("/")
        if len(ip) != 2 or ip[0] not in rank:
            errors.append(f"{path}: #include \"{inc}\" is not of the form \"LAYER/name.h\"")
            continue
        if not os.path.exists(f"lib/{inc}"):
            errors.append(f"{path}: #include \"{inc}\": no such file")
            continue
        if rank[ip[0]] > rank[layer]:
            errors.append(f"{path}: includes \"{inc}\" from the higher layer {ip[0]} ({layer} may include "
                          f"only {' '.join(order[:rank[layer] + 1])})")
        deps.add(inc)

# include cycles among headers (within a layer: across layers the order
# above already forbids them)
state = {}
def visit(m, stack):
    state[m] = 1
    for d in sorted(modules.get(m, ())):
        if state.get(d) == 1:
            cyc = stack[stack.index(d):] + [d] if d in stack else [m, d]
            errors.append("include cycle: " + " -> ".join(cyc))
        elif d not in state:
            visit(d, stack + [d])
    state[m] = 2
for m in sorted(modules):
    if m not in state:
        visit(m, [m])

# the command-line layer is the programs' side: bin/ only
for path in sorted(glob.glob("bin/*.c") + glob.glob("tests/unit/*.[ch]")):
    for inc in INC.findall(open(path).read()):
        if "/" in inc and inc.split("/")[0] in rank and not os.path.exists(f"lib/{inc}"):
            errors.append(f"{path}: #include \"{inc}\": no such file")
for path in sorted(glob.glob("lib/*/*.[ch]")):
    if path.startswith("lib/cli/"):
        continue
    for inc in INC.findall(open(path).read()):
        if inc.startswith("cli/"):
            errors.append(f"{path}: includes \"{inc}\": only bin/ uses the command-line layer")

# library code prints nothing (lib/cli/ is the programs' side)
PRINT = re.compile(r"\b(printf|puts|putchar|perror|vprintf)\s*\(|\bf(printf|puts|putc|write)\s*\(\s*(stderr|stdout)\b")
for path in sorted(glob.glob("lib/*/*.c")):
    if path.startswith("lib/cli/"):
        continue
    for n, line in enumerate(open(path), 1):
        code = line.split("//")[0]
        if PRINT.search(code):
            errors.append(f"{path}:{n}: library code prints: {line.strip()}")

# Python checks in the program tests exit explicitly
for path in sorted(glob.glob("tests/prog/*.sh")):
    for n, line in enumerate(open(path), 1):
        if re.match(r"\s*assert\b", line) or re.search(r";\s*assert\b", line):
            errors.append(f"{path}:{n}: Python assert (vanishes under PYTHONOPTIMIZE): {line.strip()}")

if errors:
    print("\n".join(errors))
    sys.exit(f"{len(errors)} layer violations")
nmod = len({m[:-2] for m in modules})
print(f"layers: {' < '.join(order)}; {nmod} modules, no upward include, no include cycle")
PYEOF
