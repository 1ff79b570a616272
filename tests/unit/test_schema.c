/* test_schema.c — the table of crom's file types (lib/io/schema.c) and its use by
 * the writers (lib/io/io.c): lookups, rows by model kind, the table's own
 * consistency, and writers that take units and descriptions from it and
 * refuse what it does not list. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "base/err.h"
#include "io/io.h"
#include "io/schema.h"

static char dir[] = "/tmp/crom-schema-XXXXXX";

static void test_path_match(void)
{
    CHECK(crom_schema_path_match("vertices", "vertices"));
    CHECK(!crom_schema_path_match("vertices", "vertices2"));
    CHECK(!crom_schema_path_match("vertices2", "vertices"));
    CHECK(crom_schema_path_match("regions/*", "regions/top"));
    CHECK(!crom_schema_path_match("regions/*", "regions/top/x"));
    CHECK(!crom_schema_path_match("regions/*", "regions/"));
    CHECK(!crom_schema_path_match("regions/*", "regions"));
    CHECK(!crom_schema_path_match("mesh/regions/*", "regions/top"));
    CHECK(crom_schema_path_match("sources/*/vertices", "sources/000/vertices"));
    CHECK(!crom_schema_path_match("sources/*/vertices", "sources/000/tets"));
    CHECK(!crom_schema_path_match("sources/*/vertices", "sources//vertices"));
}

static const char *units_of(const char *schema, const char *path, const char *kind)
{
    const crom_schema_dset *d = crom_schema_dset_find(crom_schema_find(schema), path, kind);
    return d ? d->units : "(none)";
}

/* a data-free latent is dimensionless; linear bases and neural modes are in metres */
static void test_rows_by_kind(void)
{
    static const struct {
        const char *kind, *q, *qdot;
    } want[] = {{NULL, "m", "m/s"},         {"mlp", "m", "m/s"},      {"pod", "m", "m/s"},
                {"modes", "m", "m/s"},      {"neuralmodes", "m", "m/s"}, {"energy", "1", "1/s"},
                {"energy-field", "1", "1/s"}, {"energy-fiel", "m", "m/s"}, {"field", "m", "m/s"}};
    for (size_t i = 0; i < sizeof want / sizeof *want; i++) {
        const char *k = want[i].kind ? want[i].kind : "NULL";
        CHECK_MSG(!strcmp(units_of("crom/latent", "frames/q", want[i].kind), want[i].q), "q of %s: %s", k,
                  units_of("crom/latent", "frames/q", want[i].kind));
        CHECK_MSG(!strcmp(units_of("crom/latent", "frames/qdot", want[i].kind), want[i].qdot), "qdot of %s: %s",
                  k, units_of("crom/latent", "frames/qdot", want[i].kind));
        /* rows without kinds hold for every kind */
        CHECK(!strcmp(units_of("crom/latent", "frames/time", want[i].kind), "s"));
    }
    CHECK(crom_schema_dset_find(crom_schema_find("crom/latent"), "frames/nothing", NULL) == NULL);
    CHECK(!strcmp(units_of("crom/mesh", "regions/top", NULL), "1"));
    CHECK(!strcmp(units_of("crom/samples", "sources/007/vertices", NULL), "m"));
    CHECK(crom_schema_find("crom/nothing") == NULL && crom_schema_find(NULL) == NULL);
}

