/* crom-export — write meshes and trajectories as files other tools open:
 * VTU (+ PVD for a series) and XDMF+HDF5 for ParaView and meshio, surface OBJ
 * and PLY, PNG pictures and strips. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "err.h"
#include "export.h"
#include "io.h"
#include "mesh.h"
#include "render.h"
#include "result.h"

enum { O_FORMAT = 300, O_FRAME, O_EVERY, O_NAME, O_MESH, O_MODEL, O_COMPARE, O_COLUMNS, O_PANEL, O_RANGE, O_FOLLOW };

static const crom_opt export_opts[] = {
    {"format", O_FORMAT, "FMT", "vtu, pvd, xdmf, obj, ply, png (a picture per frame), or strip (one PNG: the input and each --compare side by side, rows, at --columns times). Default: from the extension of OUT; pvd when OUT ends in '/'."},
    {"output", 'o', "OUT", "Output file; for pvd, and for obj/ply/png with --frame all, a directory (created if needed); for xdmf OUT.xdmf (heavy data in OUT.xdmf.h5 beside it) or a directory (NAME.xdmf and NAME.xdmf.h5 in it)."},
    {"frame", O_FRAME, "K", "Which frame of a series to write for vtu/obj/ply/png: an index (negative counts from the end; default -1, the last) or 'all' for one file per frame."},
    {"every", O_EVERY, "K", "With pvd, xdmf, strip or --frame all: keep every K-th frame (default 1)."},
    {"name", O_NAME, "BASE", "File name stem inside the output directory (default 'frame': frame.pvd, frame_00000.vtu, ...)."},
    {"mesh", O_MESH, "MESH", "For a crom/latent: the mesh to decode onto (any mesh: the training mesh, a finer one for display, another shape; a trajectory or cubature carrying a mesh will do). For a trajectory: a mesh with the same vertices, e.g. to add regions."},
    {"model", O_MODEL, "MODEL", "The crom/model that decodes a crom/latent: u(X) = W(X) q."},
    {"follow-schedule", O_FOLLOW, NULL, "For a crom/latent run with a --schedule (cuts, punches, swaps): decode each frame on the mesh of the cubature in use at that frame, read from the latent's 'cubatures' record (the files must still be there); --mesh, if given, stands in for the first. The latent must be a file (it is read once per mesh). Applies to --compare latents too."},
    {"compare", O_COMPARE, "RESULT", "strip: another result (trajectory, or latent decoded with --model/--mesh) drawn as a further row (repeatable), e.g. the full run under the reduced one."},
    {"columns", O_COLUMNS, "K", "strip: frames shown per row, evenly spaced in time (default 6)."},
    {"panel", O_PANEL, "WxH", "png, strip: pixels of one picture (default 360x300)."},
    {"range", O_RANGE, "UMAX", "png, strip: colour |u| over [0, UMAX] m (default: the largest |u| of all frames shown)."},
    {NULL, 0, NULL, NULL}};

static const crom_optgroup groups[] = {{"Options", export_opts}, {NULL, NULL}};

static const crom_doc doc = {
    "crom-export",
    "write crom meshes, trajectories and decoded latent runs as VTU/PVD, XDMF, OBJ, PLY or PNG",
    "crom-export --format vtu|pvd|xdmf|obj|ply|png|strip [options] -o OUT [MESH|TRAJ|-]\n"
    "crom-export --format vtu|pvd|xdmf|obj|ply|png|strip --model MODEL --mesh MESH -o OUT [LATENT|-]",
    "Reads a crom/mesh, a crom/trajectory, or a crom/latent decoded through a model onto any "
    "mesh (HDF5 file or frame stream, from a path or stdin) and writes files ParaView, meshio "
    "and mesh viewers open.\n\n"
    "vtu: the tetrahedral mesh on its rest positions; for a trajectory frame the point data "
    "'displacement' and 'velocity' (use ParaView's Warp By Vector on 'displacement'). Every "
    "named region becomes a 0/1 point field 'region_NAME'.\n\n"
    "pvd: a directory holding one VTU per frame and a .pvd collection with the frame times, "
    "written frame by frame as a stream arrives.\n\n"
    "xdmf: an XDMF 3 temporal collection (XML) and one HDF5 file beside it (OUT.xdmf.h5) holding the mesh "
    "(/mesh/vertices, /mesh/tets, /mesh/region_NAME), the frame times (/time) and one dataset "
    "per frame (/displacement/00000, /velocity/00000, ...); each frame is a Tetrahedron grid "
    "with 'displacement', 'velocity' and the region masks as node attributes. ParaView (Xdmf3 "
    "reader) and meshio (meshio.xdmf.TimeSeriesReader) read it. A bare mesh becomes one "
    "grid. With --follow-schedule a frame refers to the mesh in use then (/mesh_1, ...).\n\n"
    "obj, ply: the boundary surface in its deformed position (binary PLY adds |u| per vertex); "
    "--frame all writes a numbered sequence into a directory.\n\n"
    "png, strip: pictures rendered without a display: the deformed boundary surface, shaded and "
    "coloured by |u| on one colour scale, from a fixed camera. strip puts several results side by "
    "side (rows) at the same times (columns) for a quick look without ParaView.\n\n"
    "Every output appears only when complete (written to a temporary file and renamed).",
    groups,
    "crom-mesh box | crom-export --format vtu -o box.vtu\n"
    "crom-fullsim @compress.flags < box.h5 | crom-export --format pvd -o out/\n"
    "crom-export --format xdmf -o run.xdmf traj.h5          # run.xdmf + run.xdmf.h5\n"
    "crom-export --format obj --frame all -o surf/ traj.h5\n"
    "crom-export --format strip --model m.h5 --mesh box.h5 --compare full.h5 -o strip.png reduced.h5\n"
    "crom-export --format pvd --model m.h5 --follow-schedule -o punch/ punched_run.h5",
    "crom-mesh(1), crom-fullsim(1), crom-reducedstep(1), crom-info(1)"};

typedef struct {
    const char *input, *out, *format, *name, *mesh, *model;
    const char *compare[8];
    int ncompare, columns, pw, ph;
    double range;
    long frame;
    int all, every, follow;
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
        if (strcmp(v, "vtu") && strcmp(v, "pvd") && strcmp(v, "xdmf") && strcmp(v, "obj") && strcmp(v, "ply") &&
            strcmp(v, "png") && strcmp(v, "strip"))
            return crom_err(CROM_EUSAGE, "--format: '%s' is not vtu, pvd, xdmf, obj, ply, png or strip", v);
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
        if (!*v || strchr(v, '/') || strchr(v, ':'))
            return crom_err(CROM_EUSAGE, "--name: '%s' must be a plain file name stem", v);
        a->name = v;
        return 0;
    case O_MESH: a->mesh = v; return 0;
    case O_MODEL: a->model = v; return 0;
    case O_FOLLOW: a->follow = 1; return 0;
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
        static const char *ext[] = {".vtu", ".pvd", ".xdmf", ".obj", ".ply", ".png"};
        for (int i = 0; i < 6; i++)
            if (ends_with(a->out, ext[i]))
                a->format = ext[i] + 1;
        if (!a->format && ends_with(a->out, "/"))
            a->format = "pvd";
    }
    const char *err = NULL;
    if (!a->format)
        err = "no --format given and none follows from -o";
    else if (!a->out && (!strcmp(a->format, "pvd") || !strcmp(a->format, "xdmf") || a->all))
        err = "pvd, xdmf and --frame all write several files: give -o";
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

/* ------------------------------------------------------------- sources
 * A result to export: a trajectory or a latent decoded on one mesh, or with
 * --follow-schedule a latent decoded on the mesh of the cubature in use at
 * each frame (one crom_result per mesh, read in lockstep). */

