/* crom-export — write meshes and trajectories (of solids and of shell
 * surfaces) as files other tools open: VTU (+ PVD for a series) and
 * XDMF+HDF5 for ParaView and meshio, MSH for gmsh, surface OBJ, PLY and STL,
 * PNG pictures and strips. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "phys/rigidsys.h"
#include "rom/result.h"
#include "view/export.h"
#include "view/follow.h"
#include "view/picture.h"

enum { O_FORMAT = 300, O_FRAME, O_EVERY, O_NAME, O_MESH, O_MODEL, O_COMPARE, O_COLUMNS, O_PANEL, O_RANGE, O_FOLLOW,
       O_YOUNGS, O_POISSON };

static const crom_opt export_opts[] = {
    {"format", O_FORMAT, "FMT", "vtu, pvd, xdmf, msh, obj, ply, stl, png (a picture per frame), or strip (one PNG: the input and each --compare side by side, rows, at --columns times). Default: from the extension of OUT; pvd when OUT ends in '/'."},
    {"output", 'o', "OUT", "Output file. pvd: OUT.pvd with its frames in OUT/ beside it (OUT/OUT_00000.vtu, ...), or, for any other name or one ending in '/', a directory holding NAME.pvd and NAME_00000.vtu, ...; xdmf: OUT.xdmf with its heavy data OUT.xdmf.h5 beside it, or a directory (NAME.xdmf and NAME.xdmf.h5 in it); vtu/obj/ply/stl/png with --frame all: a directory (created if needed)."},
    {"frame", O_FRAME, "K", "Which frame of a series to write for vtu/obj/ply/stl/png: an index (negative counts from the end; default -1, the last) or 'all' for one file per frame."},
    {"every", O_EVERY, "K", "With pvd, xdmf, msh, strip or --frame all: keep every K-th frame (default 1)."},
    {"name", O_NAME, "BASE", "File name stem inside an output directory (default 'frame': frame.pvd, frame_00000.vtu, ...); -o OUT.pvd and -o OUT.xdmf name their files themselves."},
    {"mesh", O_MESH, "MESH", "For a crom/latent: the mesh to decode onto (any tet mesh: the training mesh, a finer one for display, another shape; a trajectory or cubature carrying a mesh will do; not a shell surface). For a trajectory: a mesh of the same kind (tets or a shell) with the same vertices, e.g. to add regions."},
    {"model", O_MODEL, "MODEL", "The crom/model that decodes a crom/latent: u(X) = W(X) q."},
    {"follow-schedule", O_FOLLOW, NULL, "For a crom/latent run with a --schedule (cuts, punches, swaps): decode each frame on the mesh of the cubature in use at that frame, read from the latent's 'cubatures' record (the files must still be there); --mesh, if given, stands in for the first. The latent must be a file (it is read once per mesh). Applies to --compare latents too."},
    {"compare", O_COMPARE, "RESULT", "strip: another result (trajectory, or latent decoded with --model/--mesh) drawn as a further row (repeatable), e.g. the full run under the reduced one."},
    {"columns", O_COLUMNS, "K", "strip: frames shown per row, evenly spaced in time (default 6)."},
    {"panel", O_PANEL, "WxH", "png, strip: pixels of one picture (default 360x300)."},
    {"range", O_RANGE, "UMAX", "png, strip: colour |u| over [0, UMAX] m (default: the largest |u| of all frames shown)."},
    {"youngs", O_YOUNGS, "E", "vtu, pvd, xdmf: Young's modulus (Pa) of the cell data 'energy_density' and 'von_mises_stress' (default: the input's 'youngs' attribute, which trajectories and reduced runs carry)."},
    {"poisson", O_POISSON, "NU", "vtu, pvd, xdmf: Poisson ratio of the same (default: the input's 'poisson' attribute). When the input records no material and none is given, those two fields are left out (with a note)."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", export_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-export",
    "write crom meshes, trajectories and decoded latent runs as VTU/PVD, XDMF, MSH, OBJ, PLY, STL or PNG",
    "crom-export --format vtu|pvd|xdmf|msh|obj|ply|stl|png|strip [options] -o OUT [MESH|TRAJ|-]\n"
    "crom-export --format vtu|pvd|xdmf|msh|obj|ply|stl|png|strip --model MODEL --mesh MESH -o OUT [LATENT|-]",
    "Reads a crom/mesh, a crom/trajectory, or a crom/latent decoded through a model onto any "
    "mesh (HDF5 file or frame stream, from a path or stdin) and writes files ParaView, meshio "
    "and mesh viewers open.\n\n"
    "vtu: the tetrahedral mesh on its rest positions; for a trajectory frame the point data "
    "'displacement' (m) and 'velocity' (m/s) (use ParaView's Warp By Vector on 'displacement'), the "
    "frame's time as field data 'TimeValue' (s), and cell data per tet: 'volume' (rest volume, m^3), "
    "'J' (det F), 'energy_density' (stable neo-Hookean strain energy per rest volume, J/m^3) and "
    "'von_mises_stress' (von Mises equivalent of the Cauchy stress, Pa; NaN where J <= 0), from the "
    "element kernel crom-fullsim uses and the material of --youngs/--poisson. A latent run gets the "
    "same fields from its decoded displacement. Every named region becomes a 0/1 point field "
    "'region_NAME'. A bare mesh has 'volume' only. Times are written with the fewest digits that "
    "read back as the same double.\n\n"
    "pvd: a .pvd collection with the frame times and one VTU per frame (-o run.pvd: run.pvd and "
    "run/run_00000.vtu, ...; -o DIR/: DIR/frame.pvd and DIR/frame_00000.vtu, ...), written frame by "
    "frame as a stream arrives.\n\n"
    "xdmf: an XDMF 3 temporal collection (XML) and one HDF5 file beside it (OUT.xdmf.h5) holding the mesh "
    "(/mesh/vertices, /mesh/tets, /mesh/region_NAME), the frame times (/time) and one dataset "
    "per frame (/displacement/00000, /velocity/00000, /J/00000, ...; each with a 'units' "
    "attribute); each frame is a Tetrahedron grid with 'displacement', 'velocity' and the region "
    "masks as node attributes and the cell data of vtu as cell attributes ('volume' from "
    "/mesh/volume). ParaView (Xdmf3 "
    "reader) and meshio (meshio.xdmf.TimeSeriesReader) read it. A bare mesh becomes one "
    "grid. With --follow-schedule a frame refers to the mesh in use then (/mesh_1, ...).\n\n"
    "msh: a gmsh MSH 4.1 file written by gmsh (one discrete volume of linear tets) with, for a "
    "series, the views 'displacement' (m) and 'velocity' (m/s) as NodeData, one step per "
    "(--every-th) frame at its time (gmsh prints 16 digits). It holds one mesh: a run that "
    "switches meshes needs pvd or xdmf.\n\n"
    "obj, ply, stl: the boundary surface in its deformed position, outward oriented (binary PLY "
    "adds |u| per vertex as 'displacement_magnitude'; STL is ASCII, written by gmsh); --frame all "
    "writes a numbered sequence into a directory.\n\n"
    "png, strip: pictures rendered without a display: the deformed boundary surface, shaded and "
    "coloured by |u| on one colour scale, from a fixed camera. strip puts several results side by "
    "side (rows) at the same times (columns) for a quick look without ParaView.\n\n"
    "Shells: a shell surface (a crom/mesh of triangles, crom-mesh sheet) and its trajectories "
    "(crom-fullsim) export to every format as their triangles: vtu cells are VTK_TRIANGLE (5), "
    "xdmf grids a Triangle topology (/mesh/triangles), msh one discrete surface, obj/ply/stl and "
    "png the triangles themselves, both sides drawn. Their cell data per triangle: 'area' (rest "
    "area, m^2; in place of 'volume'), 'J' (the deformed over the rest area) and "
    "'energy_density' (the membrane stretching energy per rest volume, thickness x area, J/m^3, "
    "from the membrane kernel crom-fullsim uses; bending lives on edges and is left out) and "
    "'von_mises_stress' (of the membrane stress F S F^T / J in the deformed plane, Pa; the "
    "bending stresses at the faces are left out). A crom/latent is decoded onto tet meshes, or onto the "
    "shell its model (modes, energy, neuralmodes) was made on.\n\n"
    "Rigid-body scenes (crom-scene) and their runs are shown by their bodies' shapes: each body's "
    "box, sphere or capsule as closed triangles (spheres and capsules in 12 latitude rings) that "
    "move with the body's frame, exported like a shell surface (a region per body).\n\n"
    "Every output appears only when complete (written to a temporary file and renamed).",
    groups,
    "crom-mesh box | crom-export --format vtu -o box.vtu\n"
    "crom-fullsim @compress.flags < box.h5 | crom-export -o out/run.pvd   # run.pvd + run/run_*.vtu\n"
    "crom-export --format xdmf -o run.xdmf traj.h5          # run.xdmf + run.xdmf.h5\n"
    "crom-export --format obj --frame all -o surf/ traj.h5\n"
    "crom-export -o run.msh traj.h5 && gmsh run.msh        # views 'displacement', 'velocity'\n"
    "crom-export --format strip --model m.h5 --mesh box.h5 --compare full.h5 -o strip.png reduced.h5\n"
    "crom-export --format pvd --model m.h5 --follow-schedule -o punch.pvd punched_run.h5",
    "crom-mesh(1), crom-fullsim(1), crom-reducedstep(1), crom-info(1)"};

typedef struct {
    const char *input, *out, *format, *name, *mesh, *model;
    const char *compare[8];
    int ncompare, columns, pw, ph;
    double range, youngs, poisson;
    long frame;
    int all, every, follow;
    int dir, named; /* -o ended in '/'; --name given */
} args;

