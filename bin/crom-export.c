/* crom-export — write meshes and trajectories as files other tools open:
 * VTU (+ PVD for a series) for ParaView and meshio, surface OBJ and PLY. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "err.h"
#include "export.h"
#include "io.h"
#include "mesh.h"
#include "render.h"
#include "result.h"

enum { O_FORMAT = 300, O_FRAME, O_EVERY, O_NAME, O_MESH, O_MODEL, O_COMPARE, O_COLUMNS, O_PANEL, O_RANGE };

static const crom_opt export_opts[] = {
    {"format", O_FORMAT, "FMT", "vtu, pvd, obj, ply, png (a picture per frame), or strip (one PNG: the input and each --compare side by side, rows, at --columns times). Default: from the extension of OUT; pvd when OUT ends in '/'."},
    {"output", 'o', "OUT", "Output file; for pvd, and for obj/ply with --frame all, a directory (created if needed)."},
    {"frame", O_FRAME, "K", "Which frame of a series to write for vtu/obj/ply: an index (negative counts from the end; default -1, the last) or 'all' for one file per frame."},
    {"every", O_EVERY, "K", "With pvd or --frame all: keep every K-th frame (default 1)."},
    {"name", O_NAME, "BASE", "File name stem inside the output directory (default 'frame': frame.pvd, frame_00000.vtu, ...)."},
    {"mesh", O_MESH, "MESH", "For a crom/latent: the mesh to decode onto (any mesh: the training mesh, a finer one for display, another shape; a trajectory or cubature carrying a mesh will do). For a trajectory: a mesh with the same vertices, e.g. to add regions."},
    {"model", O_MODEL, "MODEL", "The crom/model that decodes a crom/latent: u(X) = W(X) q."},
    {"compare", O_COMPARE, "RESULT", "strip: another result (trajectory, or latent decoded with --model/--mesh) drawn as a further row (repeatable), e.g. the full run under the reduced one."},
    {"columns", O_COLUMNS, "K", "strip: frames shown per row, evenly spaced in time (default 6)."},
    {"panel", O_PANEL, "WxH", "png, strip: pixels of one picture (default 360x300)."},
    {"range", O_RANGE, "UMAX", "png, strip: colour |u| over [0, UMAX] m (default: the largest |u| of all frames shown)."},
    {NULL, 0, NULL, NULL}};

static const crom_optgroup groups[] = {{"Options", export_opts}, {NULL, NULL}};

static const crom_doc doc = {
    "crom-export",
    "write crom meshes, trajectories and decoded latent runs as VTU/PVD, OBJ or PLY",
    "crom-export --format vtu|pvd|obj|ply [options] -o OUT [MESH|TRAJ|-]\n"
    "crom-export --format vtu|pvd|obj|ply --model MODEL --mesh MESH -o OUT [LATENT|-]",
    "Reads a crom/mesh, a crom/trajectory, or a crom/latent decoded through a model onto any "
    "mesh (HDF5 file or frame stream, from a path or stdin) and writes files ParaView, meshio "
    "and mesh viewers open.\n\n"
    "vtu: the tetrahedral mesh on its rest positions; for a trajectory frame the point data "
    "'displacement' and 'velocity' (use ParaView's Warp By Vector on 'displacement'). Every "
    "named region becomes a 0/1 point field 'region_NAME'.\n\n"
    "pvd: a directory holding one VTU per frame and a .pvd collection with the frame times, "
    "written frame by frame as a stream arrives.\n\n"
    "obj, ply: the boundary surface in its deformed position (binary PLY adds |u| per vertex).\n\n"
    "png, strip: pictures rendered without a display: the deformed boundary surface, shaded and "
    "coloured by |u| on one colour scale, from a fixed camera. strip puts several results side by "
    "side (rows) at the same times (columns) for a quick look without ParaView.",
    groups,
    "crom-mesh box | crom-export --format vtu -o box.vtu\n"
    "crom-fullsim @compress.flags < box.h5 | crom-export --format pvd -o out/\n"
    "crom-export --format obj --frame all -o surf/ traj.h5\n"
    "crom-export --format strip --model m.h5 --mesh box.h5 --compare full.h5 -o strip.png reduced.h5",
    "crom-mesh(1), crom-fullsim(1), crom-info(1)"};

typedef struct {
    const char *input, *out, *format, *name, *mesh, *model;
    const char *compare[8];
    int ncompare, columns, pw, ph;
    double range;
    long frame;
    int all, every;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    long n;
    switch (key) {
    case 0:
        if (a->input)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s' (one input at a time)", v);
        a->input = v;
        return 0;
    case 'o': a->out = v; return 0;
    case O_FORMAT:
        if (strcmp(v, "vtu") && strcmp(v, "pvd") && strcmp(v, "obj") && strcmp(v, "ply") && strcmp(v, "png") &&
            strcmp(v, "strip"))
            return crom_err(CROM_EUSAGE, "--format: '%s' is not vtu, pvd, obj, ply, png or strip", v);
        a->format = v;
        return 0;
    case O_FRAME:
        if (!strcmp(v, "all")) {
            a->all = 1;
            return 0;
        }
        if (crom_parse_int(v, "--frame", -1000000000L, 1000000000L, &n))
            return CROM_EUSAGE;
        a->frame = n;
        return 0;
    case O_EVERY:
        if (crom_parse_int(v, "--every", 1, 1000000000L, &n))
            return CROM_EUSAGE;
        a->every = (int)n;
        return 0;
    case O_NAME:
        if (!*v || strchr(v, '/'))
            return crom_err(CROM_EUSAGE, "--name: '%s' must be a plain file name stem", v);
        a->name = v;
        return 0;
    case O_MESH: a->mesh = v; return 0;
    case O_MODEL: a->model = v; return 0;
    case O_COMPARE:
        if (a->ncompare == 8)
            return crom_err(CROM_EUSAGE, "--compare: at most 8");
        a->compare[a->ncompare++] = v;
        return 0;
    case O_COLUMNS:
        if (crom_parse_int(v, "--columns", 1, 64, &n))
            return CROM_EUSAGE;
        a->columns = (int)n;
        return 0;
    case O_PANEL:
        if (sscanf(v, "%dx%d", &a->pw, &a->ph) != 2 || a->pw < 32 || a->ph < 32 || a->pw > 4096 || a->ph > 4096)
            return crom_err(CROM_EUSAGE, "--panel: '%s' is not WxH with 32..4096 pixels", v);
        return 0;
    case O_RANGE: return crom_parse_positive(v, "--range", &a->range);
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

static int ends_with(const char *s, const char *suf)
{
    size_t n = strlen(s), m = strlen(suf);
    return n >= m && !strcmp(s + n - m, suf);
}

static void parse_args(crom_cli *cli, args *a, int argc, char **argv)
{
    memset(a, 0, sizeof *a);
    a->frame = -1;
    a->every = 1;
    a->name = "frame";
    a->columns = 6;
    a->pw = 360;
    a->ph = 300;
    crom_cli_parse(cli, &doc, argc, argv, on_opt, a);
    /* trailing slashes of a directory are noise in the file names we print */
    if (a->out) {
        static char outbuf[1024];
        snprintf(outbuf, sizeof outbuf, "%s", a->out);
        size_t l = strlen(outbuf);
        while (l > 1 && outbuf[l - 1] == '/')
            outbuf[--l] = 0;
        int was_dir = strcmp(outbuf, a->out) != 0;
        a->out = outbuf;
        if (was_dir && !a->format)
            a->format = "pvd";
    }
    if (!a->format && a->out) {
        static const char *ext[] = {".vtu", ".pvd", ".obj", ".ply", ".png"};
        for (int i = 0; i < 5; i++)
            if (ends_with(a->out, ext[i]))
                a->format = ext[i] + 1;
        if (!a->format && ends_with(a->out, "/"))
            a->format = "pvd";
    }
    const char *err = NULL;
    if (!a->format)
        err = "no --format given and none follows from -o";
    else if (!a->out && (!strcmp(a->format, "pvd") || a->all))
        err = "pvd and --frame all write a directory: give -o DIR";
    else if (a->ncompare && strcmp(a->format, "strip"))
        err = "--compare is for --format strip";
    if (err)
        exit(crom_cli_exit(cli, crom_err(CROM_EUSAGE, "%s (see crom-export --help)", err)));
}

