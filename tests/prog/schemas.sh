#!/usr/bin/env bash
# schemas.sh — schemas/*.md, the table in lib/io/schema.c and the files the
# programs write say the same thing.
#
# 1. Documents against the table (`test_schema --dump` prints it). For every
#    schema, schemas/<type>.md (crom/mesh -> mesh.md) must say `schema` =
#    `crom/<type>`, `schema_version` = N with the table's version, and its
#    tables must hold exactly the table's rows, with the same words:
#      | path | dtype | shape | units | required | meaning |       by path and units
#      | name | type | required | meaning |                       root attributes, by name
#      | object | name | type | required | meaning |              other attributes
#    The meaning cell, without its backticks, is the table's meaning (which
#    every file carries as the dataset's `description`). Doc paths start with
#    '/' and write a group member as <name> where the table writes '*';
#    shapes are written [nv, 3] for "nv,3". schemas/README.md must list every
#    schema and hold the attributes of every file; schemas/stream.md must
#    carry io.c's STREAM_VERSION.
# 2. Files the programs write: every writer, every model kind, both series
#    forms. Each passes crom-info --check (which reports any dataset or
#    attribute the table lacks, and units other than the table's), and each
#    dataset's units and description are its row's, word for word — for q of
#    a data-free latent, the dimensionless row.
# 3. crom-info --check fails on an undocumented dataset, root attribute or
#    attribute of an object, on wrong units, a missing description and a
#    missing required attribute of an object.
. "$CROM_TOP/tests/prog/common.bash"
TOP=$CROM_TOP
DUMPER="${CROM_BUILD:-$TOP/build}/tests/test_schema"
[ -x "$DUMPER" ] || fail "$DUMPER is not built (make $DUMPER)"
"$DUMPER" --dump >"$TMP/table.tsv" || fail "test_schema --dump"

# ------------------------------------------------- 1. documents and the table
$PY - "$TMP/table.tsv" "$TOP/lib/io/io.c" "$TOP/schemas" <<'EOF' || fail "schemas/ and lib/io/schema.c disagree"
import os, re, sys

table, iosrc, docdir = sys.argv[1:4]
errors = []
err = errors.append

specs, dsets, attrs = [], {}, {}
for line in open(table):
    f = line.rstrip('\n').split('\t')
    if f[0] == 'schema':
        specs.append((f[1], int(f[2])))
    elif f[0] == 'dset':
        _, s, path, dtype, shape, req, units, kinds, meaning = f
        dsets.setdefault(s, []).append(dict(path=path, dtype=dtype, shape=shape, req=int(req), units=units,
                                            kinds=kinds, meaning=meaning))
    elif f[0] == 'attr':
        _, s, obj, name, typ, req, meaning = f
        attrs.setdefault(s, []).append(dict(obj=None if obj == '-' else obj, name=name, type=typ, req=int(req),
                                            meaning=meaning))
if len(specs) < 6 or '*' not in attrs:
    sys.exit(f"schemas.sh: the table dump holds {len(specs)} schemas; expected 6 and the common attributes")

def cells(line):
    parts = re.split(r'(?<!\\)\|', line.strip())
    return [c.strip() for c in parts[1:-1]]

def plain(c):
    return c.replace('`', '').replace('\\|', '|').strip()

HEADS = {('path', 'dtype', 'shape', 'units', 'required', 'meaning'): 'dset',
         ('name', 'type', 'required', 'meaning'): 'attr',
         ('object', 'name', 'type', 'required', 'meaning'): 'objattr'}

def doc_tables(text):
    """Rows of the dataset, attribute and other-attribute tables of a document."""
    out = {'dset': [], 'attr': [], 'objattr': []}
    lines = text.split('\n')
    i = 0
    while i < len(lines):
        head = tuple(plain(c).lower() for c in cells(lines[i])) if lines[i].startswith('|') else ()
        kind = HEADS.get(head)
        if not kind:
            i += 1
            continue
        i += 2  # header and |---| rule
        while i < len(lines) and lines[i].startswith('|'):
            c = cells(lines[i])
            if len(c) != len(head):
                err(f"line {i + 1}: {len(c)} cells, expected {len(head)}")
            else:
                out[kind].append((i + 1, c))
            i += 1
    return out

def norm_path(p):
    return re.sub(r'<[^>]*>', '*', plain(p)).lstrip('/')

def norm_shape(s):
    return re.sub(r'[\s\[\]`]', '', s)

def norm_req(r, where):
    r = plain(r).lower()
    if r not in ('yes', 'no'):
        err(f"{where}: required is '{r}', expected yes or no")
    return 1 if r == 'yes' else 0

