/* crom-remesh — meshes for run-time topology changes: cut, punch, swap,
 * refine (crom/mesh to crom/mesh). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/mesh.h"
#include "mesh/remesh.h"
#include "view/export.h"

enum { SUB_CUT = 1, SUB_PUNCH, SUB_SWAP, SUB_REFINE };
static const char *sub_names[] = {"", "cut", "punch", "swap", "refine"};

enum { O_SEGMENT = 400, O_AXIS, O_STAGES, O_STAGE, O_ALLSTAGES, O_SPHERE, O_BOX, O_TRANSLATE,
       O_SCALE, O_ROTATE, O_FIT, O_TIMES };

static const crom_opt common[] = {
    {"output", 'o', "OUT", "Write the mesh to OUT (default: stdout, which must not be a terminal)."},
    {NULL, 0, NULL, NULL}};

static const crom_opt cut_opts[] = {
    {"segment", O_SEGMENT, "AU,AV,BU,BV", "A ribbon of the cut surface: the segment from A to B in the plane perpendicular to --axis, extruded along the axis through the whole mesh (repeatable). (U,V) are the other two coordinates in x,y,z order: x,z for the default axis y."},
    {"axis", O_AXIS, "x|y|z", "Extrusion axis of the ribbons (default y: vertical walls through a plate lying in the xz-plane)."},
    {"stages", O_STAGES, "N", "Number of stages the cut grows in (default 1)."},
    {"stage", O_STAGE, "K", "Which stage to write, 0..N (default N): the first K/N of each segment's length, measured from its first point, is cut. Stage 0 writes the mesh uncut (with a warning)."},
    {"all-stages", O_ALLSTAGES, "DIR", "Write every stage, DIR/stage_1.h5 ... DIR/stage_N.h5 (each complete or absent), instead of one mesh (creates DIR)."},
    {NULL, 0, NULL, NULL}};

static const crom_opt punch_opts[] = {
    {"sphere", O_SPHERE, "CX,CY,CZ,R", "Remove the tets whose centroid lies in this closed ball (R > 0; repeatable)."},
    {"box", O_BOX, "X0,Y0,Z0,X1,Y1,Z1", "Remove the tets whose centroid lies in this closed axis-aligned box (X0<X1, Y0<Y1, Z0<Z1; repeatable)."},
    {NULL, 0, NULL, NULL}};

static const crom_opt swap_opts[] = {
    {"scale", O_SCALE, "S", "Uniform scale of OTHER about the origin (S > 0, default 1), applied first."},
    {"rotate", O_ROTATE, "AX,AY,AZ,DEG", "Then rotate it about the origin, right-handed about the axis (AX,AY,AZ) by DEG degrees."},
    {"translate", O_TRANSLATE, "TX,TY,TZ", "Then translate it (m)."},
    {"fit", O_FIT, NULL, "Instead of --scale: after the rotation, scale OTHER uniformly so that its largest bounding-box extent equals the input's largest extent, and centre it on the input's bounding box (--translate is added on top)."},
    {NULL, 0, NULL, NULL}};

static const crom_opt refine_opts[] = {
    {"times", O_TIMES, "N", "Number of uniform refinements, 1..6 (default 1): each splits every tet into 8."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", common},
                                       {"cut options", cut_opts},
                                       {"punch options", punch_opts},
                                       {"swap options", swap_opts},
                                       {"refine options", refine_opts},
                                       {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-remesh",
    "cut, punch, swap or refine a mesh for run-time topology changes",
    "crom-remesh cut --segment AU,AV,BU,BV... [--axis y] [--stages N --stage K | --all-stages DIR] [-o OUT] [MESH|-]\n"
    "crom-remesh punch --sphere CX,CY,CZ,R... --box X0,Y0,Z0,X1,Y1,Z1... [-o OUT] [MESH|-]\n"
    "crom-remesh swap OTHER [--scale S] [--rotate AX,AY,AZ,DEG] [--translate TX,TY,TZ] [--fit] [-o OUT] [MESH|-]\n"
    "crom-remesh refine [--times N] [-o OUT] [MESH|-]",
    "Reads a crom/mesh (a path, or stdin) and writes another crom/mesh for a reduced simulation to "
    "switch to mid-run (LiCROM §4-6: the state lives in the latent q, not in the mesh, so the "
    "meshes need no vertex correspondence; they share the reference frame and the named regions "
    "boundary conditions use). Every output has positively oriented tets and no unused vertex, is "
    "validated, carries the input's history plus this command, and a 'generator' attribute saying "
    "what was done ('remesh cut stage 3/5').\n\n"
    "cut: splits the mesh along a cut surface made of ribbons (--segment), duplicating vertices "
    "across cut faces so that the two sides separate (LiCROM's Y-shaped tear: one stem segment and "
    "two branch segments starting at the fork, grown in N stages). An interior face shared by two "
    "tets is cut when the segment between their centroids crosses a (partial) ribbon; then the tets "
    "around each vertex are grouped into components connected through un-cut faces, and each "
    "component after the first gets its own copy of the vertex, with the vertex's region "
    "memberships. The cut follows element faces, so it is jagged at the element scale: its surface "
    "area exceeds the ribbon's (by 50-75% on unstructured gmsh meshes, less where faces happen to align), although the side it "
    "exposes has exactly the ribbon's projected area when the cut spans the body. Where a ribbon "
    "ends inside the body the crack tip stays attached.\n\n"
    "punch: removes the tets whose centroid lies in any --sphere or --box, then the vertices no tet "
    "uses; regions keep their surviving vertices, and a region left empty is dropped with a warning. "
    "Removing everything is an error (exit 65). --verbose reports the removed volume and the number "
    "of connected components left.\n\n"
    "swap: writes OTHER (a crom/mesh file) transformed into the frame of the input: scaled, rotated "
    "about the origin, translated, in that order (or fitted with --fit). OTHER keeps its own regions; "
    "in addition every region of the input made by a predicate (source 'y<-0.45', ...) is "
    "re-evaluated on the transformed OTHER under the same name, so '--pin bottom' still works after "
    "the swap. Regions from gmsh groups cannot be transferred, and a predicate that selects nothing "
    "on OTHER is skipped: both with a warning.\n\n"
    "refine: uniform 1:8 refinement by gmsh (the tets are loaded as a discrete volume and refined "
    "with gmsh's mesh refinement), --times N times. Every vertex keeps its index, a midpoint is added "
    "on every edge, the volume is unchanged (straight-sided tets) and the tet count grows 8 times per "
    "refinement. A new vertex belongs to a region when both ends of its edge do. target_size is "
    "halved per refinement.",
    groups,
    "crom-mesh plate --size 0.05 | crom-remesh cut --segment 0,-0.6,0,0 --segment 0,0,-0.3,0.3 --segment 0,0,0.3,0.3 --stages 4 --stage 2 -o tear2.h5\n"
    "crom-remesh cut --segment 0,-0.6,0,0 --segment 0,0,-0.3,0.3 --segment 0,0,0.3,0.3 --stages 4 --all-stages tear/ plate.h5\n"
    "crom-remesh punch --sphere 0.2,0.2,0.2,0.15 --box -0.5,-0.1,-0.1,0.5,0.1,0.1 < cube.h5 > holed.h5\n"
    "crom-remesh swap bunny.h5 --fit < armadillo.h5 > bunny_in_frame.h5\n"
    "crom-remesh refine --times 2 box.h5 | crom-info -",
    "crom-mesh(1), crom-info(1), crom-export(1), crom-cubature(1), crom-reducedstep(1)"};

#define MAX_ITEMS 256

typedef struct {
    int sub;
    const char *other, *input, *out, *alldir;
    int given[O_TIMES + 1 - O_SEGMENT]; /* which subcommand options were given */
    double seg[MAX_ITEMS][4];
    int nseg, axis;
    long stages, stage;
    int stage_given;
    crom_remesh_punch_shape shapes[MAX_ITEMS];
    int nshapes;
    crom_remesh_xform xf;
    long times;
} args;