/* mkdir -p for the output directory */
static int make_dir(const char *path)
{
    char buf[1024];
    snprintf(buf, sizeof buf, "%s", path);
    for (char *p = buf + 1;; p++) {
        if (*p == '/' || !*p) {
            char c = *p;
            *p = 0;
            if (mkdir(buf, 0777) != 0 && errno != EEXIST)
                return crom_err(CROM_ECANTCREAT, "cannot create directory %s: %s", buf, strerror(errno));
            if (!c)
                break;
            *p = c;
        }
    }
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISDIR(st.st_mode))
        return crom_err(CROM_ECANTCREAT, "%s exists and is not a directory", path);
    return 0;
}

/* Write one frame (or the bare mesh: disp == NULL) to path in format fmt. */
static int write_one(const char *path, const char *fmt, const crom_mesh *m, const double *disp,
                     const double *vel)
{
    crom_fileout fo;
    int binary = !strcmp(fmt, "ply");
    int rc = crom_fileout_open(&fo, path, binary);
    if (rc)
        return rc;
    if (!strcmp(fmt, "vtu") || !strcmp(fmt, "pvd")) {
        crom_pointfield pf[2] = {{"displacement", 3, disp}, {"velocity", 3, vel}};
        rc = crom_export_vtu(fo.f, m, pf, disp ? (vel ? 2 : 1) : 0);
    } else if (!strcmp(fmt, "obj")) {
        rc = crom_export_obj(fo.f, m, disp);
    } else {
        rc = crom_export_ply(fo.f, m, disp);
    }
    if (rc) {
        crom_fileout_abort(&fo);
        return crom_err_ctx("%s", path);
    }
    return crom_fileout_commit(&fo);
}