static void test_attr_find(void)
{
    const crom_schema *lat = crom_schema_find("crom/latent"), *mesh = crom_schema_find("crom/mesh");
    CHECK(crom_schema_attr_find(lat, NULL, "history") != NULL);     /* common */
    CHECK(crom_schema_attr_find(NULL, NULL, "crom_version") != NULL); /* common, any file */
    CHECK(crom_schema_attr_find(lat, NULL, "solver") != NULL);
    CHECK(crom_schema_attr_find(lat, NULL, "cubatures") != NULL);
    CHECK(crom_schema_attr_find(lat, NULL, "every") != NULL); /* the scenario of a reduced run */
    CHECK(crom_schema_attr_find(lat, NULL, "fields") == NULL);   /* that is on /frames */
    CHECK(crom_schema_attr_find(lat, "frames", "fields") != NULL);
    CHECK(crom_schema_attr_find(mesh, "regions/top", "source") != NULL);
    CHECK(crom_schema_attr_find(mesh, NULL, "source") == NULL);
    CHECK(crom_schema_attr_find(mesh, "regions/top", "history") == NULL);
    CHECK(crom_schema_attr_find(mesh, NULL, "complete") == NULL); /* series only */
    CHECK(crom_schema_attr_find(crom_schema_find("crom/trajectory"), NULL, "complete") != NULL);
}

static int valid_type(const char *t, const char *const *ok)
{
    for (; *ok; ok++)
        if (!strcmp(t, *ok))
            return 1;
    return 0;
}

/* every row well formed; a second row of a path (model kinds) differs from
 * the plain row in units only, names real kinds and mentions them */
static void test_table_consistency(void)
{
    static const char *const dtypes[] = {"f64", "f32", "i32", NULL};
    static const char *const atypes[] = {"str", "i64", "f64", "f64[2]", "f64[3]", NULL};
    static const char *const kinds[] = {"mlp", "pod", "modes", "energy", "neuralmodes", "energy-field", NULL};
    int nspecs = 0;
    for (const crom_schema *s = crom_schema_all(); s->schema; s++, nspecs++) {
        CHECK_MSG(s->attrs && s->objattrs && s->dsets, "%s: missing tables", s->schema);
        for (const crom_schema_dset *d = s->dsets; d->path; d++) {
            CHECK_MSG(valid_type(d->type, dtypes), "%s /%s: dtype %s", s->schema, d->path, d->type);
            CHECK_MSG(d->units && *d->units && d->meaning && *d->meaning, "%s /%s: units and a description",
                      s->schema, d->path);
            if (s->series)
                CHECK_MSG(strncmp(d->path, "frames/", 7) || !strncmp(d->shape, "F", 1),
                          "%s /%s: a frame field leads with F", s->schema, d->path);
            const crom_schema_dset *plain = NULL;
            for (const crom_schema_dset *e = s->dsets; e < d; e++)
                if (!strcmp(e->path, d->path) && !e->kinds)
                    plain = e;
            if (!d->kinds) {
                CHECK_MSG(!plain, "%s /%s: listed twice", s->schema, d->path);
                continue;
            }
            CHECK_MSG(plain && !strcmp(plain->type, d->type) && !strcmp(plain->shape, d->shape) &&
                          plain->required == d->required && strcmp(plain->units, d->units),
                      "%s /%s (%s): a second row needs a plain row before it, same dtype, shape and "
                      "required, other units", s->schema, d->path, d->kinds);
            char list[128];
            snprintf(list, sizeof list, "%s", d->kinds);
            char *save = NULL;
            for (char *k = strtok_r(list, " ", &save); k; k = strtok_r(NULL, " ", &save)) {
                CHECK_MSG(valid_type(k, kinds), "%s /%s: unknown kind '%s'", s->schema, d->path, k);
                CHECK_MSG(strstr(d->meaning, k) != NULL, "%s /%s: the description does not name %s", s->schema,
                          d->path, k);
                const crom_schema_dset *f = crom_schema_dset_find(s, d->path, k);
                CHECK_MSG(f == d, "%s /%s: kind %s finds another row", s->schema, d->path, k);
            }
        }
        for (int obj = 0; obj < 2; obj++)
            for (const crom_schema_attr *a = obj ? s->objattrs : s->attrs; a->name; a++) {
                CHECK_MSG(valid_type(a->type, atypes), "%s '%s': type %s", s->schema, a->name, a->type);
                CHECK_MSG(a->meaning && *a->meaning, "%s '%s': meaning", s->schema, a->name);
                CHECK_MSG(obj ? a->object != NULL : a->object == NULL, "%s '%s': object", s->schema, a->name);
                CHECK_MSG(crom_schema_attr_find(s, a->object, a->name) == a, "%s '%s': listed twice", s->schema,
                          a->name);
            }
    }
    CHECK(nspecs == 6);
    for (const crom_schema_attr *a = crom_schema_common_attrs(); a->name; a++)
        CHECK(a->required && a->object == NULL && valid_type(a->type, atypes));
}

