#!/usr/bin/env bash
# layers.sh — lib/ keeps the order of its layers (issue 13).
#
# The order is stated once, in lib/README.md ("Layers, bottom to top: ...").
# Every library file lives in lib/LAYER/, includes crom headers as
# "LAYER/name.h" and only from its own layer or the layers below; the
# headers include one another in no cycle; lib/cli/ is included by bin/ only;
# library code outside lib/cli/ prints nothing; every public name declared in
# lib/LAYER/name.h starts with the module's prefix (below). Also: the Python
# checks of the program tests exit explicitly (an `assert` would vanish under
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

# ------------------------------------------------------------------ prefixes
# Every public name of lib/LAYER/name.h (function, type, struct tag, macro,
# enumerator, extern variable) starts with crom_name_ / CROM_NAME_, or is
# crom_name / CROM_NAME itself, except for what is kept on purpose:
EXCEPT = {
    "base/err.h": (r"CROM_OK|CROM_E[A-Z]+|crom_(errmsg|errcode|malloc|calloc|realloc|strdup)",
                   "the error codes and checked allocation that every module uses, named like errno and malloc"),
    "io/io.h": (r"crom_(h5|in|out|fileout)(_\w+)?|CROM_OUT_\w+",
                "io.c is one module of four families (checked HDF5 calls, inputs, outputs, plain "
                "outputs) that share the temporary-file registry and the stream format"),
    "mesh/locate.h": (r"crom_locator", "the object crom_locate_* build and query: a noun, not crom_locate"),
}
def strip_c(text):
    """text without comments and string/char literals (newlines kept)"""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("/*", i):
            j = text.find("*/", i + 2); j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j])); i = j
        elif text.startswith("//", i):
            j = text.find("\n", i); j = n if j < 0 else j
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + c); i = j + 1
        else:
            out.append(c); i += 1
    return "".join(out)

KEYWORDS = set("""typedef struct union enum const volatile static extern inline void char short int long
float double signed unsigned restrict _Bool __attribute__ sizeof""".split())
TOKEN = re.compile(r"[A-Za-z_]\w*|\d[\w.]*|\S")

def public_names(text):
    """[(kind, name)] declared at file scope of a header"""
    names = []
    text = re.sub(r"\\\n", " ", strip_c(text))   # macros continued over lines
    body = []
    for line in text.split("\n"):
        m = re.match(r"\s*#\s*define\s+(\w+)(.*)", line)
        if m:
            names.append(("macro", m.group(1)))
        body.append("" if line.lstrip().startswith("#") else line)
    toks = TOKEN.findall("\n".join(body))
    decl, depth = [], 0
    def finish(d):
        if not d:
            return
        words = [t for t in d if re.fullmatch(r"[A-Za-z_]\w*", t)]
        # struct/union/enum tags that are defined here
        for k in range(len(d) - 2):
            if d[k] in ("struct", "union", "enum") and re.fullmatch(r"[A-Za-z_]\w*", d[k + 1]) and d[k + 2] == "{":
                names.append(("tag", d[k + 1]))
        # enumerators
        for k in range(len(d) - 1):
            if d[k] == "enum" and "{" in d[k:k + 3]:
                lvl, j = 0, d.index("{", k)
                expect = True
                for t in d[j:]:
                    if t == "{": lvl += 1; expect = lvl == 1; continue
                    if t == "}":
                        lvl -= 1
                        if lvl == 0: break
                        continue
                    if lvl == 1 and t == ",": expect = True; continue
                    if lvl == 1 and expect and re.fullmatch(r"[A-Za-z_]\w*", t):
                        names.append(("enumerator", t)); expect = False
        # the declared name, outside braces, brackets and (but for a
        # function pointer) parentheses
        top, lvl = [], 0
        for t in d:
            if t in "{[": lvl += 1
            elif t in "}]": lvl -= 1
            elif lvl == 0: top.append(t)
        if d[0] == "typedef":
            m = re.search(r"\( \* (\w+) \)", " ".join(top))
            if m:
                names.append(("typedef", m.group(1)))
            else:
                flat, plvl = [], 0
                for t in top:
                    if t == "(": plvl += 1
                    elif t == ")": plvl -= 1
                    elif plvl == 0: flat.append(t)
                ids = [t for t in flat if re.fullmatch(r"[A-Za-z_]\w*", t) and t not in KEYWORDS]
                if ids:
                    names.append(("typedef", ids[-1]))
            return
        plvl = 0
        for k, t in enumerate(top):
            if t == "(" and plvl == 0 and k and re.fullmatch(r"[A-Za-z_]\w*", top[k - 1]) \
                    and top[k - 1] not in KEYWORDS:
                names.append(("function", top[k - 1]))
                return
            if t == "(": plvl += 1
            elif t == ")": plvl -= 1
        ids = [t for t in top if re.fullmatch(r"[A-Za-z_]\w*", t) and t not in KEYWORDS]
        if ids and ("extern" in top or len(ids) >= 2):
            names.append(("variable", ids[-1]))
    for t in toks:
        if t == "{":
            depth += 1
        elif t == "}":
            depth -= 1
            if depth == 0 and decl and decl[0] != "typedef" and "=" not in decl and \
                    not any(w in decl for w in ("struct", "union", "enum")):
                decl.append(t); finish(decl); decl = []; continue   # a function body
        if t == ";" and depth == 0:
            finish(decl); decl = []
        else:
            decl.append(t)
    finish(decl)
    return names

nnames = 0
for path in sorted(glob.glob("lib/*/*.h")):
    mod = os.path.relpath(path, "lib")
    name = os.path.basename(path)[:-2]
    ok_rx = re.compile(rf"(crom_{name}|CROM_{name.upper()})(_\w+)?")
    exc = EXCEPT.get(mod)
    names = public_names(open(path).read())
    for kind, n in names:
        nnames += 1
        if ok_rx.fullmatch(n) or (exc and re.fullmatch(exc[0], n)):
            continue
        errors.append(f"{path}: {kind} {n} does not start with crom_{name}_ or CROM_{name.upper()}_")
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
print(f"prefixes: {nnames} public names in {len(glob.glob('lib/*/*.h'))} headers start with their module's prefix, "
      f"but for {len(EXCEPT)} headers' exceptions")
PYEOF