/* ------------------------------------------------------------ pictures */

typedef struct {
    crom_result res;
    int nf;
    double *t, *u; /* [nf], [nf][3nv] */
    int ntri, *tris;
    const char *label;
} row;

static void free_row(row *r)
{
    crom_result_close(&r->res);
    free(r->t);
    free(r->u);
    free(r->tris);
}

/* Read every frame of a result into memory, with its boundary surface. */
static int load_row(row *r, const args *a)
{
    size_t n3 = 3 * (size_t)r->res.mesh.nv, cap = 16;
    r->t = crom_malloc(sizeof(double) * cap);
    r->u = crom_malloc(sizeof(double) * cap * n3);
    if (!r->t || !r->u)
        return CROM_EINTERNAL;
    int rc;
    double t;
    long k = 0;
    for (;;) {
        if ((size_t)r->nf == cap) {
            cap *= 2;
            double *nt = crom_realloc(r->t, sizeof(double) * cap), *nu = nt ? crom_realloc(r->u, sizeof(double) * cap * n3) : NULL;
            if (!nt || !nu)
                return CROM_EINTERNAL;
            r->t = nt;
            r->u = nu;
        }
        rc = crom_result_next(&r->res, &t, r->u + (size_t)r->nf * n3, NULL);
        if (rc != 1)
            break;
        if (k++ % a->every)
            continue;
        r->t[r->nf++] = t;
    }
    if (rc)
        return rc;
    if (r->nf == 0)
        return crom_err(CROM_EDATA, "%s has no frames", r->res.in.name);
    return crom_mesh_boundary(&r->res.mesh, &r->ntri, &r->tris, NULL);
}

/* camera and colour range shared by all pictures */
static void frame_all(row *rows, int nrows, const args *a, int pw, int ph, crom_camera *cam, double *umax)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, m = 0;
    for (int r = 0; r < nrows; r++) {
        const crom_mesh *mesh = &rows[r].res.mesh;
        for (int f = -1; f < rows[r].nf; f++)
            for (int i = 0; i < mesh->nv; i++) {
                double d2 = 0;
                for (int c = 0; c < 3; c++) {
                    double d = f < 0 ? 0 : rows[r].u[(size_t)f * 3 * mesh->nv + 3 * i + c];
                    double x = mesh->X[3 * i + c] + d;
                    lo[c] = fmin(lo[c], x);
                    hi[c] = fmax(hi[c], x);
                    d2 += d * d;
                }
                m = fmax(m, sqrt(d2));
            }
    }
    crom_camera_fit(cam, lo, hi, pw, ph, 1.12);
    *umax = a->range > 0 ? a->range : (m > 0 ? m : 1);
}

static int write_png(const char *path, const crom_image *im)
{
    crom_fileout fo;
    int rc = crom_fileout_open(&fo, path, 1);
    if (rc)
        return rc;
    if ((rc = crom_image_write_png(im, fo.f))) {
        crom_fileout_abort(&fo);
        return rc;
    }
    return crom_fileout_commit(&fo);
}