def yn(r):
    return 'yes' if r else 'no'

def same_meaning(where, what, doc, tab):
    if plain(doc) != tab.replace('`', ''):
        err(f"{where}: {what}: the meaning is\n    '{plain(doc)}' in the doc,\n    '{tab}' in lib/io/schema.c")

def check_attrs(where_doc, rows, want, objects):
    """rows: (line, cells) of a doc table; want: table rows; objects: other-attribute table."""
    seen = set()
    for ln, c in rows:
        where = f"{where_doc}:{ln}"
        if objects:
            key = (norm_path(c[0]), plain(c[1]))
            typ, req, meaning = c[2], c[3], c[4]
        else:
            key = (None, plain(c[0]))
            typ, req, meaning = c[1], c[2], c[3]
        label = f"attribute '{key[1]}'" + (f" of /{key[0]}" if key[0] else "")
        if key in seen:
            err(f"{where}: {label} is listed twice")
        seen.add(key)
        row = want.get(key)
        if not row:
            err(f"{where}: {label} is documented but not in lib/io/schema.c")
            continue
        if plain(typ) != row['type']:
            err(f"{where}: {label}: type '{plain(typ)}' in the doc, '{row['type']}' in lib/io/schema.c")
        if norm_req(req, where) != row['req']:
            err(f"{where}: {label}: required '{plain(req)}' in the doc, {yn(row['req'])} in lib/io/schema.c")
        same_meaning(where, label, meaning, row['meaning'])
    for key, row in want.items():
        if key not in seen:
            err(f"{where_doc}: {'attribute' if not key[0] else 'attribute of /' + key[0]} '{key[1]}' "
                f"({row['type']}) from lib/io/schema.c is not documented")

for schema, version in specs:
    short = schema.split('/', 1)[1]
    doc = os.path.join(docdir, short + '.md')
    if not os.path.exists(doc):
        err(f"{doc}: missing (lib/io/schema.c defines {schema} v{version})")
        continue
    text = open(doc).read()
    m = re.search(r'^`schema` = `([^`]*)`, `schema_version` = (\d+)', text, re.M)
    if not m:
        err(f"{doc}: no line '`schema` = `{schema}`, `schema_version` = {version}'")
    elif m.group(1) != schema or int(m.group(2)) != version:
        err(f"{doc}: says {m.group(1)} v{m.group(2)}, lib/io/schema.c has {schema} v{version}")
    t = re.search(r'^# (\S+) v(\d+)\s*$', text, re.M)
    if not t or t.group(1) != schema or int(t.group(2)) != version:
        err(f"{doc}: title should be '# {schema} v{version}'")
    tabs = doc_tables(text)
    # datasets, by path and units (a path has a second row for other model kinds)
    want = {(d['path'], d['units']): d for d in dsets.get(schema, [])}
    seen = set()
    for ln, c in tabs['dset']:
        where = f"{doc}:{ln}"
        key = (norm_path(c[0]), plain(c[3]))
        if key in seen:
            err(f"{where}: /{key[0]} in {key[1]} is listed twice")
        seen.add(key)
        d = want.get(key)
        if not d:
            units = [u for p, u in want if p == key[0]]
            err(f"{where}: /{key[0]} in units '{key[1]}' is documented but not in lib/io/schema.c"
                + (f" (which has it in {', '.join(units)})" if units else ""))
            continue
        if plain(c[1]) != d['dtype']:
            err(f"{where}: /{key[0]}: dtype '{plain(c[1])}' in the doc, '{d['dtype']}' in lib/io/schema.c")
        if norm_shape(c[2]) != d['shape']:
            err(f"{where}: /{key[0]}: shape {c[2]} in the doc, [{d['shape']}] in lib/io/schema.c")
        if norm_req(c[4], where) != d['req']:
            err(f"{where}: /{key[0]}: required '{plain(c[4])}' in the doc, {yn(d['req'])} in lib/io/schema.c")
        same_meaning(where, f"/{key[0]}", c[5], d['meaning'])
    for key, d in want.items():
        if key not in seen:
            err(f"{doc}: dataset /{key[0]} ({d['dtype']} [{d['shape']}] {d['units']}) from lib/io/schema.c "
                "is not documented")
    a = attrs.get(schema, [])
    check_attrs(doc, tabs['attr'], {(None, r['name']): r for r in a if r['obj'] is None}, False)
    check_attrs(doc, tabs['objattr'], {(r['obj'], r['name']): r for r in a if r['obj']}, True)