static char *attr_of(hid_t loc, const char *obj, const char *name)
{
    char *v = NULL;
    if (crom_h5_get_str(loc, obj, name, &v))
        return NULL;
    return v;
}

/* the writers take units and descriptions from the table and refuse what it does not list */
static void test_writers(void)
{
    char p[256];
    snprintf(p, sizeof p, "%s/mesh.h5", dir);
    crom_out o;
    CHECK(crom_out_create(&o, p, "crom/mesh", 1, NULL, NULL, CROM_OUT_PLAIN) == 0);
    double X[6] = {0, 1, 2, 3, 4, 5};
    float Xf[6] = {0};
    int idx[2] = {0, 1};
    hsize_t d2[2] = {2, 3}, d1 = 2;
    CHECK(crom_h5_put_f64(o.h5, "vertices", 2, d2, X) == 0);
    char *u = attr_of(o.h5, "vertices", "units"), *desc = attr_of(o.h5, "vertices", "description");
    const crom_schema_dset *row = crom_schema_dset_find(crom_schema_find("crom/mesh"), "vertices", NULL);
    CHECK(u && desc && !strcmp(u, "m") && !strcmp(desc, row->meaning));
    free(u);
    free(desc);
    hid_t g = crom_h5_group(o.h5, "regions");
    CHECK(crom_h5_put_i32(g, "top", 1, &d1, idx) == 0); /* a group member: the row of regions/ */
    u = attr_of(g, "top", "units");
    CHECK(u && !strcmp(u, "1"));
    free(u);
    CHECK(crom_h5_set_str(g, "top", "source", "y>0") == 0);
    CHECK(crom_h5_set_str(g, "top", "colour", "red") == CROM_EINTERNAL);
    CHECK(strstr(crom_errmsg(), "attribute 'colour' of /regions/top: crom/mesh does not list it") != NULL);
    CHECK(crom_h5_set_i64(g, "top", "source", 1) == CROM_EINTERNAL); /* listed as str */
    H5Gclose(g);
    /* unlisted, wrong dtype, wrong rank */
    CHECK(crom_h5_put_f64(o.h5, "normals", 2, d2, X) == CROM_EINTERNAL);
    CHECK(strstr(crom_errmsg(), "dataset /normals: crom/mesh does not list it") != NULL);
    CHECK(crom_h5_put_f32(o.h5, "tets", 2, d2, Xf) == CROM_EINTERNAL);
    CHECK(strstr(crom_errmsg(), "as f32 of rank 2: crom/mesh lists it as i32 [nt,4]") != NULL);
    CHECK(crom_h5_put_i32(o.h5, "tets", 1, &d1, idx) == CROM_EINTERNAL);
    /* root attributes: listed ones with their type only */
    double size = 0.1, g3[3] = {0, -9.81, 0};
    CHECK(crom_h5_set_f64(o.h5, ".", "target_size", &size, 1) == 0);
    CHECK(crom_h5_set_str(o.h5, ".", "generator", "box") == 0);
    CHECK(crom_h5_set_f64(o.h5, ".", "gravity", g3, 3) == CROM_EINTERNAL); /* not a mesh attribute */
    CHECK(crom_h5_set_i64(o.h5, ".", "target_size", 1) == CROM_EINTERNAL);
    CHECK(strstr(crom_errmsg(), "as i64: crom/mesh lists it as f64") != NULL);
    /* the free-text writer is for other files only */
    CHECK(crom_h5_write_f64(o.h5, "tets2", 2, d2, X, "m", "x") == CROM_EINTERNAL);
    CHECK(strstr(crom_errmsg(), "write it with crom_h5_put_*") != NULL);
    crom_out_fail(&o);

    /* another HDF5 file (XDMF heavy data): free units and descriptions */
    snprintf(p, sizeof p, "%s/heavy.h5", dir);
    CHECK(crom_out_create(&o, p, "xdmf/heavy-data", 1, NULL, NULL, CROM_OUT_PLAIN) == 0);
    CHECK(crom_h5_write_f64(o.h5, "any/thing", 2, d2, X, "m/s", "anything") == 0);
    desc = attr_of(o.h5, "any/thing", "description");
    CHECK(desc && !strcmp(desc, "anything"));
    free(desc);
    CHECK(crom_h5_put_f64(o.h5, "vertices", 2, d2, X) == CROM_EINTERNAL); /* no table */
    crom_out_fail(&o);

    /* frame fields: the row of the model kind */
    for (int k = 0; k < 2; k++) {
        snprintf(p, sizeof p, "%s/lat%d.h5", dir, k);
        CHECK(crom_out_create(&o, p, "crom/latent", 1, NULL, NULL, CROM_OUT_SERIES_H5) == 0);
        hsize_t r = 2;
        CHECK(crom_out_field(&o, "q", 1, &r, k ? "energy" : "mlp") == 0);
        CHECK(crom_out_field(&o, "qdot", 1, &r, k ? "energy" : "mlp") == 0);
        CHECK(crom_out_field(&o, "spin", 0, NULL, NULL) == CROM_EINTERNAL);
        CHECK(crom_out_field(&o, "time", 1, &r, NULL) == CROM_EINTERNAL); /* [F] listed, not [F, 2] */
        u = attr_of(o.h5, "frames/q", "units");
        char *ud = attr_of(o.h5, "frames/qdot", "units");
        CHECK_MSG(u && ud && !strcmp(u, k ? "1" : "m") && !strcmp(ud, k ? "1/s" : "m/s"), "kind %d: %s, %s", k,
                  u ? u : "-", ud ? ud : "-");
        free(u);
        free(ud);
        crom_out_fail(&o);
    }
}