static const char *base_name(const char *p)
{
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

/* --format png: one picture per frame (a directory) or the --frame-th */
static int run_png(crom_cli *cli, args *a, crom_result *res)
{
    row r = {0};
    r.res = *res;
    int rc = load_row(&r, a);
    crom_camera cam;
    double umax;
    crom_image im = {0};
    double *work = NULL;
    if (rc)
        goto out;
    frame_all(&r, 1, a, a->pw, a->ph, &cam, &umax);
    int nv = r.res.mesh.nv;
    work = crom_malloc(sizeof(double) * 4 * (size_t)nv);
    if (!work || (rc = crom_image_init(&im, a->pw, a->ph + 34))) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    int series = a->all;
    long first = 0, last = r.nf - 1;
    if (!series) {
        long k = a->frame < 0 ? r.nf + a->frame : a->frame;
        if (k < 0 || k >= r.nf) {
            rc = crom_err(CROM_EUSAGE, "--frame %ld: %s has %d frames", a->frame, r.res.in.name, r.nf);
            goto out;
        }
        first = last = k;
    } else if ((rc = make_dir(a->out))) {
        goto out;
    }
    for (long f = first; f <= last && !rc; f++) {
        crom_image_free(&im);
        if ((rc = crom_image_init(&im, a->pw, a->ph + 34)))
            break;
        char label[64], path[1400];
        snprintf(label, sizeof label, "t=%.3f s", r.t[f]);
        crom_render_panel(&im, &cam, 0, 0, a->pw, a->ph, nv, r.res.mesh.X, r.u + (size_t)f * 3 * nv, r.ntri,
                          r.tris, umax, label, work);
        crom_image_colorbar(&im, 10, a->ph + 2, a->pw - 20, 10, 0, umax, "m");
        if (series)
            snprintf(path, sizeof path, "%s/%s_%05ld.png", a->out, a->name, f);
        else
            snprintf(path, sizeof path, "%s", a->out ? a->out : "-");
        rc = write_png(path, &im);
    }
    if (!rc && series)
        crom_cli_info(cli, "wrote %ld pictures to %s/", last - first + 1, a->out);
out:
    crom_image_free(&im);
    free(work);
    *res = r.res; /* handed back for closing */
    free(r.t);
    free(r.u);
    free(r.tris);
    return rc;
}

/* --format strip: rows of results, columns of times, one colour scale */
static int run_strip(crom_cli *cli, args *a, crom_result *res)
{
    int nrows = 1 + a->ncompare, rc = 0;
    row *rows = crom_calloc((size_t)nrows, sizeof(row));
    if (!rows)
        return CROM_EINTERNAL;
    rows[0].res = *res;
    memset(res, 0, sizeof *res);
    res->in.h5 = -1;
    rows[0].label = a->input ? base_name(a->input) : "stdin";
    for (int i = 0; i < a->ncompare && !rc; i++) {
        /* --mesh decodes latents; a compared trajectory keeps its own mesh */
        crom_in in;
        if (!(rc = crom_in_open(&in, a->compare[i])))
            rc = crom_result_adopt(&rows[i + 1].res, &in, strcmp(in.schema, "crom/latent") ? NULL : a->mesh, a->model);
        rows[i + 1].label = base_name(a->compare[i]);
    }
    for (int i = 0; i < nrows && !rc; i++)
        rc = load_row(&rows[i], a);
    crom_image im = {0};
    double *work = NULL;
    if (rc)
        goto out;
    int K = a->columns < rows[0].nf ? a->columns : rows[0].nf, head = 34, maxnv = 0;
    for (int i = 0; i < nrows; i++)
        maxnv = rows[i].res.mesh.nv > maxnv ? rows[i].res.mesh.nv : maxnv;
    crom_camera cam;
    double umax;
    frame_all(rows, nrows, a, a->pw, a->ph, &cam, &umax);
    work = crom_malloc(sizeof(double) * 4 * (size_t)maxnv);
    if (!work || (rc = crom_image_init(&im, K * a->pw, nrows * a->ph + head))) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int c = 0; c < K; c++) {
        int f0 = K == 1 ? rows[0].nf - 1 : (int)((double)c * (rows[0].nf - 1) / (K - 1) + 0.5);
        double t = rows[0].t[f0];
        for (int r = 0; r < nrows; r++) {
            int best = 0; /* the frame nearest in time */
            for (int f = 1; f < rows[r].nf; f++)
                if (fabs(rows[r].t[f] - t) < fabs(rows[r].t[best] - t))
                    best = f;
            char label[160];
            if (c == 0)
                snprintf(label, sizeof label, "%.40s  t=%.3f", rows[r].label, rows[r].t[best]);
            else
                snprintf(label, sizeof label, "t=%.3f", rows[r].t[best]);
            int nv = rows[r].res.mesh.nv;
            crom_render_panel(&im, &cam, c * a->pw, r * a->ph, a->pw, a->ph, nv, rows[r].res.mesh.X,
                              rows[r].u + (size_t)best * 3 * nv, rows[r].ntri, rows[r].tris, umax, label, work);
        }
    }
    crom_image_colorbar(&im, 10, nrows * a->ph + 2, (K * a->pw) / 2, 10, 0, umax, "m  |u|");
    rc = write_png(a->out ? a->out : "-", &im);
    if (!rc)
        crom_cli_info(cli, "wrote a %d x %d strip (%d rows, %d columns) to %s", im.w, im.h, nrows, K,
                      a->out ? a->out : "stdout");
out:
    crom_image_free(&im);
    free(work);
    for (int i = 0; i < nrows; i++)
        free_row(&rows[i]);
    free(rows);
    return rc;
}

