/* validate.c — the checker behind `crom-info --check` (see validate.h): a
 * file against the table of its type in schema.c. */
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "io/schema.h"
#include "mesh/mesh.h"
#include "rom/result.h"
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
    if (rank > 8)
        rank = 8;
    H5Sget_simple_extent_dims(sp, dims, NULL);
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
    /* values must be finite */
    if (ok && cls == H5T_FLOAT && rank >= 0) {
        hssize_t n = H5Sget_simple_extent_npoints(sp);
        double *buf = n > 0 ? malloc(sizeof(double) * (size_t)n) : NULL;
        if (buf && H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf) >= 0) {
            for (hssize_t i = 0; i < n; i++)
                if (!isfinite(buf[i])) {
                    violation(c, "/%s has a non-finite value at flat index %lld", path, (long long)i);
                    break;
                }
        } else if (n > 0) {
            violation(c, "/%s cannot be read (corrupt?)", path);
        }
        free(buf);
    }
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
    /* a stream carries its frames separately: bind F from what is read */
    double *frames = NULL;
    long nframes = 0;
    if (s->series) {
        if (!in->nfields)
            violation(&c, "a %s must have frame fields under /frames", s->schema);
        if (in->form == CROM_IO_H5)
            in->cursor = 0; /* check every frame, wherever the reader stood */
        if (crom_in_read_all(in, &frames, &nframes))
            violation(&c, "frames cannot be read: %s", crom_errmsg());
        long long dummy;
        sym(&c, "F", in->form == CROM_IO_STREAM ? 0 : nframes, &dummy);
        if (in->complete != 1)
            violation(&c, "incomplete: the run that wrote it stopped after %ld frames", nframes);
        for (long f = 0; frames && f < nframes; f++)
            if (crom_result_check_frame(in, frames + (size_t)f * in->frame_len, f)) {
                /* the message names the file first: the violation does too */
                const char *m = crom_errmsg();
                size_t len = strlen(in->name);
                violation(&c, "%s", !strncmp(m, in->name, len) && !strncmp(m + len, ": ", 2) ? m + len + 2 : m);
                break;
            }
    }
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
    /* nothing the table does not describe; units and descriptions */
    if (H5Ovisit(in->h5, H5_INDEX_NAME, H5_ITER_INC, object_cb, &c) < 0)
        violation(&c, "the objects of the file cannot be listed");
    crom_err_clear();
    /* semantic checks */
    if (!strcmp(s->schema, "crom/mesh") || !strcmp(s->schema, "crom/trajectory")) {
        crom_mesh m;
        hid_t loc = !strcmp(s->schema, "crom/mesh") ? H5Gopen2(in->h5, "/", H5P_DEFAULT)
                                                    : H5Gopen2(in->h5, "mesh", H5P_DEFAULT);
        if (loc >= 0) {
            if (crom_mesh_read(loc, &m))
                violation(&c, "mesh: %s", crom_errmsg());
            else
                crom_mesh_free(&m);
            H5Gclose(loc);
        }
    }
    free(frames);
    return c.violations;
}