/* `test_schema --dump`: the whole table as tab-separated lines, for
 * tests/prog/schemas.sh to hold against schemas/ (one line per row):
 *   schema NAME VERSION SERIES SUMMARY
 *   dset   SCHEMA PATH DTYPE SHAPE REQUIRED UNITS KINDS|- MEANING
 *   attr   SCHEMA OBJECT|- NAME TYPE REQUIRED MEANING      (SCHEMA "*": every file) */
static void dump(void)
{
    for (const crom_schema_attr *a = crom_schema_common_attrs(); a->name; a++)
        printf("attr\t*\t-\t%s\t%s\t%d\t%s\n", a->name, a->type, a->required, a->meaning);
    for (const crom_schema *s = crom_schema_all(); s->schema; s++) {
        printf("schema\t%s\t%d\t%d\t%s\n", s->schema, s->version, s->series, s->summary);
        for (const crom_schema_dset *d = s->dsets; d->path; d++)
            printf("dset\t%s\t%s\t%s\t%s\t%d\t%s\t%s\t%s\n", s->schema, d->path, d->type, d->shape, d->required,
                   d->units, d->kinds ? d->kinds : "-", d->meaning);
        for (int obj = 0; obj < 2; obj++)
            for (const crom_schema_attr *a = obj ? s->objattrs : s->attrs; a->name; a++)
                printf("attr\t%s\t%s\t%s\t%s\t%d\t%s\n", s->schema, a->object ? a->object : "-", a->name,
                       a->type, a->required, a->meaning);
    }
}

int main(int argc, char **argv)
{
    if (argc == 2 && !strcmp(argv[1], "--dump")) {
        dump();
        return 0;
    }
    check_begin("test_schema");
    crom_h5_quiet();
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_path_match();
    test_rows_by_kind();
    test_attr_find();
    test_table_consistency();
    test_writers();
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    return check_done();
}