/* the formats; all but the last follow from -o's extension too */
static const char *const formats[] = {"vtu", "pvd", "xdmf", "msh", "obj", "ply", "stl", "png", "strip", NULL};

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
        a->format = NULL;
        for (int i = 0; formats[i]; i++)
            if (!strcmp(v, formats[i]))
                a->format = formats[i];
        return a->format ? 0 : crom_err(CROM_EUSAGE, "--format: '%s' is not vtu, pvd, xdmf, msh, obj, ply, stl, png or strip", v);
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
        a->named = 1;
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
    case O_PANEL: { /* WxH, two decimal integers (crom_parse_int: no signs, hex or trailing text) */
        const char *x = strchr(v, 'x');
        char w[16];
        long pw, ph;
        if (!x || x == v || (size_t)(x - v) >= sizeof w || !(v[0] >= '0' && v[0] <= '9') ||
            !(x[1] >= '0' && x[1] <= '9'))
            return crom_err(CROM_EUSAGE, "--panel: '%s' is not WxH with 32..4096 pixels", v);
        memcpy(w, v, (size_t)(x - v));
        w[x - v] = 0;
        if (crom_parse_int(w, "--panel", 32, 4096, &pw) || crom_parse_int(x + 1, "--panel", 32, 4096, &ph))
            return crom_err(CROM_EUSAGE, "--panel: '%s' is not WxH with 32..4096 pixels", v);
        a->pw = (int)pw;
        a->ph = (int)ph;
        return 0;
    }
    case O_RANGE: return crom_parse_positive(v, "--range", &a->range);
    case O_YOUNGS: return crom_parse_positive(v, "--youngs", &a->youngs);
    case O_POISSON: return crom_parse_double(v, "--poisson", &a->poisson);
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
    a->youngs = a->poisson = NAN;
    crom_cli_parse(cli, &doc, argc, argv, on_opt, a);
    /* trailing slashes of a directory are noise in the file names we print */
    if (a->out) {
        static char outbuf[1024];
        snprintf(outbuf, sizeof outbuf, "%s", a->out);
        size_t l = strlen(outbuf);
        while (l > 1 && outbuf[l - 1] == '/')
            outbuf[--l] = 0;
        a->dir = strcmp(outbuf, a->out) != 0;
        a->out = outbuf;
        if (a->dir && !a->format)
            a->format = "pvd";
    }
    if (!a->format && a->out) {
        for (int i = 0; formats[i + 1]; i++) {
            char ext[8];
            snprintf(ext, sizeof ext, ".%s", formats[i]);
            if (ends_with(a->out, ext))
                a->format = formats[i];
        }
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
    else if (a->named && !a->dir && !strcmp(a->format, "pvd") && ends_with(a->out, ".pvd"))
        err = "--name names the files in an output directory; -o OUT.pvd names them itself (OUT/OUT_00000.vtu)";
    if (err)
        exit(crom_cli_exit(cli, crom_err(CROM_EUSAGE, "%s (see crom-export --help)", err)));
}