typedef struct {
    int n;            /* meshes */
    crom_result *res; /* [n]: the same result decoded on each mesh */
    double **u, **v;  /* [n] frame buffers [nv][3] */
    int fcub;         /* the latent's per-frame 'cubature' field, or -1 */
    int cur;          /* mesh of the frame last read */
    int maxnv;
} source;

static void source_close(source *s)
{
    for (int i = 0; i < s->n; i++) {
        crom_result_close(&s->res[i]);
        if (s->u)
            free(s->u[i]);
        if (s->v)
            free(s->v[i]);
    }
    free(s->res);
    free(s->u);
    free(s->v);
    memset(s, 0, sizeof *s);
}

/* The cubature files of a latent's schedule: its 'cubatures' attribute, one
 * "STEP PATH" line per entry (entry 0 the initial --cubature). */
static int schedule_paths(crom_in *in, char ***paths, int *n)
{
    *paths = NULL;
    *n = 0;
    if (in->h5 < 0 || !crom_h5_has_attr(in->h5, ".", "cubatures"))
        return 0;
    char *txt = NULL;
    if (crom_h5_get_str(in->h5, ".", "cubatures", &txt))
        return crom_err_ctx("%s", in->name);
    int cap = 1;
    for (const char *p = txt; *p; p++)
        cap += *p == '\n';
    char **list = crom_calloc((size_t)cap, sizeof(char *));
    if (!list) {
        free(txt);
        return CROM_EINTERNAL;
    }
    int k = 0, rc = 0;
    for (char *line = strtok(txt, "\n"); line && !rc; line = strtok(NULL, "\n")) {
        long step;
        int pos = 0;
        if (sscanf(line, "%ld %n", &step, &pos) != 1 || !line[pos]) {
            rc = crom_err(CROM_EDATA, "%s: bad 'cubatures' entry '%s'", in->name, line);
            break;
        }
        if (!(list[k++] = crom_strdup(line + pos)))
            rc = CROM_EINTERNAL;
    }
    free(txt);
    if (rc) {
        for (int i = 0; i < k; i++)
            free(list[i]);
        free(list);
        return rc;
    }
    *paths = list;
    *n = k;
    return 0;
}