readme = open(os.path.join(docdir, 'README.md')).read()
for schema, version in specs:
    short = schema.split('/', 1)[1]
    if not re.search(rf'^\| `{re.escape(schema)}` \| {version} \| \[{short}\.md\]\({short}\.md\)', readme, re.M):
        err(f"{docdir}/README.md: the schema table lacks the row '| `{schema}` | {version} | "
            f"[{short}.md]({short}.md) | …'")
if re.search(r'planned', readme + ''.join(open(os.path.join(docdir, s.split('/')[1] + '.md')).read()
                                          for s, _ in specs), re.I):
    err(f"{docdir}: a document still marks something 'planned'")
check_attrs(f"{docdir}/README.md", doc_tables(readme)['attr'], {(None, r['name']): r for r in attrs['*']}, False)
m = re.search(r'#define\s+STREAM_VERSION\s+(\d+)', open(iosrc).read())
s = re.search(r'^- stream version: (\d+)\s*$', open(os.path.join(docdir, 'stream.md')).read(), re.M)
if not m:
    err(f"{iosrc}: no STREAM_VERSION")
elif not s or s.group(1) != m.group(1):
    err(f"{docdir}/stream.md: needs the line '- stream version: {m.group(1)}' (STREAM_VERSION in {iosrc})")

for e in errors:
    print("schemas.sh:", e, file=sys.stderr)
if errors:
    sys.exit(f"schemas.sh: {len(errors)} mismatch(es) between schemas/ and lib/io/schema.c")
n = sum(len(v) for v in dsets.values()), sum(len(v) for v in attrs.values())
print(f"schemas.sh: {len(specs)} schemas, {n[0]} dataset rows and {n[1]} attribute rows in step with lib/io/schema.c")
EOF
ok

# ------------------------------------------- 2. what the programs write
cd "$TMP"
MAT=(--youngs 1e6 --poisson 0.3 --density 1000)
crom-mesh box --dims 1,0.2,0.2 --size 0.1 --region clamp='x<-0.49' --region tip='x>0.49' -o bar.h5
crom-mesh box --dims 1,0.2,0.2 --size 0.08 --region clamp='x<-0.49' -o bar2.h5
crom-remesh punch --sphere 0,0,0,0.05 -q -o punched.h5 bar.h5
SC=(--velocity 'tip=0,-2,0@0:0.04' --pin clamp --gravity 0,0,0 --dt 0.01 --steps 4)
crom-fullsim "${MAT[@]}" "${SC[@]}" -q -o full.h5 bar.h5
crom-fullsim "${MAT[@]}" "${SC[@]}" -q bar.h5 | cat >full.crs
crom-sample --points 60 full.h5 -o samp.h5
crom-sample --points all full.h5 -o samp_all.h5
crom-fitfield --rank 3 --epochs 10 -q -o mlp.h5 samp.h5
crom-fitfield --rank 3 --epochs 3 --encoder pointnet -q -o pn.h5 samp.h5
crom-fitfield --rank 3 --basis pod -q -o pod.h5 samp_all.h5
crom-modes "${MAT[@]}" --pin clamp --count 3 -q -o modes.h5 bar.h5
DF=(--steps 20 --batch 8 --width 16 -q)
crom-fitfield --objective energy --mesh bar.h5 "${MAT[@]}" --pin clamp --rank 2 "${DF[@]}" -o df.h5
crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes.h5 "${DF[@]}" -o nm.h5
crom-fitfield --objective field --mesh bar.h5 "${MAT[@]}" --pin clamp --rank 2 "${DF[@]}" -o fld.h5
crom-encode --model mlp.h5 -q -o enc.h5 <full.h5
crom-cubature --model mlp.h5 --scheme metis --count 20 -q -o cub.h5 bar.h5
crom-cubature --model mlp.h5 --scheme all -q -o cub_p.h5 punched.h5
crom-cubature --model fld.h5 --scheme metis --count 30 -q -o fldcub.h5 bar2.h5
RS=(--pin clamp --dt 0.01 --steps 4 --gravity 0,-9.81,0)
printf '2 cub_p.h5\n' >sched.txt
crom-reducedstep --cubature cub.h5 --schedule sched.txt "${MAT[@]}" "${RS[@]}" -q -o red.h5
crom-reducedstep --cubature cub.h5 "${MAT[@]}" "${RS[@]}" -q | cat >red.crs
crom-reducedstep --model df.h5 "${MAT[@]}" "${RS[@]}" -q -o red_df.h5
crom-reducedstep --model nm.h5 "${MAT[@]}" "${RS[@]}" -q -o red_nm.h5
crom-reducedstep --model fld.h5 --mesh bar2.h5 --cubature fldcub.h5 "${MAT[@]}" "${RS[@]}" -q -o red_fld.h5
crom-reducedstep --model modes.h5 --mesh bar.h5 "${MAT[@]}" "${RS[@]}" -q -o red_modes.h5
FILES=(bar.h5 punched.h5 full.h5 full.crs samp.h5 mlp.h5 pn.h5 pod.h5 modes.h5 df.h5 nm.h5 fld.h5 enc.h5
       cub.h5 fldcub.h5 red.h5 red.crs red_df.h5 red_nm.h5 red_fld.h5 red_modes.h5)
