/* validate.c — the checker behind `crom-info --check` (see validate.h): a
 * file against the table of its type in schema.c. */
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "io/schema.h"
#include "mesh/mesh.h"
#include "rom/cubature.h"
#include "rom/model.h"
#include "rom/result.h"
#include "rom/samples.h"
#include "view/validate.h"

#define MAX_SYM 32
typedef struct {
    char name[MAX_SYM][16];
    long long val[MAX_SYM];
    int n;
    FILE *report;
    int violations;
    const char *file;
    const crom_schema *s;
    hsize_t filesize;   /* bytes of the file (or image): no dataset stores more */
    int oversized;      /* a dataset declares more than the file holds: read nothing more */
} ctx;

static void violation(ctx *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void violation(ctx *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    if (c->report) {
        fprintf(c->report, "%s: ", c->file);
        vfprintf(c->report, fmt, ap);
        fputc('\n', c->report);
    }
    va_end(ap);
    c->violations++;
}

/* Bind or compare a dimension symbol. Returns 0 if consistent. */
static int sym(ctx *c, const char *s, long long v, long long *expected)
{
    for (int i = 0; i < c->n; i++)
        if (!strcmp(c->name[i], s)) {
            *expected = c->val[i];
            return c->val[i] == v ? 0 : -1;
        }
    if (c->n < MAX_SYM) {
        snprintf(c->name[c->n], sizeof c->name[0], "%s", s);
        c->val[c->n++] = v;
    }
    return 0;
}

/* Deflate, the strongest filter HDF5 ships, shrinks data at most about
 * 1032:1: a filtered dataset that declares more than this many times what it
 * stores cannot be real. */
#define MAX_FILTER_RATIO 1032.0
/* Values read at once when scanning a dataset (8 MB of doubles). */
#define SCAN_VALUES ((hsize_t)1 << 20)

/* 1 if dataset ds (n values of esize bytes in the file) can be what the file
 * holds: its stored bytes (at most the file's size) cover the declared
 * extent. Otherwise a violation, and nothing may be allocated from it. */
static int storage_ok(ctx *c, hid_t ds, const char *path, hsize_t n, size_t esize)
{
    hsize_t stored = H5Dget_storage_size(ds);
    if (c->filesize > 0 && stored > c->filesize)
        stored = c->filesize;
    hid_t dcpl = H5Dget_create_plist(ds);
    int filtered = dcpl >= 0 && H5Pget_nfilters(dcpl) > 0;
    if (dcpl >= 0)
        H5Pclose(dcpl);
    if ((double)n * (double)esize <= (double)stored * (filtered ? MAX_FILTER_RATIO : 1.0))
        return 1;
    violation(c, "/%s declared %llu values but the file stores only %llu bytes", path, (unsigned long long)n,
              (unsigned long long)stored);
    c->oversized = 1;
    return 0;
}

/* Every value of the float dataset ds finite, read SCAN_VALUES at a time
 * along its first dimension. */
static void scan_finite(ctx *c, hid_t ds, hid_t sp, const char *path, int rank, const hsize_t *dims)
{
    hsize_t row = 1;
    for (int k = 1; k < rank; k++)
        row *= dims[k];
    hsize_t nrows = rank > 0 ? dims[0] : 1, step = row >= SCAN_VALUES ? 1 : SCAN_VALUES / row;
    if (!row || !nrows)
        return;
    double *buf = malloc(sizeof(double) * (size_t)(row * (step < nrows ? step : nrows)));
    if (!buf) {
        violation(c, "/%s cannot be read: out of memory", path);
        return;
    }
    for (hsize_t r0 = 0; r0 < nrows; r0 += step) {
        hsize_t cnt = nrows - r0 < step ? nrows - r0 : step;
        hsize_t start[8] = {0}, count[8];
        for (int k = 0; k < rank; k++)
            count[k] = dims[k];
        start[0] = r0;
        count[0] = cnt;
        hsize_t nmem = cnt * row;
        hid_t mem = H5Screate_simple(1, &nmem, NULL);
        herr_t e = rank > 0 ? H5Sselect_hyperslab(sp, H5S_SELECT_SET, start, NULL, count, NULL) : 0;
        if (e < 0 || mem < 0 || H5Dread(ds, H5T_NATIVE_DOUBLE, rank > 0 ? mem : H5S_ALL,
                                        rank > 0 ? sp : H5S_ALL, H5P_DEFAULT, buf) < 0) {
            if (mem >= 0)
                H5Sclose(mem);
            violation(c, "/%s cannot be read (corrupt?)", path);
            break;
        }
        H5Sclose(mem);
        hsize_t i = 0;
        while (i < nmem && isfinite(buf[i]))
            i++;
        if (i < nmem) {
            violation(c, "/%s has a non-finite value at flat index %llu", path, (unsigned long long)(r0 * row + i));
            break;
        }
    }
    free(buf);
}

static void check_dset(ctx *c, hid_t root, const char *path, const crom_schema_dset *d)
{
    if (!crom_h5_has(root, path)) {
        if (d->required)
            violation(c, "missing dataset /%s (%s)", path, d->meaning);
        return;
    }
    hid_t ds = H5Dopen2(root, path, H5P_DEFAULT);
    if (ds < 0) {
        violation(c, "/%s is not a dataset", path);
        return;
    }
    hid_t t = H5Dget_type(ds), sp = H5Dget_space(ds);
    H5T_class_t cls = H5Tget_class(t);
    size_t sz = H5Tget_size(t);
    const char *want = d->type;
    int ok = (!strcmp(want, "f64") && cls == H5T_FLOAT && sz == 8) ||
             (!strcmp(want, "f32") && cls == H5T_FLOAT && sz == 4) ||
             (!strcmp(want, "i32") && cls == H5T_INTEGER && sz == 4);
    if (!ok)
        violation(c, "/%s has the wrong type (expected %s)", path, want);
    hsize_t dims[8];
    int rank = H5Sget_simple_extent_ndims(sp);
    if (rank < 0 || rank > 8 || H5Sget_simple_extent_dims(sp, dims, NULL) < 0) {
        violation(c, "/%s has an unreadable shape (corrupt?)", path);
        c->oversized = 1;
        goto done;
    }
    /* split the shape spec */
    char spec[64], *save = NULL;
    snprintf(spec, sizeof spec, "%s", d->shape);
    int k = 0;
    for (char *tok = strtok_r(spec, ",", &save); tok; tok = strtok_r(NULL, ",", &save), k++) {
        if (k >= rank)
            continue;
        if (!strcmp(tok, "?"))
            continue;
        char *end;
        long long lit = strtoll(tok, &end, 10);
        long long expected;
        if (!*end) {
            if ((long long)dims[k] != lit)
                violation(c, "/%s dimension %d is %llu, expected %lld", path, k,
                          (unsigned long long)dims[k], lit);
        } else if (sym(c, tok, (long long)dims[k], &expected)) {
            violation(c, "/%s dimension %d (%s) is %llu, but %s = %lld elsewhere in the file", path,
                      k, tok, (unsigned long long)dims[k], tok, expected);
        }
    }
    if (k != rank)
        violation(c, "/%s has rank %d, expected %d (%s)", path, rank, k, d->shape);
    /* what it declares must fit in what the file stores, before anything is
     * allocated from it; then its values must be finite */
    hssize_t n = H5Sget_simple_extent_npoints(sp);
    if (n < 0 || !storage_ok(c, ds, path, (hsize_t)n, sz ? sz : 1))
        goto done;
    if (ok && cls == H5T_FLOAT)
        scan_finite(c, ds, sp, path, rank, dims);
done:
    H5Sclose(sp);
    H5Tclose(t);
    H5Dclose(ds);
}

/* Attribute a of object `obj` ("." for the root): present if required, of its type. */
static void check_attr(ctx *c, hid_t root, const char *obj, const crom_schema_attr *a)
{
    const char *on = strcmp(obj, ".") ? obj : NULL;
    if (!crom_h5_has_attr(root, obj, a->name)) {
        if (a->required && on)
            violation(c, "/%s has no attribute '%s' (%s)", on, a->name, a->meaning);
        else if (a->required)
            violation(c, "missing root attribute '%s' (%s)", a->name, a->meaning);
        return;
    }
    char where[300];
    if (on)
        snprintf(where, sizeof where, "attribute '%s' of /%s", a->name, on);
    else
        snprintf(where, sizeof where, "root attribute '%s'", a->name);
    if (!strcmp(a->type, "str")) {
        char *s = NULL;
        if (crom_h5_get_str(root, obj, a->name, &s))
            violation(c, "%s is not a string", where);
        free(s);
    } else {
        int n = 1;
        const char *br = strchr(a->type, '[');
        if (br)
            n = atoi(br + 1);
        double v[16];
        if (n > 16 || crom_h5_get_f64(root, obj, a->name, v, n))
            violation(c, "%s is not %s", where, a->type);
        else
            for (int i = 0; i < n; i++)
                if (!isfinite(v[i]))
                    violation(c, "%s is not finite", where);
    }
    crom_err_clear();
}

/* ------------------------------------------------ nothing undocumented */

typedef struct {
    ctx *c;
    const char *path;     /* the object's path, "." for the root */
    int dataset;
} attr_walk;

static herr_t attr_cb(hid_t loc, const char *name, const H5A_info_t *info, void *data)
{
    (void)loc;
    (void)info;
    attr_walk *w = data;
    const char *obj = strcmp(w->path, ".") ? w->path : NULL;
    if (w->dataset && (!strcmp(name, "units") || !strcmp(name, "description")))
        return 0;
    if (crom_schema_attr_find(w->c->s, obj, name))
        return 0;
    if (obj)
        violation(w->c, "attribute '%s' of /%s is not in the %s table (undocumented)", name, obj, w->c->s->schema);
    else
        violation(w->c, "root attribute '%s' is not in the %s table (undocumented)", name, w->c->s->schema);
    return 0;
}

/* A dataset's units and description: the units of one of its rows. */
static void check_dset_doc(ctx *c, hid_t root, const char *path)
{
    const crom_schema_dset *first = NULL;
    int units_ok = 0;
    char *units = NULL, *desc = NULL;
    if (crom_h5_has_attr(root, path, "units"))
        crom_h5_get_str(root, path, "units", &units);
    for (const crom_schema_dset *d = c->s->dsets; d->path; d++)
        if (crom_schema_path_match(d->path, path)) {
            first = first ? first : d;
            units_ok |= units && !strcmp(units, d->units);
        }
    if (!first) {
        violation(c, "dataset /%s is not in the %s table (undocumented)", path, c->s->schema);
        free(units);
        return;
    }
    if (!units)
        violation(c, "/%s has no string attribute 'units' (expected '%s')", path, first->units);
    else if (!units_ok)
        violation(c, "/%s has units '%s', expected '%s'", path, units, first->units);
    if (!crom_h5_has_attr(root, path, "description") || crom_h5_get_str(root, path, "description", &desc) ||
        !*desc)
        violation(c, "/%s has no description", path);
    crom_err_clear();
    free(units);
    free(desc);
}

static herr_t object_cb(hid_t root, const char *name, const H5O_info_t *info, void *data)
{
    ctx *c = data;
    if (info->type != H5O_TYPE_DATASET && info->type != H5O_TYPE_GROUP)
        return 0;
    int dataset = info->type == H5O_TYPE_DATASET;
    if (dataset)
        check_dset_doc(c, root, name);
    int is_root = !strcmp(name, ".");
    for (const crom_schema_attr *a = c->s->objattrs; !is_root && a && a->name; a++)
        if (crom_schema_path_match(a->object, name))
            check_attr(c, root, name, a);
    attr_walk w = {c, name, dataset};
    hid_t o = H5Oopen(root, name, H5P_DEFAULT);
    if (o < 0) {
        violation(c, "/%s cannot be opened", name);
        return 0;
    }
    hsize_t idx = 0;
    if (H5Aiterate2(o, H5_INDEX_NAME, H5_ITER_INC, &idx, attr_cb, &w) < 0)
        violation(c, "the attributes of /%s cannot be listed", name);
    H5Oclose(o);
    return 0;
}

/* --------------------------------------------------------------- checker */

/* A violation from the last library error, which names the file first (the
 * violation does too: that prefix is dropped) and then what = a mesh group
 * (may be NULL) is put before the rest. */
static void reader_violation(ctx *c, const crom_in *in, const char *what)
{
    const char *m = crom_errmsg();
    size_t len = strlen(in->name);
    if (!strncmp(m, in->name, len) && !strncmp(m + len, ": ", 2))
        m += len + 2;
    if (what)
        violation(c, "%s: %s", what, m);
    else
        violation(c, "%s", m);
    crom_err_clear();
}

/* The mesh in group `group` ("/" for the root) as crom_mesh_read takes it. */
static void check_mesh(ctx *c, const crom_in *in, const char *group)
{
    hid_t loc = H5Gopen2(in->h5, group, H5P_DEFAULT);
    if (loc < 0) {
        crom_err_clear();
        return; /* missing: already a violation of the table */
    }
    crom_mesh m;
    char what[160];
    snprintf(what, sizeof what, "/%s", strcmp(group, "/") ? group : "");
    if (crom_mesh_read_flags(loc, CROM_MESH_SURFACES | CROM_MESH_SCENES, &m))
        reader_violation(c, in, strcmp(group, "/") ? what : NULL);
    else
        crom_mesh_free(&m);
    H5Gclose(loc);
}

/* Read the file as the programs do: each reader's refusal is a violation. */
static void check_readers(ctx *c, crom_in *in)
{
    const char *sc = c->s->schema;
    if (!strcmp(sc, "crom/mesh")) {
        check_mesh(c, in, "/");
    } else if (!strcmp(sc, "crom/trajectory")) {
        check_mesh(c, in, "mesh");
    } else if (!strcmp(sc, "crom/cubature")) {
        crom_cubature cub;
        if (crom_cubature_read(in, &cub))
            reader_violation(c, in, NULL);
        else
            crom_cubature_free(&cub);
    } else if (!strcmp(sc, "crom/model")) {
        crom_model m;
        if (crom_model_read(in, &m))
            reader_violation(c, in, NULL);
        else
            crom_model_free(&m);
    } else if (!strcmp(sc, "crom/samples")) {
        crom_samples smp;
        if (crom_samples_read(in, &smp))
            reader_violation(c, in, NULL);
        else
            crom_samples_free(&smp);
    }
    crom_err_clear();
}

int crom_validate_file(crom_in *in, FILE *report)
{
    ctx c;
    memset(&c, 0, sizeof c);
    c.report = report;
    c.file = in->name;
    const crom_schema *s = crom_schema_find(in->schema);
    if (!s) {
        violation(&c, "unknown schema '%s'", in->schema);
        return c.violations;
    }
    c.s = s;
    hsize_t fsize = 0;
    if (H5Fget_filesize(in->h5, &fsize) >= 0)
        c.filesize = fsize;
    crom_err_clear();
    if (in->version > s->version) {
        violation(&c, "%s v%d is newer than this crom understands (v%d)", s->schema, in->version,
                  s->version);
        return c.violations;
    }
    if (in->version < 1)
        violation(&c, "invalid schema_version %d", in->version);
    for (const crom_schema_attr *a = crom_schema_common_attrs(); a->name; a++)
        check_attr(&c, in->h5, ".", a);
    for (const crom_schema_attr *a = s->attrs; a && a->name; a++)
        check_attr(&c, in->h5, ".", a);
    /* a stream carries its frames separately (its header's are empty) */
    long long dummy;
    if (s->series)
        sym(&c, "F", in->form == CROM_IO_STREAM ? 0 : in->nframes, &dummy);
    for (const crom_schema_dset *d = s->dsets; d->path; d++) {
        if (d->kinds)
            continue; /* a second row of a path: the same dtype and shape, other units */
        const char *star = strchr(d->path, '*');
        if (!star) {
            check_dset(&c, in->h5, d->path, d);
            continue;
        }
        char group[128];
        snprintf(group, sizeof group, "%.*s", (int)(star - d->path - 1), d->path);
        if (!crom_h5_has(in->h5, group)) {
            if (d->required)
                violation(&c, "missing group /%s", group);
            continue;
        }
        char **names = crom_h5_list(in->h5, group);
        if (!names)
            violation(&c, "group /%s cannot be listed", group);
        for (int i = 0; names && names[i]; i++) {
            char path[256];
            snprintf(path, sizeof path, "%s/%s%s", group, names[i], star + 1);
            check_dset(&c, in->h5, path, d);
        }
        crom_h5_list_free(names);
    }
    /* the frames, unless a dataset declares more than the file holds */
    double *frames = NULL;
    long nframes = 0;
    if (s->series && !c.oversized) {
        if (!in->nfields)
            violation(&c, "a %s must have frame fields under /frames", s->schema);
        if (in->form == CROM_IO_H5)
            in->cursor = 0; /* check every frame, wherever the reader stood */
        if (crom_in_read_all(in, &frames, &nframes))
            violation(&c, "frames cannot be read: %s", crom_errmsg());
        if (in->complete != 1)
            violation(&c, "incomplete: the run that wrote it stopped after %ld frames", nframes);
        for (long f = 0; frames && f < nframes; f++)
            if (crom_result_check_frame(in, frames + (size_t)f * in->frame_len, f)) {
                reader_violation(&c, in, NULL);
                break;
            }
    }
    /* nothing the table does not describe; units and descriptions */
    if (H5Ovisit(in->h5, H5_INDEX_NAME, H5_ITER_INC, object_cb, &c) < 0)
        violation(&c, "the objects of the file cannot be listed");
    crom_err_clear();
    /* semantic checks: what the programs' own readers refuse (tets and
     * regions of every mesh, cubature indices and weights, sample vertices
     * and sources, network widths and parameter counts, ...) */
    if (!c.oversized)
        check_readers(&c, in);
    free(frames);
    return c.violations;
}
