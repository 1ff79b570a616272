/* crom-info — say what is in a crom file; --check validates it against its
 * schema. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "io/schema.h"
#include "mesh/mesh.h"
#include "view/validate.h"

enum { O_CHECK = 300, O_FRAMES, O_HISTORY };

static const crom_opt info_opts[] = {
    {"check", O_CHECK, NULL, "Validate each file against its schema (datasets, types, shapes, attributes, units, nothing undocumented, finite values, mesh orientation, completeness); print one line per violation and exit 65 if there is any."},
    {"frames", O_FRAMES, NULL, "For a time series, also print a table of its scalar per-frame fields."},
    {"history", O_HISTORY, NULL, "Print the whole history (default: the last 3 lines)."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", info_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-info",
    "summarize or validate crom files",
    "crom-info [--check] [--frames] FILE|- ...",
    "Prints what a crom file holds: its schema and version, where it came from (history), "
    "a summary that depends on the file type (mesh size, volume and quality; frames, time "
    "span and energies of a trajectory; rank and training of a model; ...) and every dataset "
    "with its type, shape and units. Reads HDF5 files and crom frame streams, from a path or "
    "from stdin ('-').\n\n"
    "With --check it validates each file against the table of its schema (lib/io/schema.c, the "
    "same as schemas/*.md): every dataset and attribute must be in it, with its type, shape "
    "and units; it exits non-zero when anything is wrong.",
    groups,
    "crom-mesh box | crom-info -\n"
    "crom-info --check traj.h5 model.h5\n"
    "crom-fullsim ... < box.h5 | crom-info --frames -",
    "crom-mesh(1), crom-diff(1)"};

typedef struct {
    int check, frames, history;
    const char **files;
    int nfiles;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    switch (key) {
    case 0: {
        const char **f = realloc(a->files, sizeof(char *) * (size_t)(a->nfiles + 1));
        if (!f)
            return crom_err(CROM_EINTERNAL, "out of memory");
        a->files = f;
        a->files[a->nfiles++] = v;
        return 0;
    }
    case O_CHECK: a->check = 1; return 0;
    case O_FRAMES: a->frames = 1; return 0;
    case O_HISTORY: a->history = 1; return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* ------------------------------------------------------------ summaries */

static void print_mesh(hid_t loc, const char *indent)
{
    crom_mesh m;
    if (crom_mesh_read_flags(loc, CROM_MESH_SURFACES | CROM_MESH_SCENES, &m)) {
        printf("%smesh: INVALID: %s\n", indent, crom_errmsg());
        return;
    }
    double lo[3], hi[3], worst = 0, mean = 0;
    int wt;
    crom_mesh_bbox(&m, lo, hi);
    if (m.scene) {
        const crom_scene *s = m.scene;
        int count[CROM_SCENE_COUNT] = {0}, pins = 0;
        double mass = 0;
        for (int b = 0; b < s->nb; b++) {
            count[s->bodies[b].shape]++;
            mass += s->bodies[b].density * crom_scene_body_volume(&s->bodies[b]);
        }
        for (int j = 0; j < s->nj; j++)
            pins += s->joints[j].b < 0;
        printf("%sa rigid-body scene: %d bodies (%d boxes, %d spheres, %d capsules, %d rings; %d DOF), mass %.6g kg\n",
               indent, s->nb, count[CROM_SCENE_BOX], count[CROM_SCENE_SPHERE], count[CROM_SCENE_CAPSULE],
               count[CROM_SCENE_RING], 12 * s->nb, mass);
        printf("%s%d joints (%d pinned to the world), %d collision pairs, orthogonality weight %.4g J\n", indent,
               s->nj, pins, s->np, s->ortho_weight);
    } else if (crom_mesh_is_surface(&m)) {
        printf("%s%d vertices, %d triangles (a shell), thickness %.6g m, area %.6g m^2\n", indent, m.nv, m.ntri,
               m.thickness, crom_mesh_volume(&m) / m.thickness);
    } else {
        crom_mesh_quality(&m, &worst, &mean, &wt);
        printf("%s%d vertices, %d tets, volume %.6g m^3\n", indent, m.nv, m.nt, crom_mesh_volume(&m));
    }
    printf("%sbounding box [%.4g, %.4g] x [%.4g, %.4g] x [%.4g, %.4g] m\n", indent, lo[0], hi[0],
           lo[1], hi[1], lo[2], hi[2]);
    if (!crom_mesh_is_surface(&m) && !m.scene)
        printf("%squality (mean ratio) worst %.3f, mean %.3f\n", indent, worst, mean);
    for (int r = 0; r < m.nregions; r++)
        printf("%sregion %-12s %6d vertices  (%s)\n", indent, m.regions[r].name, m.regions[r].n,
               m.regions[r].source);
    crom_mesh_free(&m);
}