for f in "${FILES[@]}"; do
  crom-info --check "$f" >"$TMP/check.txt" || fail "crom-info --check $f: $(cat "$TMP/check.txt")"
done; ok
# the latents' q: metres for linear bases and neural modes, dimensionless for data-free maps
$PY - "$TMP/table.tsv" "${FILES[@]}" <<'EOF' || fail "files and lib/io/schema.c disagree"
import io, struct, sys, h5py
table, files = sys.argv[1], sys.argv[2:]
rows = {}
for line in open(table):
    f = line.rstrip('\n').split('\t')
    if f[0] == 'dset':
        rows.setdefault((f[1], f[2]), []).append((f[6], f[8]))
def match(pattern, path):
    p, q = pattern.split('/'), path.split('/')
    return len(p) == len(q) and all(a == '*' or a == b for a, b in zip(p, q))
def s(v):
    return v.decode() if isinstance(v, bytes) else v
def open_any(name):
    b = open(name, 'rb').read()
    if b[:8] == b'CROMSTRM':  # a frame stream: its header is an HDF5 image
        n = struct.unpack('<Q', b[16:24])[0]
        return h5py.File(io.BytesIO(b[24:24 + n]), 'r')
    return h5py.File(name, 'r')
bad, ndsets = [], 0
units_q = {}
for name in files:
    f = open_any(name)
    schema = s(f.attrs['schema'])
    def visit(path, obj):
        global ndsets
        if not isinstance(obj, h5py.Dataset):
            return
        ndsets += 1
        cand = [r for (sc, pat), rs in rows.items() if sc == schema and match(pat, path) for r in rs]
        got = (s(obj.attrs.get('units')), s(obj.attrs.get('description')))
        if got not in cand:
            bad.append(f"{name}: /{path} has units {got[0]!r}, description {got[1]!r}; lib/io/schema.c: {cand}")
        if path == 'frames/q':
            units_q[name] = got[0]
    f.visititems(visit)
want_q = {'enc.h5': 'm', 'red.h5': 'm', 'red.crs': 'm', 'red_nm.h5': 'm', 'red_modes.h5': 'm',
          'red_df.h5': '1', 'red_fld.h5': '1'}
for k, v in want_q.items():
    if units_q.get(k) != v:
        bad.append(f"{k}: q in {units_q.get(k)!r}, expected {v!r}")
for b in bad:
    print(b, file=sys.stderr)
if bad or ndsets < 150:
    sys.exit(f"{len(bad)} datasets differ from lib/io/schema.c ({ndsets} checked)")
print(f"{ndsets} datasets in {len(files)} files carry the units and descriptions of lib/io/schema.c")
EOF
ok

# ------------------------------------------- 3. --check reports what is not in the table
breaks=(
  "f.attrs['colour'] = 'red'|root attribute 'colour' is not in the crom/mesh table"
  "f['normals'] = f['vertices'][()]|dataset /normals is not in the crom/mesh table"
  "f['vertices'].attrs['units'] = 'mm'|/vertices has units 'mm', expected 'm'"
  "del f['tets'].attrs['description']|/tets has no description"
  "f['regions/clamp'].attrs['colour'] = 'red'|attribute 'colour' of /regions/clamp is not in the crom/mesh table"
  "del f['regions/clamp'].attrs['source']|/regions/clamp has no attribute 'source'"
  "f['vertices'].attrs['pretty'] = 1|attribute 'pretty' of /vertices is not in the crom/mesh table"
)
for b in "${breaks[@]}"; do
  cp bar.h5 broken.h5
  $PY -c "import h5py; f = h5py.File('broken.h5', 'r+'); ${b%%|*}" || fail "cannot break: ${b%%|*}"
  rc=0; crom-info --check broken.h5 >"$TMP/check.txt" 2>/dev/null || rc=$?
  [ $rc -eq 65 ] || fail "crom-info --check after '${b%%|*}' exited $rc, expected 65"
  grep -qF "${b#*|}" "$TMP/check.txt" || fail "crom-info --check after '${b%%|*}': $(cat "$TMP/check.txt")"
  [ "$(grep -c . "$TMP/check.txt")" -eq 1 ] || fail "one violation expected: $(cat "$TMP/check.txt")"
  ok
done
done_checks