static const char *base_name(const char *p)
{
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

/* How a series is laid out: pvd is OUT.pvd with its frames beside it, or
 * a directory (-o DIR/, or a name without .pvd) */
static int series_kind(const args *a)
{
    if (!strcmp(a->format, "xdmf") || !strcmp(a->format, "msh"))
        return a->format[0] == 'x' ? CROM_EXPORT_SERIES_XDMF : CROM_EXPORT_SERIES_MSH;
    if (strcmp(a->format, "pvd"))
        return CROM_EXPORT_SERIES_FILES;
    return !a->dir && ends_with(a->out, ".pvd") ? CROM_EXPORT_SERIES_PVD_FILE : CROM_EXPORT_SERIES_PVD_DIR;
}

/* The frame on mesh mi with displacement u, velocity v at time t, and its
 * cell fields when cells is not NULL. */
static int frame_at(crom_follow *s, int mi, const double *u, const double *v, double t, crom_export_cells *cells,
                    crom_export_frame *fr)
{
    *fr = (crom_export_frame){&s->res[mi].mesh, u, v, t, cells};
    return cells ? crom_export_cells_eval(cells, fr->mesh, u) : 0;
}

/* A bare mesh: one file (or one picture) */
static int export_mesh(crom_cli *cli, args *a, crom_in *probe)
{
    int rc = crom_in_expect(probe, "crom/mesh", 1);
    crom_mesh m;
    hid_t root = rc ? -1 : H5Gopen2(probe->h5, "/", H5P_DEFAULT);
    if (!rc && (rc = crom_mesh_read_flags(root, CROM_MESH_SURFACES | CROM_MESH_SCENES, &m)))
        crom_err_ctx("%s", probe->name);
    if (!rc && m.scene) { /* a rigid-body scene: its bodies' shapes */
        crom_mesh d;
        double *beta;
        int *body;
        rc = crom_rigidsys_display(&m, CROM_RESULT_DISPLAY_RINGS, &d, &beta, &body);
        crom_mesh_free(&m);
        if (!rc) {
            free(beta);
            free(body);
            m = d;
        }
    }
    if (root >= 0)
        H5Gclose(root);
    char *history = probe->history ? crom_strdup(probe->history) : NULL;
    crom_in_close(probe);
    if (rc) {
        free(history);
        return rc;
    }
    const char *inputs[1] = {a->input};
    if (!strcmp(a->format, "png")) {
        crom_image im;
        char path[1400];
        snprintf(path, sizeof path, "%s", a->out ? a->out : "-");
        if (a->all && !(rc = crom_export_mkdir(a->out)))
            snprintf(path, sizeof path, "%s/%s.png", a->out, a->name);
        if (!rc && !(rc = crom_picture_mesh(&im, &m, a->pw, a->ph)))
            rc = crom_image_save(&im, path);
        crom_image_free(&im);
    } else {
        rc = crom_export_mesh(&m, series_kind(a), a->format, a->out, a->name, a->dir, a->all, inputs, 1, cli->cmdline, history);
    }
    free(history);
    crom_mesh_free(&m);
    return rc;
}

/* vtu/obj/ply of one frame: the --frame-th (negative: from the end) */
static int export_one_frame(args *a, crom_follow *s, crom_export_cells *cells)
{
    size_t n3 = 3 * (size_t)(s->maxnv ? s->maxnv : 1);
    double *u = crom_malloc(sizeof(double) * 2 * n3), t;
    long nframes;
    int mi, rc = u ? crom_follow_pick(s, a->frame, &mi, &t, u, u + n3, &nframes) : CROM_EINTERNAL;
    crom_export_frame fr;
    if (!rc && !(rc = frame_at(s, mi, u, u + n3, t, cells, &fr)))
        rc = crom_export_write(a->out ? a->out : "-", a->format, &fr);
    free(u);
    return rc;
}

/* pvd, or vtu/obj/ply/stl with --frame all: one file per frame, as frames
 * arrive; xdmf: one heavy-data file and its XML; msh: one file */
static int export_series(crom_cli *cli, args *a, crom_follow *s, crom_export_cells *cells)
{
    const char *inputs[11] = {a->input, a->mesh, a->model};
    for (int i = 0; i < a->ncompare; i++)
        inputs[3 + i] = a->compare[i];
    int kind = series_kind(a);
    crom_export_sink k;
    int rc = crom_export_sink_open(&k, kind, a->format, a->out, a->name, a->dir, inputs, 3 + a->ncompare, s->n, cli->cmdline,
                                   s->res[0].in.history);
    if (rc)
        return rc;
    crom_cli_progress prog;
    crom_cli_progress_start(&prog, cli, "export", s->res[0].in.form == CROM_IO_H5 ? s->res[0].in.nframes : 0);
    long i = 0;
    double t;
    crom_export_frame fr;
    while ((rc = crom_follow_next(s, &t)) == 1) {
        if (i++ % a->every)
            continue;
        if ((rc = frame_at(s, s->cur, s->u[s->cur], s->v[s->cur], t, cells, &fr)) ||
            (rc = crom_export_sink_frame(&k, s->cur, &fr)))
            break;
        crom_cli_progress_update(&prog, i, NULL);
    }
    crom_cli_progress_end(&prog);
    if (!rc && k.n == 0 && kind >= CROM_EXPORT_SERIES_XDMF)
        rc = crom_err(CROM_EDATA, "%s has no frames", s->res[0].in.name);
    if (rc) {
        crom_export_sink_abort(&k);
        return rc;
    }
    if (s->res[0].in.complete != 1)
        crom_cli_warn(cli, "%s is incomplete (the run stopped early): exported its %d frames", s->res[0].in.name, k.n);
    if (cells && cells->degenerate && crom_mesh_is_surface(&s->res[0].mesh))
        crom_cli_warn(cli, "%ld degenerate triangles (over all frames): NaN in their J and energy density",
                      cells->degenerate);
    else if (cells && cells->degenerate)
        crom_cli_warn(cli, "%ld degenerate tets (over all frames): NaN in their J, energy density and stress",
                      cells->degenerate);
    int n = k.n;
    char where[2600];
    if (kind == CROM_EXPORT_SERIES_XDMF)
        snprintf(where, sizeof where, "%s (heavy data %s)", k.xdmf.xml, k.xdmf.h5);
    else if (kind == CROM_EXPORT_SERIES_PVD_FILE)
        snprintf(where, sizeof where, "%s (frames in %s/)", k.files.pvd, k.files.dir);
    else
        snprintf(where, sizeof where, kind == CROM_EXPORT_SERIES_MSH ? "%s" : "%s/", a->out ? a->out : "stdout");
    if (!(rc = crom_export_sink_finish(&k)))
        crom_cli_info(cli, "wrote %d frames to %s", n, where);
    return rc;
}

/* png: one picture per frame (a directory) or the --frame-th; strip: rows
 * of results (the input and each --compare), columns of times */
static int export_pictures(crom_cli *cli, args *a, crom_follow *src)
{
    int nrows = !strcmp(a->format, "strip") ? 1 + a->ncompare : 1, rc = 0;
    crom_follow_frames rows[9];
    const char *labels[9] = {a->input ? base_name(a->input) : "stdin"};
    memset(rows, 0, sizeof rows);
    rc = crom_follow_load(&rows[0], src, a->every);
    for (int i = 1; i < nrows && !rc; i++) { /* --compare: further rows */
        labels[i] = base_name(a->compare[i - 1]);
        rc = crom_follow_load_path(&rows[i], a->compare[i - 1], a->mesh, a->model, a->follow, a->every);
    }
    crom_image im = {0};
    int K;
    long n;
    if (!rc && !strcmp(a->format, "strip")) {
        if (!(rc = crom_picture_strip(&im, rows, labels, nrows, a->columns, a->pw, a->ph, a->range, &K)) &&
            !(rc = crom_image_save(&im, a->out ? a->out : "-")))
            crom_cli_info(cli, "wrote a %d x %d strip (%d rows, %d columns) to %s", im.w, im.h, nrows, K,
                          a->out ? a->out : "stdout");
    } else if (!rc && !(rc = crom_picture_write(&rows[0], a->all, a->frame, a->out, a->name, a->pw, a->ph, a->range,
                                                &n)) && a->all) {
        crom_cli_info(cli, "wrote %ld pictures to %s/", n, a->out);
    }
    crom_image_free(&im);
    for (int i = 0; i < nrows; i++)
        crom_follow_frames_free(&rows[i]);
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
    crom_follow s;
    if ((rc = crom_follow_adopt(&s, &probe, a->input, a->mesh, a->model, a->follow)))
        return rc;
    if (!strcmp(a->format, "png") || !strcmp(a->format, "strip"))
        return export_pictures(cli, a, &s);
    for (int i = 0; i < s.n; i++)
        if (crom_follow_outside(&s, i))
            crom_cli_warn(cli, "%zu vertices of the mesh lie outside the model's mesh: W is extended there",
                          crom_follow_outside(&s, i));
    /* cell data (vtu, pvd, xdmf) with the run's material, if known */
    crom_material mat;
    crom_export_cells cells = {0}, *cp = NULL;
    int known = 0;
    if (!strcmp(a->format, "vtu") || !strcmp(a->format, "pvd") || !strcmp(a->format, "xdmf")) {
        cp = &cells;
        if (!(rc = crom_export_material(&mat, &known, &s.res[0].in, a->youngs, a->poisson)) && known > 0)
            cells.mat = &mat;
        else if (!rc && known < 0)
            crom_cli_info(cli, "%s has regions of other materials: cell data without energy_density and "
                          "von_mises_stress (one material for all is --youngs E --poisson NU)", s.res[0].in.name);
        else if (!rc)
            crom_cli_info(cli, "%s records no material: cell data without energy_density%s (give --youngs and "
                          "--poisson)", s.res[0].in.name,
                          crom_mesh_is_surface(&s.res[0].mesh) ? "" : " and von_mises_stress");
    }
    if (!rc && (series_kind(a) != CROM_EXPORT_SERIES_FILES || a->all))
        rc = export_series(cli, a, &s, cp);
    else if (!rc)
        rc = export_one_frame(a, &s, cp);
    crom_export_cells_free(&cells);
    crom_follow_close(&s);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    parse_args(&cli, &a, argc, argv);
    return crom_cli_exit(&cli, run(&cli, &a));
}