static void print_attr_line(hid_t h, const char *name, const char *label)
{
    if (!crom_h5_has_attr(h, ".", name))
        return;
    char *s = NULL;
    double v[3];
    long long i;
    if (!crom_h5_get_str(h, ".", name, &s)) {
        printf("  %-22s ", label);
        for (const char *c = s; *c; c++)
            if (*c == '\n')
                printf("\n%25s", ""); /* continuation lines under the first */
            else
                putchar(*c);
        putchar('\n');
        free(s);
    } else if (!crom_h5_get_i64(h, ".", name, &i) && !crom_h5_get_f64(h, ".", name, v, 1) &&
               v[0] == (double)i) {
        printf("  %-22s %lld\n", label, i);
    } else if (!crom_h5_get_f64(h, ".", name, v, 1)) {
        printf("  %-22s %.6g\n", label, v[0]);
    } else if (!crom_h5_get_f64(h, ".", name, v, 3)) {
        printf("  %-22s %.6g, %.6g, %.6g\n", label, v[0], v[1], v[2]);
    }
    crom_err_clear();
}

typedef struct {
    int depth;
} visit_ctx;

static herr_t visit_cb(hid_t root, const char *name, const H5O_info_t *info, void *data)
{
    (void)data;
    if (info->type != H5O_TYPE_DATASET)
        return 0;
    int rank;
    hsize_t dims[CROM_IO_MAX_RANK];
    if (crom_h5_shape(root, name, &rank, dims)) {
        crom_err_clear();
        return 0;
    }
    hid_t d = H5Dopen2(root, name, H5P_DEFAULT);
    hid_t t = H5Dget_type(d);
    const char *ty = H5Tget_class(t) == H5T_FLOAT ? (H5Tget_size(t) == 8 ? "f64" : "f32")
                     : H5Tget_class(t) == H5T_INTEGER ? (H5Tget_size(t) == 4 ? "i32" : "int")
                                                       : "other";
    char shape[96] = "";
    size_t off = 0;
    for (int i = 0; i < rank; i++)
        off += (size_t)snprintf(shape + off, sizeof shape - off, "%s%llu", i ? "," : "",
                                (unsigned long long)dims[i]);
    char *units = NULL, *desc = NULL;
    if (crom_h5_has_attr(d, ".", "units"))
        crom_h5_get_str(d, ".", "units", &units);
    if (crom_h5_has_attr(d, ".", "description"))
        crom_h5_get_str(d, ".", "description", &desc);
    printf("    /%-28s %-4s [%s]%*s %-5s %s\n", name, ty, shape,
           (int)(off < 14 ? 14 - off : 0), "", units ? units : "", desc ? desc : "");
    free(units);
    free(desc);
    H5Tclose(t);
    H5Dclose(d);
    return 0;
}

static void print_series(crom_in *in, int table)
{
    if (!in->nfields)
        return;
    double *frames = NULL;
    long n = 0;
    if (crom_in_read_all(in, &frames, &n)) {
        printf("  frames: cannot read: %s\n", crom_errmsg());
        return;
    }
    int ti = -1;
    for (int i = 0; i < in->nfields; i++)
        if (!strcmp(in->fields[i].name, "time"))
            ti = i;
    printf("  frames                 %ld%s", n, in->complete == 1 ? "" : "  (INCOMPLETE: the run stopped early)");
    if (ti >= 0 && n > 0)
        printf(", t = %.6g .. %.6g s", frames[in->fields[ti].offset],
               frames[(size_t)(n - 1) * in->frame_len + in->fields[ti].offset]);
    printf("\n  fields                 ");
    for (int i = 0; i < in->nfields; i++) {
        printf("%s%s", i ? ", " : "", in->fields[i].name);
        if (in->fields[i].rank) {
            printf("[");
            for (int j = 0; j < in->fields[i].rank; j++)
                printf("%s%llu", j ? "," : "", (unsigned long long)in->fields[i].dims[j]);
            printf("]");
        }
    }
    printf("\n");
    if (table && n > 0) {
        printf("\n  %6s", "frame");
        for (int i = 0; i < in->nfields; i++)
            if (in->fields[i].rank == 0)
                printf(" %14.14s", in->fields[i].name);
        printf("\n");
        for (long f = 0; f < n; f++) {
            printf("  %6ld", f);
            for (int i = 0; i < in->nfields; i++)
                if (in->fields[i].rank == 0)
                    printf(" %14.6g", frames[(size_t)f * in->frame_len + in->fields[i].offset]);
            printf("\n");
        }
    }
    free(frames);
}