/* Open a source over an input already open (taken over, closed on failure);
 * path names it again for --follow-schedule. */
static int source_adopt(source *s, crom_in *opened, const char *path, const args *a)
{
    memset(s, 0, sizeof *s);
    s->fcub = -1;
    char **paths = NULL;
    int np = 0, rc = 0;
    int follow = a->follow && !strcmp(opened->schema, "crom/latent");
    if (follow && (rc = schedule_paths(opened, &paths, &np))) {
        crom_in_close(opened);
        return rc;
    }
    if (follow && np > 1 && (!path || !strcmp(path, "-"))) {
        crom_in_close(opened);
        rc = crom_err(CROM_EUSAGE, "--follow-schedule reads the latent once per mesh: give it as a file, not stdin");
        goto out;
    }
    s->n = np > 1 ? np : 1;
    s->res = crom_calloc((size_t)s->n, sizeof(crom_result));
    s->u = crom_calloc((size_t)s->n, sizeof(double *));
    s->v = crom_calloc((size_t)s->n, sizeof(double *));
    if (!s->res || !s->u || !s->v) {
        crom_in_close(opened);
        s->n = 0;
        rc = CROM_EINTERNAL;
        goto out;
    }
    const char *mesh0 = a->mesh ? a->mesh : (np > 0 ? paths[0] : NULL);
    int opened_n = 0;
    rc = crom_result_adopt(&s->res[0], opened, mesh0, a->model);
    if (!rc)
        opened_n = 1;
    for (int i = 1; i < s->n && !rc; i++) {
        if (!(rc = crom_result_open(&s->res[i], path, paths[i], a->model)))
            opened_n = i + 1;
        else
            crom_err_ctx("schedule entry %d", i);
    }
    if (!rc && s->n > 1) {
        s->fcub = crom_in_field(&s->res[0].in, "cubature");
        if (s->fcub < 0)
            rc = crom_err(CROM_EDATA, "%s has a schedule but no per-frame 'cubature' field", s->res[0].in.name);
    }
    for (int i = 0; i < s->n && !rc; i++) {
        size_t n3 = 3 * (size_t)s->res[i].mesh.nv;
        s->u[i] = crom_malloc(sizeof(double) * (n3 ? n3 : 1));
        s->v[i] = crom_malloc(sizeof(double) * (n3 ? n3 : 1));
        if (!s->u[i] || !s->v[i])
            rc = CROM_EINTERNAL;
        if (s->res[i].mesh.nv > s->maxnv)
            s->maxnv = s->res[i].mesh.nv;
    }
    if (rc) {
        int n = s->n;
        s->n = opened_n; /* close only what was opened */
        for (int i = opened_n; i < n; i++) {
            free(s->u[i]);
            free(s->v[i]);
        }
        source_close(s);
    }
out:
    for (int i = 0; i < np; i++)
        free(paths[i]);
    free(paths);
    return rc;
}

