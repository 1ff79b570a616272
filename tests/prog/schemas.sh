#!/usr/bin/env bash
# schemas.sh — keep schemas/*.md in step with the tables in lib/schema.c.
#
# For every schema in `specs[]` of lib/schema.c, schemas/<type>.md (crom/mesh ->
# mesh.md) must say `schema` = `crom/<type>`, `schema_version` = N with the
# table's version, and its tables must hold exactly the table's rows:
#   | path | dtype | shape | units | required | meaning |   same path, dtype, shape, units, required
#   | name | type | required | meaning |                     same name, type, required
# Doc paths start with '/' and write a group member as <name> where the C table
# writes '*'; shapes are written [nv, 3] for "nv,3". schemas/README.md must list
# every schema and its document, and schemas/stream.md must carry io.c's
# STREAM_VERSION. Any mismatch is named, and the test fails.
set -euo pipefail
cd "${CROM_TOP:-$(dirname "$0")/../..}"

/usr/bin/python3 - lib/schema.c lib/io.c schemas <<'EOF'
import os, re, sys

csrc, iosrc, docdir = sys.argv[1:4]
errors = []

def err(msg):
    errors.append(msg)

# ------------------------------------------------------------- the C tables
TOKEN = re.compile(r'"((?:[^"\\]|\\.)*)"|(-?\d+)|(NULL)|([A-Za-z_]\w*)|(\{)|(\})|(,)|/\*.*?\*/|//[^\n]*',
                   re.S)  # comments match as nothing, after strings (so "a/*b" stays a string)

def c_rows(body):
    """Split the body of an array initializer into rows (lists of values);
    adjacent string literals are joined, as the C compiler does."""
    rows, row, depth, last_str = [], None, 0, False
    for m in TOKEN.finditer(body):
        s, num, null, ident, lb, rb, comma = m.groups()
        if not any(g is not None for g in m.groups()):
            continue  # a comment
        if lb:
            depth += 1
            if depth == 1:
                row = []
        elif rb:
            depth -= 1
            if depth == 0:
                rows.append(row)
        elif depth == 1:
            if s is not None:
                if last_str:
                    row[-1] += s
                else:
                    row.append(s)
            elif num is not None:
                row.append(int(num))
            elif null:
                row.append(None)
            elif ident:
                row.append(ident)
        last_str = s is not None
    return [r for r in rows if r and r[0] is not None]   # drop the sentinel

src = open(csrc).read()
arrays = {}
for m in re.finditer(r'static\s+const\s+crom_schema(?:_(attr|dset))?\s+(\w+)\s*\[\s*\]\s*=\s*\{(.*?)\};',
                     src, re.S):
    arrays[m.group(2)] = (m.group(1) or 'spec', c_rows(m.group(3)))
specs = arrays.get('specs', (None, []))[1]
if len(specs) < 6:
    sys.exit(f"schemas.sh: parsed {len(specs)} schemas from {csrc}; the parser no longer "
             "understands its tables (expected specs[] rows like "
             '{"crom/mesh", 1, "summary", mesh_attrs, mesh_dsets, 0})')

# ------------------------------------------------------------ the documents
def cells(line):
    parts = re.split(r'(?<!\\)\|', line.strip())
    return [c.strip() for c in parts[1:-1]]

def plain(c):
    return c.replace('`', '').strip()

def doc_tables(text):
    """Rows of the dataset tables and of the attribute tables of a document."""
    dsets, attrs = [], []
    lines = text.split('\n')
    i = 0
    while i < len(lines):
        head = [plain(c).lower() for c in cells(lines[i])] if lines[i].startswith('|') else []
        kind = ('dset' if head[:5] == ['path', 'dtype', 'shape', 'units', 'required'] else
                'attr' if head[:3] == ['name', 'type', 'required'] else None)
        if not kind:
            i += 1
            continue
        i += 2  # header and |---| rule
        while i < len(lines) and lines[i].startswith('|'):
            (dsets if kind == 'dset' else attrs).append((i + 1, cells(lines[i])))
            i += 1
    return dsets, attrs

def norm_path(p):
    return re.sub(r'<[^>]*>', '*', plain(p)).lstrip('/')

def norm_shape(s):
    return re.sub(r'[\s\[\]`]', '', s)

def norm_req(r, where):
    r = plain(r).lower()
    if r not in ('yes', 'no'):
        err(f"{where}: required is '{r}', expected yes or no")
    return 1 if r == 'yes' else 0

def show_shape(s):
    return '[' + s.replace(',', ', ') + ']'