static int opt_sub(int key)
{
    if (key >= O_SEGMENT && key <= O_ALLSTAGES)
        return SUB_CUT;
    if (key == O_SPHERE || key == O_BOX)
        return SUB_PUNCH;
    if (key >= O_TRANSLATE && key <= O_FIT)
        return SUB_SWAP;
    return SUB_REFINE;
}

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    double d[6];
    if (key >= O_SEGMENT && key <= O_TIMES)
        a->given[key - O_SEGMENT]++;
    switch (key) {
    case 0:
        if (!a->sub) {
            for (int s = SUB_CUT; s <= SUB_REFINE; s++)
                if (!strcmp(v, sub_names[s]))
                    a->sub = s;
            if (!a->sub)
                return crom_err(CROM_EUSAGE, "unknown subcommand '%s' (cut, punch, swap, refine)", v);
        } else if (a->sub == SUB_SWAP && !a->other) {
            a->other = v;
        } else if (!a->input) {
            a->input = v;
        } else {
            return crom_err(CROM_EUSAGE, "unexpected operand '%s'", v);
        }
        return 0;
    case 'o': a->out = v; return 0;
    case O_SEGMENT:
        if (a->nseg == MAX_ITEMS)
            return crom_err(CROM_EUSAGE, "too many --segment (at most %d)", MAX_ITEMS);
        if (crom_parse_doubles(v, "--segment", 4, d))
            return CROM_EUSAGE;
        if (d[0] == d[2] && d[1] == d[3])
            return crom_err(CROM_EUSAGE, "--segment %s has zero length", v);
        memcpy(a->seg[a->nseg++], d, 4 * sizeof(double));
        return 0;
    case O_AXIS:
        if (strlen(v) != 1 || v[0] < 'x' || v[0] > 'z')
            return crom_err(CROM_EUSAGE, "--axis: '%s' is not x, y or z", v);
        a->axis = v[0] - 'x';
        return 0;
    case O_STAGES: return crom_parse_int(v, "--stages", 1, 100000, &a->stages);
    case O_STAGE:
        a->stage_given = 1;
        return crom_parse_int(v, "--stage", 0, 100000, &a->stage);
    case O_ALLSTAGES: a->alldir = v; return 0;
    case O_SPHERE:
    case O_BOX: {
        int n = key == O_SPHERE ? 4 : 6;
        if (a->nshapes == MAX_ITEMS)
            return crom_err(CROM_EUSAGE, "too many --sphere/--box (at most %d)", MAX_ITEMS);
        if (crom_parse_doubles(v, key == O_SPHERE ? "--sphere" : "--box", n, d))
            return CROM_EUSAGE;
        crom_remesh_punch_shape *s = &a->shapes[a->nshapes++];
        s->kind = key == O_SPHERE ? CROM_REMESH_PUNCH_SPHERE : CROM_REMESH_PUNCH_BOX;
        memcpy(s->a, d, sizeof(double) * (size_t)n);
        if (key == O_SPHERE && !(d[3] > 0))
            return crom_err(CROM_EUSAGE, "--sphere: the radius must be positive, got %g", d[3]);
        if (key == O_BOX && !(d[0] < d[3] && d[1] < d[4] && d[2] < d[5]))
            return crom_err(CROM_EUSAGE, "--box %s: needs X0<X1, Y0<Y1, Z0<Z1", v);
        return 0;
    }
    case O_SCALE: return crom_parse_positive(v, "--scale", &a->xf.scale);
    case O_ROTATE:
        if (crom_parse_doubles(v, "--rotate", 4, d))
            return CROM_EUSAGE;
        if (d[0] == 0 && d[1] == 0 && d[2] == 0)
            return crom_err(CROM_EUSAGE, "--rotate %s: the axis must be non-zero", v);
        memcpy(a->xf.axis, d, 3 * sizeof(double));
        a->xf.deg = d[3];
        return 0;
    case O_TRANSLATE: return crom_parse_doubles(v, "--translate", 3, a->xf.translate);
    case O_FIT: a->xf.fit = 1; return 0;
    case O_TIMES: return crom_parse_int(v, "--times", 1, 6, &a->times);
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* A usage error found after parsing: one line, exit 64. */
static void usage(crom_cli *cli, const char *fmt, const char *s1, const char *s2)
{
    char msg[256];
    snprintf(msg, sizeof msg, fmt, s1, s2);
    crom_err(CROM_EUSAGE, "%s (see %s --help)", msg, cli->prog);
    exit(crom_cli_exit(cli, CROM_EUSAGE));
}

static void parse_args(crom_cli *cli, args *a, int argc, char **argv)
{
    memset(a, 0, sizeof *a);
    a->axis = 1;
    a->stages = 1;
    a->times = 1;
    crom_remesh_xform_init(&a->xf);
    crom_cli_parse(cli, &doc, argc, argv, on_opt, a);
    if (!a->sub)
        usage(cli, "no subcommand given (cut, punch, swap or refine)%s%s", "", "");
    for (int k = O_SEGMENT; k <= O_TIMES; k++)
        if (a->given[k - O_SEGMENT] && opt_sub(k) != a->sub) {
            const char *name = "?";
            for (int g = 1; groups[g].heading; g++)
                for (const crom_opt *o = groups[g].opts; o->name; o++)
                    if (o->key == k)
                        name = o->name;
            usage(cli, "--%s is not an option of %s", name, sub_names[a->sub]);
        }
    switch (a->sub) {
    case SUB_CUT:
        if (!a->nseg)
            usage(cli, "cut needs at least one --segment AU,AV,BU,BV%s%s", "", "");
        if (!a->stage_given)
            a->stage = a->stages;
        if (a->stage > a->stages) {
            char k[32], n[32];
            snprintf(k, sizeof k, "%ld", a->stage);
            snprintf(n, sizeof n, "%ld", a->stages);
            usage(cli, "--stage %s is beyond --stages %s", k, n);
        }
        if (a->alldir && (a->stage_given || a->out))
            usage(cli, "--all-stages writes every stage into a directory: drop %s%s",
                  a->stage_given ? "--stage" : "-o", "");
        break;
    case SUB_PUNCH:
        if (!a->nshapes)
            usage(cli, "punch needs at least one --sphere or --box%s%s", "", "");
        break;
    case SUB_SWAP:
        if (!a->other)
            usage(cli, "swap needs the OTHER mesh as an operand%s%s", "", "");
        if (a->xf.fit && a->given[O_SCALE - O_SEGMENT])
            usage(cli, "--fit and --scale exclude each other%s%s", "", "");
        break;
    }
}

static void on_warn(void *ctx, const char *msg)
{
    crom_cli_warn(ctx, "%s", msg);
}

/* Read a crom/mesh from path (NULL or "-": stdin); *history and *size (the
 * target_size attribute, NAN if absent) may be NULL. */
static int read_mesh(const char *path, crom_mesh *m, char **history, double *size)
{
    crom_in in;
    int rc = crom_in_open(&in, path);
    if (rc)
        return rc;
    if ((rc = crom_in_expect(&in, CROM_MESH_SCHEMA, CROM_MESH_VERSION))) {
        crom_in_close(&in);
        return rc;
    }
    hid_t root = H5Gopen2(in.h5, "/", H5P_DEFAULT);
    rc = root < 0 ? crom_err(CROM_EDATA, "%s: cannot open the root group", in.name)
                  : crom_mesh_read(root, m);
    if (rc)
        crom_err_ctx("%s", in.name);
    if (!rc && size) {
        *size = NAN;
        if (crom_h5_has_attr(root, ".", "target_size") &&
            crom_h5_get_f64(root, ".", "target_size", size, 1))
            *size = NAN;
        crom_err_clear();
    }
    if (root >= 0)
        H5Gclose(root);
    if (!rc && history)
        *history = crom_strdup(in.history ? in.history : "");
    crom_in_close(&in);
    return rc;
}

/* Write m (atomically when path is a file) with the generator attribute. */
static int write_mesh(const crom_cli *cli, const char *path, const char *history,
                      const crom_mesh *m, const char *generator, double size)
{
    crom_out o;
    int rc = crom_out_create(&o, path, CROM_MESH_SCHEMA, CROM_MESH_VERSION, cli->cmdline, history,
                             CROM_OUT_PLAIN);
    if (rc)
        return rc;
    rc = crom_mesh_write(o.h5, m);
    if (!rc)
        rc = crom_h5_set_str(o.h5, ".", "generator", generator);
    if (!rc && isfinite(size))
        rc = crom_h5_set_f64(o.h5, ".", "target_size", &size, 1);
    if (!rc)
        rc = crom_out_commit(&o);
    else
        crom_out_fail(&o);
    return rc;
}

static void summary(const crom_cli *cli, const char *what, const crom_mesh *m)
{
    double worst, mean;
    int wt;
    crom_mesh_quality(m, &worst, &mean, &wt);
    crom_cli_info(cli, "%s: %d vertices, %d tets, volume %.6g m^3, quality worst %.3f mean %.3f", what,
                  m->nv, m->nt, crom_mesh_volume(m), worst, mean);
}

static int run_cut(crom_cli *cli, args *a, const crom_mesh *m, const char *hist, double size)
{
    crom_remesh_cut_opts c = {a->axis, a->nseg, &a->seg[0][0], (int)a->stages, (int)a->stage};
    int k0 = a->alldir ? 1 : (int)a->stage, k1 = a->alldir ? (int)a->stages : (int)a->stage, rc = 0;
    if (a->alldir && (rc = crom_export_mkdir(a->alldir)))
        return rc;
    for (int k = k0; k <= k1 && !rc; k++) {
        crom_mesh out;
        crom_remesh_cut_stats st;
        char gen[96], path[1200];
        c.stage = k;
        if ((rc = crom_remesh_cut(m, &c, &out, &st, on_warn, (void *)cli)))
            break;
        snprintf(gen, sizeof gen, "remesh cut stage %d/%d", k, (int)a->stages);
        if (cli->verbose)
            crom_cli_info(cli, "stage %d/%d: %d faces cut, %d vertices duplicated, %d connected component%s",
                          k, (int)a->stages, st.faces_cut, st.verts_dup, st.components,
                          st.components == 1 ? "" : "s");
        if (a->alldir)
            snprintf(path, sizeof path, "%s/stage_%d.h5", a->alldir, k);
        rc = write_mesh(cli, a->alldir ? path : a->out, hist, &out, gen, size);
        crom_mesh_free(&out);
    }
    return rc;
}

static int run(crom_cli *cli, args *a)
{
    crom_mesh m, other, out;
    char *hist = NULL, gen[600];
    double size = NAN;
    int rc = read_mesh(a->input, &m, &hist, &size);
    if (rc)
        return rc;
    if (cli->verbose)
        summary(cli, "input", &m);
    memset(&out, 0, sizeof out);
    switch (a->sub) {
    case SUB_CUT:
        rc = run_cut(cli, a, &m, hist, size);
        goto done;
    case SUB_PUNCH: {
        int nrem = 0;
        if ((rc = crom_remesh_punch(&m, a->shapes, a->nshapes, &out, &nrem, on_warn, cli)))
            break;
        snprintf(gen, sizeof gen, "remesh punch %d shape%s", a->nshapes, a->nshapes == 1 ? "" : "s");
        if (cli->verbose) {
            int nc = crom_remesh_components(&out, NULL);
            crom_cli_info(cli, "removed %d of %d tets (%.6g m^3); %d connected component%s", nrem, m.nt,
                          crom_mesh_volume(&m) - crom_mesh_volume(&out), nc, nc == 1 ? "" : "s");
        }
        break;
    }
    case SUB_SWAP:
        if ((rc = read_mesh(a->other, &other, NULL, NULL)))
            break;
        rc = crom_remesh_swap(&m, &other, &a->xf, &out, on_warn, cli);
        crom_mesh_free(&other);
        if (rc)
            break;
        snprintf(gen, sizeof gen, "remesh swap %.500s", a->other);
        size = NAN; /* OTHER's own size, scaled: not known */
        break;
    case SUB_REFINE:
        if ((rc = crom_remesh_refine(&m, (int)a->times, &out, cli->verbose > 1 ? crom_cli_log_line : NULL, cli)))
            break;
        snprintf(gen, sizeof gen, "remesh refine x%d", (int)a->times);
        if (isfinite(size))
            size = ldexp(size, -(int)a->times);
        break;
    }
    if (!rc) {
        if (cli->verbose)
            summary(cli, "output", &out);
        rc = write_mesh(cli, a->out, hist, &out, gen, size);
    }
done:
    crom_mesh_free(&out);
    crom_mesh_free(&m);
    free(hist);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    parse_args(&cli, &a, argc, argv);
    return crom_cli_exit(&cli, run(&cli, &a));
}