static int run(crom_cli *cli, args *a)
{
    crom_in probe;
    int rc = crom_in_open(&probe, a->input);
    if (rc)
        return rc;
    int is_mesh = !strcmp(probe.schema, "crom/mesh");
    if (is_mesh) { /* a bare mesh: one file */
        rc = crom_in_expect(&probe, "crom/mesh", 1);
        crom_mesh m;
        hid_t root = rc ? -1 : H5Gopen2(probe.h5, "/", H5P_DEFAULT);
        if (!rc && (rc = crom_mesh_read(root, &m)))
            crom_err_ctx("%s", probe.name);
        if (root >= 0)
            H5Gclose(root);
        crom_in_close(&probe);
        if (rc)
            return rc;
        char path[1200];
        if (a->all || !strcmp(a->format, "pvd")) {
            if ((rc = make_dir(a->out))) {
                crom_mesh_free(&m);
                return rc;
            }
            snprintf(path, sizeof path, "%s/%s.%s", a->out, a->name, !strcmp(a->format, "pvd") ? "vtu" : a->format);
        } else {
            snprintf(path, sizeof path, "%s", a->out ? a->out : "-");
        }
        if (!strcmp(a->format, "png") || !strcmp(a->format, "strip")) {
            crom_image im;
            crom_camera cam;
            double lo[3], hi[3], *work = crom_malloc(sizeof(double) * 4 * (size_t)m.nv);
            int ntri, *tris = NULL;
            crom_mesh_bbox(&m, lo, hi);
            crom_camera_fit(&cam, lo, hi, a->pw, a->ph, 1.12);
            if (!work || (rc = crom_image_init(&im, a->pw, a->ph)) || (rc = crom_mesh_boundary(&m, &ntri, &tris, NULL))) {
                free(work);
                crom_mesh_free(&m);
                return rc ? rc : CROM_EINTERNAL;
            }
            crom_render_panel(&im, &cam, 0, 0, a->pw, a->ph, m.nv, m.X, NULL, ntri, tris, 1, NULL, work);
            rc = write_png(a->all ? path : (a->out ? a->out : "-"), &im);
            crom_image_free(&im);
            free(work);
            free(tris);
        } else {
            rc = write_one(path, a->format, &m, NULL, NULL);
        }
        crom_mesh_free(&m);
        return rc;
    }
    /* a trajectory, or a latent decoded through --model onto --mesh */
    crom_result res;
    if ((rc = crom_result_adopt(&res, &probe, a->mesh, a->model)))
        return rc;
    if (!strcmp(a->format, "png") || !strcmp(a->format, "strip")) {
        rc = !strcmp(a->format, "png") ? run_png(cli, a, &res) : run_strip(cli, a, &res);
        crom_result_close(&res);
        return rc;
    }
    if (res.outside)
        crom_cli_warn(cli, "%zu vertices of the mesh lie outside the model's mesh: W is extended there", res.outside);
    size_t n3 = 3 * (size_t)res.mesh.nv;
    double *u = crom_malloc(sizeof(double) * n3), *v = crom_malloc(sizeof(double) * n3), t;
    int series_out = !strcmp(a->format, "pvd") || a->all;
    if (!u || !v) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    if (!series_out) { /* one frame: the --frame-th */
        long nread = 0, want = a->frame;
        double *lastu = crom_malloc(sizeof(double) * n3), *lastv = crom_malloc(sizeof(double) * n3);
        double *ring = NULL;
        if (!lastu || !lastv) {
            free(lastu);
            free(lastv);
            rc = CROM_EINTERNAL;
            goto out;
        }
        /* negative --frame counts from the end: keep the last -frame frames */
        long keep = want < 0 ? -want : 1;
        ring = crom_malloc(sizeof(double) * 2 * n3 * (size_t)keep);
        if (!ring) {
            free(lastu);
            free(lastv);
            rc = CROM_EINTERNAL;
            goto out;
        }
        int r2;
        while ((r2 = crom_result_next(&res, &t, u, v)) == 1) {
            if (want >= 0 && nread == want) {
                memcpy(lastu, u, sizeof(double) * n3);
                memcpy(lastv, v, sizeof(double) * n3);
            }
            if (want < 0) {
                memcpy(ring + (size_t)(nread % keep) * 2 * n3, u, sizeof(double) * n3);
                memcpy(ring + (size_t)(nread % keep) * 2 * n3 + n3, v, sizeof(double) * n3);
            }
            nread++;
        }
        if (r2 > 1)
            rc = r2;
        else if ((want >= 0 && want >= nread) || (want < 0 && -want > nread))
            rc = crom_err(CROM_EUSAGE, "--frame %ld: %s has %ld frames", want, a->input, nread);
        else {
            if (want < 0) {
                long k = nread + want;
                memcpy(lastu, ring + (size_t)(k % keep) * 2 * n3, sizeof(double) * n3);
                memcpy(lastv, ring + (size_t)(k % keep) * 2 * n3 + n3, sizeof(double) * n3);
            }
            rc = write_one(a->out ? a->out : "-", a->format, &res.mesh, lastu, lastv);
        }
        free(ring);
        free(lastu);
        free(lastv);
        goto out;
    }
    /* a series, frame by frame as it arrives */
    if ((rc = make_dir(a->out)))
        goto out;
    const char *ext = !strcmp(a->format, "pvd") ? "vtu" : a->format;
    double *times = NULL;
    char **files = NULL;
    int nout = 0;
    crom_progress prog;
    crom_progress_start(&prog, cli, "export", res.in.form == CROM_FORM_H5 ? res.in.nframes : 0);
    long k = 0;
    while ((rc = crom_result_next(&res, &t, u, v)) == 1) {
        if (k++ % a->every)
            continue;
        char rel[256], path[1400];
        snprintf(rel, sizeof rel, "%s_%05d.%s", a->name, nout, ext);
        snprintf(path, sizeof path, "%s/%s", a->out, rel);
        if ((rc = write_one(path, a->format, &res.mesh, u, v)))
            break;
        double *nt = realloc(times, sizeof(double) * (size_t)(nout + 1));
        char **nf = realloc(files, sizeof(char *) * (size_t)(nout + 1));
        if (!nt || !nf) {
            times = nt ? nt : times;
            files = nf ? nf : files;
            rc = crom_err(CROM_EINTERNAL, "out of memory");
            break;
        }
        times = nt;
        files = nf;
        times[nout] = t;
        files[nout] = strdup(rel);
        nout++;
        crom_progress_update(&prog, k, NULL);
    }
    crom_progress_end(&prog);
    if (rc == 0 && res.in.complete != 1)
        crom_cli_warn(cli, "%s is incomplete (the run stopped early): exported its %d frames", res.in.name, nout);
    if (rc == 0 && !strcmp(a->format, "pvd")) {
        char path[1200];
        snprintf(path, sizeof path, "%s/%s.pvd", a->out, a->name);
        crom_fileout fo;
        if (!(rc = crom_fileout_open(&fo, path, 0))) {
            if ((rc = crom_export_pvd(fo.f, times, (const char *const *)files, nout)))
                crom_fileout_abort(&fo);
            else
                rc = crom_fileout_commit(&fo);
        }
    }
    if (rc == 0)
        crom_cli_info(cli, "wrote %d frames to %s/", nout, a->out);
    for (int i = 0; i < nout; i++)
        free(files[i]);
    free(files);
    free(times);
out:
    free(u);
    free(v);
    crom_result_close(&res);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    parse_args(&cli, &a, argc, argv);
    return crom_cli_exit(&cli, run(&cli, &a));
}