/* Read the next frame: 1 (time in *t, data in s->u[s->cur], s->v[s->cur]),
 * 0 at the end, or an error code. */
static int source_next(source *s, double *t)
{
    int rc = 0;
    for (int i = 0; i < s->n; i++) {
        double ti;
        int r = crom_result_next(&s->res[i], &ti, s->u[i], s->v[i]);
        if (i == 0) {
            rc = r;
            *t = ti;
        } else if (r != rc) {
            return r > 1 ? r : crom_err(CROM_EDATA, "%s changed while it was read", s->res[0].in.name);
        }
    }
    s->cur = 0;
    if (rc == 1 && s->n > 1) {
        double c = crom_in_get(&s->res[0].in, s->fcub)[0];
        if (!(c >= 0 && c < s->n))
            return crom_err(CROM_EDATA, "%s: a frame uses schedule entry %g of %d", s->res[0].in.name, c, s->n);
        s->cur = (int)c;
    }
    return rc;
}

static void source_warn_outside(const crom_cli *cli, const source *s)
{
    for (int i = 0; i < s->n; i++)
        if (s->res[i].outside)
            crom_cli_warn(cli, "%zu vertices of the mesh lie outside the model's mesh: W is extended there",
                          s->res[i].outside);
}

/* ------------------------------------------------------------ pictures */

typedef struct {
    source src;
    int nf;
    double *t, *u; /* [nf], frames one after another: frame f at u + off[f] */
    size_t *off;
    int *mi;       /* [nf] mesh of frame f */
    int *ntri, **tris; /* per mesh: the boundary surface */
    const char *label;
} row;

static void free_row(row *r)
{
    for (int i = 0; i < r->src.n; i++)
        if (r->tris)
            free(r->tris[i]);
    source_close(&r->src);
    free(r->t);
    free(r->u);
    free(r->off);
    free(r->mi);
    free(r->ntri);
    free(r->tris);
}

static const crom_mesh *row_mesh(const row *r, int f) { return &r->src.res[r->mi[f]].mesh; }

/* Read every (--every-th) frame of a result into memory, with the boundary
 * surface of each of its meshes. */
static int load_row(row *r, const args *a)
{
    size_t cap = 16, ucap = 16 * 3 * (size_t)(r->src.maxnv ? r->src.maxnv : 1), used = 0;
    r->t = crom_malloc(sizeof(double) * cap);
    r->off = crom_malloc(sizeof(size_t) * cap);
    r->mi = crom_malloc(sizeof(int) * cap);
    r->u = crom_malloc(sizeof(double) * ucap);
    r->ntri = crom_calloc((size_t)r->src.n, sizeof(int));
    r->tris = crom_calloc((size_t)r->src.n, sizeof(int *));
    if (!r->t || !r->off || !r->mi || !r->u || !r->ntri || !r->tris)
        return CROM_EINTERNAL;
    int rc;
    double t;
    long k = 0;
    while ((rc = source_next(&r->src, &t)) == 1) {
        if (k++ % a->every)
            continue;
        size_t n3 = 3 * (size_t)r->src.res[r->src.cur].mesh.nv;
        if ((size_t)r->nf == cap) {
            cap *= 2;
            double *nt = crom_realloc(r->t, sizeof(double) * cap);
            if (nt)
                r->t = nt;
            size_t *no = nt ? crom_realloc(r->off, sizeof(size_t) * cap) : NULL;
            if (no)
                r->off = no;
            int *nm = no ? crom_realloc(r->mi, sizeof(int) * cap) : NULL;
            if (!nm)
                return CROM_EINTERNAL;
            r->mi = nm;
        }
        if (used + n3 > ucap) {
            while (used + n3 > ucap)
                ucap *= 2;
            double *nu = crom_realloc(r->u, sizeof(double) * ucap);
            if (!nu)
                return CROM_EINTERNAL;
            r->u = nu;
        }
        memcpy(r->u + used, r->src.u[r->src.cur], sizeof(double) * n3);
        r->t[r->nf] = t;
        r->off[r->nf] = used;
        r->mi[r->nf] = r->src.cur;
        r->nf++;
        used += n3;
    }
    if (rc)
        return rc;
    if (r->nf == 0)
        return crom_err(CROM_EDATA, "%s has no frames", r->src.res[0].in.name);
    for (int i = 0; i < r->src.n; i++)
        if ((rc = crom_mesh_boundary(&r->src.res[i].mesh, &r->ntri[i], &r->tris[i], NULL)))
            return rc;
    return 0;
}