static int summarize(const args *a, const char *path)
{
    crom_in in;
    int rc = crom_in_open(&in, path);
    if (rc)
        return rc;
    const crom_schema *s = crom_schema_find(in.schema);
    printf("%s: %s v%d (%s)%s%s\n", in.name, in.schema, in.version,
           in.form == CROM_IO_STREAM ? "crom frame stream" : "HDF5", s ? " — " : "",
           s ? s->summary : "");
    if (in.history) {
        int lines = 1;
        for (const char *c = in.history; *c; c++)
            lines += *c == '\n';
        const char *p = in.history;
        int skip = a->history || lines <= 3 ? 0 : lines - 3;
        for (int i = 0; i < skip; i++)
            p = strchr(p, '\n') + 1;
        printf("  history%s\n", skip ? " (last 3 lines; --history for all)" : "");
        while (*p) {
            const char *e = strchr(p, '\n');
            int len = e ? (int)(e - p) : (int)strlen(p);
            printf("    %.*s\n", len, p);
            p += len + (e != NULL);
        }
    }
    static const char *skip_attrs[] = {"schema", "schema_version", "history", "crom_version",
                                       "scenario", "complete", NULL};
    if (s)
        for (const crom_schema_attr *at = s->attrs; at->name; at++) {
            int skipit = 0;
            for (int i = 0; skip_attrs[i]; i++)
                skipit |= !strcmp(at->name, skip_attrs[i]);
            if (!skipit)
                print_attr_line(in.h5, at->name, at->name);
        }
    if (!strcmp(in.schema, "crom/mesh")) {
        hid_t root = H5Gopen2(in.h5, "/", H5P_DEFAULT);
        print_mesh(root, "  ");
        H5Gclose(root);
    } else if (crom_h5_has(in.h5, "mesh/vertices")) {
        hid_t g = H5Gopen2(in.h5, "mesh", H5P_DEFAULT);
        printf("  mesh:\n");
        print_mesh(g, "    ");
        H5Gclose(g);
    }
    if (crom_h5_has_attr(in.h5, ".", "scenario")) {
        char *sc = NULL;
        if (!crom_h5_get_str(in.h5, ".", "scenario", &sc)) {
            printf("  scenario:\n    ");
            for (const char *c = sc; *c; c++) {
                putchar(*c);
                if (*c == '\n' && c[1])
                    printf("    ");
            }
            printf("\n");
        }
        free(sc);
    }
    print_series(&in, a->frames);
    printf("  datasets:\n");
    H5Ovisit(in.h5, H5_INDEX_NAME, H5_ITER_INC, visit_cb, NULL);
    crom_in_close(&in);
    crom_err_clear();
    return 0;
}

static int check(const char *path)
{
    crom_in in;
    int rc = crom_in_open(&in, path);
    if (rc)
        return rc;
    int v = crom_validate_file(&in, stdout);
    if (v == 0)
        printf("%s: valid %s v%d\n", in.name, in.schema, in.version);
    else
        crom_err(CROM_EDATA, "%s: %d schema violation%s", in.name, v, v == 1 ? "" : "s");
    crom_in_close(&in);
    return v ? CROM_EDATA : 0;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a = {0};
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    if (a.nfiles == 0) {
        static const char *dash = "-";
        a.files = malloc(sizeof(char *));
        a.files[a.nfiles++] = dash;
    }
    int rc = 0;
    for (int i = 0; i < a.nfiles; i++) {
        int r = a.check ? check(a.files[i]) : summarize(&a, a.files[i]);
        if (r) {
            if (a.nfiles > 1 && i + 1 < a.nfiles) {
                fprintf(stderr, "%s: %s\n", cli.prog, crom_errmsg());
                crom_err_clear();
            }
            if (!rc)
                rc = r;
        }
        fflush(stdout);
    }
    free(a.files);
    return crom_cli_exit(&cli, rc);
}