for row in specs:
    if len(row) != 6:
        err(f"{csrc}: cannot read specs row {row}")
        continue
    schema, version, _summary, attrs_name, dsets_name, _series = row
    short = schema.split('/', 1)[1]
    doc = os.path.join(docdir, short + '.md')
    if not os.path.exists(doc):
        err(f"{doc}: missing (lib/schema.c defines {schema} v{version})")
        continue
    text = open(doc).read()
    m = re.search(r'^`schema` = `([^`]*)`, `schema_version` = (\d+)', text, re.M)
    if not m:
        err(f"{doc}: no line '`schema` = `{schema}`, `schema_version` = {version}'")
    else:
        if m.group(1) != schema:
            err(f"{doc}: says schema {m.group(1)}, lib/schema.c has {schema}")
        if int(m.group(2)) != version:
            err(f"{doc}: says schema_version {m.group(2)}, lib/schema.c has {schema} v{version}")
    t = re.search(r'^# (\S+) v(\d+)\s*$', text, re.M)
    if not t or t.group(1) != schema or int(t.group(2)) != version:
        err(f"{doc}: title should be '# {schema} v{version}'")

    ddoc, adoc = doc_tables(text)
    # datasets
    want = {}
    for d in arrays.get(dsets_name, (None, []))[1]:
        if len(d) != 6:
            err(f"{csrc}: {dsets_name}: cannot read row {d}")
            continue
        want[d[0]] = d
    if not want:
        err(f"{csrc}: no rows parsed for {dsets_name} ({schema})")
    seen = set()
    for ln, c in ddoc:
        where = f"{doc}:{ln}"
        if len(c) < 5:
            err(f"{where}: dataset row has {len(c)} columns, expected 6")
            continue
        path = norm_path(c[0])
        if path in seen:
            err(f"{where}: /{path} is listed twice")
        seen.add(path)
        if path not in want:
            err(f"{where}: /{path} is documented but not in {dsets_name} in lib/schema.c")
            continue
        _, dtype, shape, req, units, _ = want[path]
        if plain(c[1]) != dtype:
            err(f"{where}: /{path} dtype is '{plain(c[1])}' in the doc, '{dtype}' in lib/schema.c")
        if norm_shape(c[2]) != shape:
            err(f"{where}: /{path} shape is {c[2]} in the doc, {show_shape(shape)} in lib/schema.c")
        if plain(c[3]) != units:
            err(f"{where}: /{path} units are '{plain(c[3])}' in the doc, '{units}' in lib/schema.c")
        if norm_req(c[4], where) != req:
            err(f"{where}: /{path} required is '{plain(c[4])}' in the doc, "
                f"{'yes' if req else 'no'} in lib/schema.c")
    for path in want:
        if path not in seen:
            d = want[path]
            err(f"{doc}: dataset /{path} ({d[1]} {show_shape(d[2])} {d[4]}) from {dsets_name} "
                "in lib/schema.c is not documented")
    # root attributes
    want = {}
    for a in arrays.get(attrs_name, (None, []))[1]:
        if len(a) != 4:
            err(f"{csrc}: {attrs_name}: cannot read row {a}")
            continue
        want[a[0]] = a
    seen = set()
    for ln, c in adoc:
        where = f"{doc}:{ln}"
        if len(c) < 3:
            err(f"{where}: attribute row has {len(c)} columns, expected 4")
            continue
        name = plain(c[0])
        if name in seen:
            err(f"{where}: attribute '{name}' is listed twice")
        seen.add(name)
        if name not in want:
            err(f"{where}: root attribute '{name}' is documented but not in {attrs_name} in lib/schema.c")
            continue
        _, typ, req, _ = want[name]
        if plain(c[1]) != typ:
            err(f"{where}: attribute '{name}' type is '{plain(c[1])}' in the doc, '{typ}' in lib/schema.c")
        if norm_req(c[2], where) != req:
            err(f"{where}: attribute '{name}' required is '{plain(c[2])}' in the doc, "
                f"{'yes' if req else 'no'} in lib/schema.c")
    for name in want:
        if name not in seen:
            err(f"{doc}: root attribute '{name}' ({want[name][1]}) from {attrs_name} "
                "in lib/schema.c is not documented")

# ------------------------------------------------------ README and stream.md
readme = open(os.path.join(docdir, 'README.md')).read()
for row in specs:
    schema, version = row[0], row[1]
    short = schema.split('/', 1)[1]
    if not re.search(rf'^\| `{re.escape(schema)}` \| {version} \| \[{short}\.md\]\({short}\.md\)',
                     readme, re.M):
        err(f"{docdir}/README.md: the schema table lacks the row "
            f"'| `{schema}` | {version} | [{short}.md]({short}.md) | …'")
m = re.search(r'#define\s+STREAM_VERSION\s+(\d+)', open(iosrc).read())
s = re.search(r'^- stream version: (\d+)\s*$', open(os.path.join(docdir, 'stream.md')).read(), re.M)
if not m:
    err(f"{iosrc}: no STREAM_VERSION")
elif not s or s.group(1) != m.group(1):
    err(f"{docdir}/stream.md: needs the line '- stream version: {m.group(1)}' "
        f"(STREAM_VERSION in {iosrc})")

for e in errors:
    print("schemas.sh:", e, file=sys.stderr)
if errors:
    sys.exit(f"schemas.sh: {len(errors)} mismatch(es) between schemas/ and lib/schema.c")
print(f"schemas.sh: {len(specs)} schemas in step with lib/schema.c")
EOF