/* camera and colour range shared by all pictures */
static void frame_all(row *rows, int nrows, const args *a, int pw, int ph, crom_camera *cam, double *umax)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, m = 0;
    for (int r = 0; r < nrows; r++) {
        for (int f = -1; f < rows[r].nf; f++) {
            const crom_mesh *mesh = f < 0 ? &rows[r].src.res[0].mesh : row_mesh(&rows[r], f);
            const double *u = f < 0 ? NULL : rows[r].u + rows[r].off[f];
            for (int i = 0; i < mesh->nv; i++) {
                double d2 = 0;
                for (int c = 0; c < 3; c++) {
                    double d = u ? u[3 * i + c] : 0;
                    double x = mesh->X[3 * i + c] + d;
                    lo[c] = fmin(lo[c], x);
                    hi[c] = fmax(hi[c], x);
                    d2 += d * d;
                }
                m = fmax(m, sqrt(d2));
            }
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

static void render_frame(crom_image *im, const crom_camera *cam, int x0, int y0, int pw, int ph, const row *r,
                         int f, double umax, const char *label, double *work)
{
    const crom_mesh *m = row_mesh(r, f);
    crom_render_panel(im, cam, x0, y0, pw, ph, m->nv, m->X, r->u + r->off[f], r->ntri[r->mi[f]],
                      r->tris[r->mi[f]], umax, label, work);
}

/* --format png: one picture per frame (a directory) or the --frame-th */
static int run_png(crom_cli *cli, args *a, source *src)
{
    row r = {0};
    r.src = *src;
    memset(src, 0, sizeof *src);
    int rc = load_row(&r, a);
    crom_camera cam;
    double umax;
    crom_image im = {0};
    double *work = NULL;
    if (rc)
        goto out;
    frame_all(&r, 1, a, a->pw, a->ph, &cam, &umax);
    work = crom_malloc(sizeof(double) * 4 * (size_t)(r.src.maxnv ? r.src.maxnv : 1));
    if (!work) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    int series = a->all;
    long first = 0, last = r.nf - 1;
    if (!series) {
        long k = a->frame < 0 ? r.nf + a->frame : a->frame;
        if (k < 0 || k >= r.nf) {
            rc = crom_err(CROM_EUSAGE, "--frame %ld: %s has %d frames", a->frame, r.src.res[0].in.name, r.nf);
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
        render_frame(&im, &cam, 0, 0, a->pw, a->ph, &r, (int)f, umax, label, work);
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
    free_row(&r);
    return rc;
}

/* --format strip: rows of results, columns of times, one colour scale */
static int run_strip(crom_cli *cli, args *a, source *src)
{
    int nrows = 1 + a->ncompare, rc = 0;
    row *rows = crom_calloc((size_t)nrows, sizeof(row));
    if (!rows)
        return CROM_EINTERNAL;
    rows[0].src = *src;
    memset(src, 0, sizeof *src);
    rows[0].label = a->input ? base_name(a->input) : "stdin";
    for (int i = 0; i < a->ncompare && !rc; i++) {
        /* --mesh decodes latents; a compared trajectory keeps its own mesh */
        crom_in in;
        if (!(rc = crom_in_open(&in, a->compare[i]))) {
            args b = *a;
            if (strcmp(in.schema, "crom/latent"))
                b.mesh = NULL;
            rc = source_adopt(&rows[i + 1].src, &in, a->compare[i], &b);
        }
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
        maxnv = rows[i].src.maxnv > maxnv ? rows[i].src.maxnv : maxnv;
    crom_camera cam;
    double umax;
    frame_all(rows, nrows, a, a->pw, a->ph, &cam, &umax);
    work = crom_malloc(sizeof(double) * 4 * (size_t)(maxnv ? maxnv : 1));
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
            render_frame(&im, &cam, c * a->pw, r * a->ph, a->pw, a->ph, &rows[r], best, umax, label, work);
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

/* ---------------------------------------------------------------- XDMF */

static int same_file(const char *p, const char *q)
{
    struct stat a, b;
    return p && q && strcmp(p, "-") && stat(p, &a) == 0 && stat(q, &b) == 0 && a.st_dev == b.st_dev &&
           a.st_ino == b.st_ino;
}

/* OUT.xdmf -> OUT.xdmf + OUT.xdmf.h5 (a name no crom file has, so the heavy
 * data never replace an input); anything else is a directory holding
 * NAME.xdmf + NAME.xdmf.h5. h5name is the heavy-data file's name relative to
 * the XML. */
static int xdmf_paths(const args *a, char *xml, char *h5, size_t n, const char **h5name)
{
    if (ends_with(a->out, ".xdmf")) {
        snprintf(xml, n, "%s", a->out);
    } else {
        int rc = make_dir(a->out);
        if (rc)
            return rc;
        snprintf(xml, n, "%s/%s.xdmf", a->out, a->name);
    }
    snprintf(h5, n, "%s.h5", xml);
    *h5name = base_name(h5);
    if (strchr(*h5name, ':'))
        return crom_err(CROM_EUSAGE, "-o %s: XDMF cannot refer to a file name with ':' in it", a->out);
    const char *inputs[11] = {a->input, a->mesh, a->model};
    for (int i = 0; i < a->ncompare; i++)
        inputs[3 + i] = a->compare[i];
    for (int i = 0; i < 3 + a->ncompare; i++)
        if (same_file(inputs[i], h5) || same_file(inputs[i], xml))
            return crom_err(CROM_EUSAGE, "-o %s would overwrite the input %s", a->out, inputs[i]);
    return 0;
}

/* The XML after the heavy data are in place; on failure the heavy data go
 * too, so nothing is left that looks complete. */
static int xdmf_finish(const char *xml, const char *h5, const char *h5name, const crom_mesh *const *meshes,
                       const char *const *grp, const double *time, const int *mesh_of, int nframes)
{
    static const char *const fields[] = {"displacement", "velocity"};
    crom_fileout fo;
    int rc = crom_fileout_open(&fo, xml, 0);
    if (!rc) {
        if ((rc = crom_export_xdmf(fo.f, h5name, meshes, grp, time, mesh_of, nframes, fields, nframes ? 2 : 0))) {
            crom_fileout_abort(&fo);
            crom_err_ctx("%s", xml);
        } else {
            rc = crom_fileout_commit(&fo);
        }
    }
    if (rc)
        unlink(h5);
    return rc;
}

static int xdmf_mesh(crom_cli *cli, const args *a, const crom_mesh *m, const char *history)
{
    char xml[1200], h5[1200];
    const char *h5name;
    int rc = xdmf_paths(a, xml, h5, sizeof xml, &h5name);
    if (rc)
        return rc;
    crom_out o;
    if ((rc = crom_out_create(&o, h5, "xdmf/heavy-data", 1, cli, history, CROM_OUT_PLAIN)))
        return rc;
    if ((rc = crom_xdmf_write_mesh(o.h5, "mesh", m))) {
        crom_out_fail(&o);
        return crom_err_ctx("%s", h5);
    }
    if ((rc = crom_out_commit(&o)))
        return rc;
    const char *grp = "mesh";
    return xdmf_finish(xml, h5, h5name, &m, &grp, NULL, NULL, 0);
}

static int run_xdmf(crom_cli *cli, const args *a, source *s)
{
    char xml[1200], h5[1200];
    const char *h5name;
    int rc = xdmf_paths(a, xml, h5, sizeof xml, &h5name);
    if (rc)
        return rc;
    crom_out o;
    if ((rc = crom_out_create(&o, h5, "xdmf/heavy-data", 1, cli, s->res[0].in.history, CROM_OUT_PLAIN)))
        return rc;
    const crom_mesh **meshes = crom_calloc((size_t)s->n, sizeof(crom_mesh *));
    char **grp = crom_calloc((size_t)s->n, sizeof(char *));
    double *times = NULL;
    int *mesh_of = NULL, nout = 0, cap = 0;
    crom_progress prog;
    crom_progress_start(&prog, cli, "export", s->res[0].in.form == CROM_FORM_H5 ? s->res[0].in.nframes : 0);
    if (!meshes || !grp) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    double t;
    long k = 0;
    while ((rc = source_next(s, &t)) == 1) {
        if (k++ % a->every)
            continue;
        int mi = s->cur;
        const crom_mesh *m = &s->res[mi].mesh;
        if (!meshes[mi]) { /* the first frame on this mesh: write it */
            char g[32];
            if (mi == 0)
                snprintf(g, sizeof g, "mesh");
            else
                snprintf(g, sizeof g, "mesh_%d", mi);
            if (!(grp[mi] = crom_strdup(g)) || (rc = crom_xdmf_write_mesh(o.h5, g, m)))
                break;
            meshes[mi] = m;
        }
        if ((rc = crom_xdmf_write_frame(o.h5, "displacement", nout, m->nv, s->u[mi])) ||
            (rc = crom_xdmf_write_frame(o.h5, "velocity", nout, m->nv, s->v[mi])))
            break;
        if (nout == cap) {
            cap = cap ? 2 * cap : 64;
            double *nt = crom_realloc(times, sizeof(double) * (size_t)cap);
            if (nt)
                times = nt;
            int *nm = nt ? crom_realloc(mesh_of, sizeof(int) * (size_t)cap) : NULL;
            if (!nm) {
                rc = CROM_EINTERNAL;
                break;
            }
            mesh_of = nm;
        }
        times[nout] = t;
        mesh_of[nout++] = mi;
        crom_progress_update(&prog, k, NULL);
    }
    crom_progress_end(&prog);
    if (!rc && nout == 0)
        rc = crom_err(CROM_EDATA, "%s has no frames", s->res[0].in.name);
    if (!rc) {
        hsize_t d = (hsize_t)nout;
        rc = crom_h5_write_f64(o.h5, "time", 1, &d, times, "s", "time of each frame");
    }
    if (rc) {
        crom_out_fail(&o);
        crom_err_ctx("%s", h5);
        goto out;
    }
    if (s->res[0].in.complete != 1)
        crom_cli_warn(cli, "%s is incomplete (the run stopped early): exported its %d frames", s->res[0].in.name,
                      nout);
    if ((rc = crom_out_commit(&o)))
        goto out;
    rc = xdmf_finish(xml, h5, h5name, meshes, (const char *const *)grp, times, mesh_of, nout);
    if (!rc)
        crom_cli_info(cli, "wrote %d frames to %s (heavy data %s)", nout, xml, h5);
out:
    for (int i = 0; grp && i < s->n; i++)
        free(grp[i]);
    free(grp);
    free(meshes);
    free(times);
    free(mesh_of);
    return rc;
}

/* ------------------------------------------------------------ the rest */

static int export_mesh(crom_cli *cli, args *a, crom_in *probe)
{
    int rc = crom_in_expect(probe, "crom/mesh", 1);
    crom_mesh m;
    hid_t root = rc ? -1 : H5Gopen2(probe->h5, "/", H5P_DEFAULT);
    if (!rc && (rc = crom_mesh_read(root, &m)))
        crom_err_ctx("%s", probe->name);
    if (root >= 0)
        H5Gclose(root);
    char *history = probe->history ? crom_strdup(probe->history) : NULL;
    crom_in_close(probe);
    if (rc) {
        free(history);
        return rc;
    }
    if (!strcmp(a->format, "xdmf")) {
        rc = xdmf_mesh(cli, a, &m, history);
        free(history);
        crom_mesh_free(&m);
        return rc;
    }
    free(history);
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

/* vtu/obj/ply of one frame: the --frame-th (negative: from the end) */
static int export_one_frame(args *a, source *s)
{
    size_t maxn3 = 3 * (size_t)(s->maxnv ? s->maxnv : 1);
    long nread = 0, want = a->frame;
    /* negative --frame counts from the end: keep the last -frame frames */
    long keep = want < 0 ? -want : 1;
    double *ring = crom_malloc(sizeof(double) * 2 * maxn3 * (size_t)keep);
    int *ring_mi = crom_malloc(sizeof(int) * (size_t)keep);
    if (!ring || !ring_mi) {
        free(ring);
        free(ring_mi);
        return CROM_EINTERNAL;
    }
    int r2, rc = 0;
    double t;
    while ((r2 = source_next(s, &t)) == 1) {
        long slot = want >= 0 ? 0 : nread % keep;
        if (want < 0 || nread == want) {
            size_t n3 = 3 * (size_t)s->res[s->cur].mesh.nv;
            memcpy(ring + (size_t)slot * 2 * maxn3, s->u[s->cur], sizeof(double) * n3);
            memcpy(ring + (size_t)slot * 2 * maxn3 + maxn3, s->v[s->cur], sizeof(double) * n3);
            ring_mi[slot] = s->cur;
        }
        nread++;
    }
    if (r2 > 1)
        rc = r2;
    else if ((want >= 0 && want >= nread) || (want < 0 && -want > nread))
        rc = crom_err(CROM_EUSAGE, "--frame %ld: %s has %ld frames", want, a->input ? a->input : "stdin", nread);
    else {
        long slot = want >= 0 ? 0 : (nread + want) % keep;
        const double *u = ring + (size_t)slot * 2 * maxn3;
        rc = write_one(a->out ? a->out : "-", a->format, &s->res[ring_mi[slot]].mesh, u, u + maxn3);
    }
    free(ring);
    free(ring_mi);
    return rc;
}

/* pvd, or obj/ply/vtu with --frame all: one file per frame, as frames arrive */
static int export_series(crom_cli *cli, args *a, source *s)
{
    int rc = make_dir(a->out);
    if (rc)
        return rc;
    const char *ext = !strcmp(a->format, "pvd") ? "vtu" : a->format;
    double *times = NULL;
    char **files = NULL;
    int nout = 0;
    crom_progress prog;
    crom_progress_start(&prog, cli, "export", s->res[0].in.form == CROM_FORM_H5 ? s->res[0].in.nframes : 0);
    long k = 0;
    double t;
    while ((rc = source_next(s, &t)) == 1) {
        if (k++ % a->every)
            continue;
        char rel[256], path[1400];
        snprintf(rel, sizeof rel, "%s_%05d.%s", a->name, nout, ext);
        snprintf(path, sizeof path, "%s/%s", a->out, rel);
        if ((rc = write_one(path, a->format, &s->res[s->cur].mesh, s->u[s->cur], s->v[s->cur])))
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
    if (rc == 0 && s->res[0].in.complete != 1)
        crom_cli_warn(cli, "%s is incomplete (the run stopped early): exported its %d frames", s->res[0].in.name,
                      nout);
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
    return rc;
}

static int run(crom_cli *cli, args *a)
{
    crom_in probe;
    int rc = crom_in_open(&probe, a->input);
    if (rc)
        return rc;
    if (!strcmp(probe.schema, "crom/mesh")) /* a bare mesh: one file */
        return export_mesh(cli, a, &probe);
    /* a trajectory, or a latent decoded through --model onto --mesh (or the
     * meshes of its schedule) */
    source s;
    if ((rc = source_adopt(&s, &probe, a->input, a)))
        return rc;
    if (!strcmp(a->format, "png"))
        rc = run_png(cli, a, &s);
    else if (!strcmp(a->format, "strip"))
        rc = run_strip(cli, a, &s);
    else {
        source_warn_outside(cli, &s);
        if (!strcmp(a->format, "xdmf"))
            rc = run_xdmf(cli, a, &s);
        else if (!strcmp(a->format, "pvd") || a->all)
            rc = export_series(cli, a, &s);
        else
            rc = export_one_frame(a, &s);
    }
    source_close(&s);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    parse_args(&cli, &a, argc, argv);
    return crom_cli_exit(&cli, run(&cli, &a));
}
