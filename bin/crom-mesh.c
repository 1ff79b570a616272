/* crom-mesh — make a tetrahedral mesh (crom/mesh) of a shape or a file, or a
 * shell surface (a sheet). */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/err.h"
#include "cli/cli.h"
#include "io/io.h"
#include "mesh/meshgen.h"

enum { O_SIZE = 'S' + 256, O_DIMS, O_RADIUS, O_HEIGHT, O_EXP, O_REGION, O_ALGO, O_NOOPT,
       O_REMESH, O_KEEP, O_TIMEOUT, O_THICK, O_UNSTRUCT, O_PLANE };

static const crom_opt mesh_opts[] = {
    {"output", 'o', "OUT", "Write the mesh to OUT (default: stdout, which must not be a terminal)."},
    {"size", O_SIZE, "H", "Target edge length in metres (default 0.1)."},
    {"dims", O_DIMS, "X,Y,Z", "Extents of box, plate and superquadric, centred at the origin (default 1,1,1; plate 1,0.05,1). sheet: X by Y in the xy-plane (Z is not used)."},
    {"plane-strain", O_PLANE, NULL, "sheet, disk, import of a surface in z = 0: make a 2-D solid in plane strain instead of a shell: the triangles are a body of depth --thickness (default 0.001) whose every section deforms alike (stable neo-Hookean in plane strain, no bending term beyond the triangles'; crom-fullsim, crom-modes, crom-fitfield energy|neuralmodes, crom-reducedstep --model and crom-export take it like a shell)."},
    {"unstructured", O_UNSTRUCT, NULL, "sheet: mesh the rectangle with gmsh (unstructured triangles of edge about --size) instead of regular rows."},
    {"thickness", O_THICK, "T", "Make a thin shell of this thickness in metres: sheet, disk (default 0.001), or import of an .stl/.obj surface, open or closed, whose triangles become the shell's (subdivided until no edge exceeds --size), or of the 3-node triangles of a gmsh .msh surface, kept as they are, its physical groups becoming regions."},
    {"radius", O_RADIUS, "R", "Radius of sphere, cylinder and disk (default 0.5)."},
    {"height", O_HEIGHT, "H", "Height of the cylinder along y (default 1)."},
    {"exponent", O_EXP, "P", "Superquadric exponent: |x/a|^P+|y/b|^P+|z/c|^P <= 1; 2 is an ellipsoid, large P approaches the box (default 4)."},
    {"region", O_REGION, "NAME=PRED", "Store the vertices selected by PRED as region NAME (repeatable). PRED: x<V, y>=V, box:X0,Y0,Z0,X1,Y1,Z1, sphere:CX,CY,CZ,R, plane:NX,NY,NZ,D, all, joined by '&'. Imported gmsh physical groups become regions of their own name."},
    {"algorithm", O_ALGO, "NAME", "gmsh 3D algorithm: delaunay (default; repeatable output) or hxt (faster on big meshes, output varies slightly between runs)."},
    {"no-optimize", O_NOOPT, NULL, "Skip gmsh's tetrahedron optimization."},
    {"remesh", O_REMESH, NULL, "import of .stl/.obj: let gmsh reparametrize and remesh the surface at --size (better elements; can be slow on bad surfaces). This is the default when the surface is much finer than --size (median edge below half of it), and crom-mesh says so in one line."},
    {"keep-surface", O_KEEP, NULL, "import of .stl/.obj: keep the file's triangles, split until no edge exceeds --size. This is the default when the surface is not much finer than --size; on a much finer one it gives far more vertices than --size suggests (crom-mesh says how many triangles it keeps)."},
    {"timeout", O_TIMEOUT, "S", "Give up meshing after S seconds (default 600): bad surfaces can make gmsh spin."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", mesh_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-mesh",
    "make a tetrahedral mesh of a shape or a surface/volume file, or a shell sheet",
    "crom-mesh box|plate|sphere|cylinder|superquadric [options] [-o OUT]\n"
    "crom-mesh import FILE [options] [-o OUT]\n"
    "crom-mesh sheet [--dims X,Y,Z] [--size H] [--thickness T] [--unstructured] [options] [-o OUT]\n"
    "crom-mesh disk [--radius R] [--size H] [--thickness T] [options] [-o OUT]\n"
    "crom-mesh import FILE.obj|FILE.stl|FILE.msh --thickness T [--size H] [options] [-o OUT]",
    "Meshes a shape centred at the origin, or the inside of a closed .stl/.obj surface, or "
    "a .msh/.geo volume, with gmsh, and writes a crom/mesh file: rest positions, positively "
    "oriented tetrahedra and named vertex regions.\n\n"
    "The superquadric family |x/a|^p+|y/b|^p+|z/c|^p <= 1 spans sphere (p = 2) to cube (large "
    "p); LiCROM's five training shapes are superquadrics in the bounding cube [-0.5,0.5]^3.\n\n"
    "sheet makes a thin shell instead (crom-fullsim simulates it with a StVK membrane and "
    "discrete-shell bending): the rectangle X by Y in the xy-plane, in rows of near-equilateral "
    "triangles of edge about --size (straight sides: each row ends in half-triangles), with "
    "--thickness stored in the mesh; disk makes a round one of --radius in the xy-plane, meshed by "
    "gmsh. import with --thickness makes a shell of the triangles of "
    "an .stl/.obj surface or of a gmsh .msh surface mesh (its physical groups become regions), open "
    "or closed (consistently oriented, each edge shared by at most two triangles).\n\n"
    "Nothing but the mesh goes to stdout. With --verbose the vertex and tet counts, the volume "
    "and the worst element quality (mean ratio, 1 = regular) are printed on stderr.",
    groups,
    "crom-mesh box --size 0.05 --region top='y>0.45' --region bottom='y<-0.45' -o box.h5\n"
    "crom-mesh superquadric --exponent 3 --size 0.05 | crom-info -\n"
    "crom-mesh import bunny.stl --size 0.02 -o bunny.h5\n"
    "crom-mesh sheet --dims 1,1,1 --size 0.02 --thickness 0.002 --region top='y>0.49' -o sheet.h5",
    "crom-info(1), crom-export(1), crom-fullsim(1), crom-remesh(1)"};

typedef struct {
    crom_meshgen_opts gen;  /* filled from the options after parsing */
    const char *shape, *file, *out;
    char **regions;
    int nregions;
    double size, dims[3], radius, height, exponent, timeout, thickness;
    int exponent_given;
    int algorithm, no_optimize, remesh, unstructured, plane;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    switch (key) {
    case 0:
        if (!a->shape)
            a->shape = v;
        else if (!a->file && !strcmp(a->shape, "import"))
            a->file = v;
        else
            return crom_err(CROM_EUSAGE, "unexpected operand '%s'", v);
        return 0;
    case 'o': a->out = v; return 0;
    case O_SIZE: return crom_parse_positive(v, "--size", &a->size);
    case O_DIMS:
        if (crom_parse_doubles(v, "--dims", 3, a->dims))
            return CROM_EUSAGE;
        if (!(a->dims[0] > 0 && a->dims[1] > 0 && a->dims[2] > 0))
            return crom_err(CROM_EUSAGE, "--dims must be three positive extents, got %s", v);
        return 0;
    case O_RADIUS: return crom_parse_positive(v, "--radius", &a->radius);
    case O_HEIGHT: return crom_parse_positive(v, "--height", &a->height);
    case O_EXP: /* any value given is used (0 too, and refused by the range check) */
        a->exponent_given = 1;
        return crom_parse_double(v, "--exponent", &a->exponent);
    case O_REGION: {
        size_t len = strcspn(v, "=");
        for (int i = 0; i < a->nregions; i++)
            if (!strncmp(a->regions[i], v, len) && a->regions[i][len] == '=' && v[len] == '=')
                return crom_err(CROM_EUSAGE, "--region: region '%.*s' is given twice", (int)len, v);
        char **r = realloc(a->regions, sizeof(char *) * (size_t)(a->nregions + 1));
        if (!r)
            return crom_err(CROM_EINTERNAL, "out of memory");
        a->regions = r;
        a->regions[a->nregions++] = (char *)v;
        return 0;
    }
    case O_ALGO:
        if (!strcmp(v, "delaunay"))
            a->algorithm = 1;
        else if (!strcmp(v, "hxt"))
            a->algorithm = 10;
        else
            return crom_err(CROM_EUSAGE, "--algorithm: '%s' is not delaunay or hxt", v);
        return 0;
    case O_NOOPT: a->no_optimize = 1; return 0;
    case O_REMESH: a->remesh = 1; return 0;
    case O_KEEP: a->remesh = 0; return 0;
    case O_TIMEOUT: return crom_parse_positive(v, "--timeout", &a->timeout);
    case O_THICK: return crom_parse_positive(v, "--thickness", &a->thickness);
    case O_UNSTRUCT: a->unstructured = 1; return 0;
    case O_PLANE: a->plane = 1; return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* The first option given that only a tet mesh uses, or NULL */
static const char *solid_flag(const args *a)
{
    return a->algorithm ? "--algorithm" : a->no_optimize ? "--no-optimize" : a->exponent_given ? "--exponent"
         : a->remesh == 1 ? "--remesh" : a->remesh == 0 ? "--keep-surface" : NULL;
}

static void parse_args(crom_cli *cli, args *a, int argc, char **argv)
{
    memset(a, 0, sizeof *a);
    a->timeout = 600;
    a->remesh = CROM_MESHGEN_REMESH_AUTO;
    crom_cli_parse(cli, &doc, argc, argv, on_opt, a);
    int shape = a->shape ? crom_meshgen_shape(a->shape) : -1;
    if (!a->shape)
        crom_err(CROM_EUSAGE, "no shape given (box, plate, sphere, cylinder, superquadric, import FILE, sheet, disk)");
    else if (shape < 0)
        crom_err(CROM_EUSAGE, "unknown shape '%s' (box, plate, sphere, cylinder, superquadric, import, sheet, disk)",
                 a->shape);
    else if (a->unstructured && shape != CROM_MESHGEN_SHEET)
        crom_err(CROM_EUSAGE, "--unstructured is for a sheet");
    else if (a->plane && shape != CROM_MESHGEN_SHEET && shape != CROM_MESHGEN_DISK &&
             !(shape == CROM_MESHGEN_IMPORT && a->thickness > 0))
        crom_err(CROM_EUSAGE, "--plane-strain is for triangles in z = 0 (sheet, disk, or import --thickness); %s "
                 "makes a solid", a->shape);
    else if (a->thickness > 0 && shape != CROM_MESHGEN_SHEET && shape != CROM_MESHGEN_DISK &&
             shape != CROM_MESHGEN_IMPORT)
        crom_err(CROM_EUSAGE, "--thickness is for a shell (sheet, disk, or import of a surface); %s makes a solid",
                 a->shape);
    else if (shape == CROM_MESHGEN_IMPORT && !a->file)
        crom_err(CROM_EUSAGE, "import needs a FILE operand");
    else if (solid_flag(a) && (shape == CROM_MESHGEN_SHEET || shape == CROM_MESHGEN_DISK ||
                               (shape == CROM_MESHGEN_IMPORT && a->thickness > 0)))
        crom_err(CROM_EUSAGE, "%s is for a tet mesh; a shell (%s%s) has no volume to mesh", solid_flag(a), a->shape,
                 shape == CROM_MESHGEN_IMPORT ? " --thickness" : "");
    else if ((shape == CROM_MESHGEN_SHEET && (a->radius > 0 || a->height > 0)) ||
             (shape == CROM_MESHGEN_DISK && (a->dims[0] > 0 || a->height > 0)))
        crom_err(CROM_EUSAGE, "%s takes %s", a->shape, shape == CROM_MESHGEN_SHEET ? "--dims, not --radius or --height"
                                                                                  : "--radius, not --dims or --height");
    else
        shape = shape + 1000;
    if (shape < 1000) {
        fprintf(stderr, "%s: %s\n", cli->prog, crom_errmsg());
        exit(CROM_EUSAGE);
    }
    crom_meshgen_defaults(&a->gen, shape - 1000);
    if (a->size > 0)
        a->gen.size = a->size;
    if (a->dims[0] > 0)
        memcpy(a->gen.dims, a->dims, sizeof a->dims);
    if (a->radius > 0)
        a->gen.radius = a->radius;
    if (a->height > 0)
        a->gen.height = a->height;
    if (a->exponent_given)
        a->gen.exponent = a->exponent;
    if (a->thickness > 0)
        a->gen.thickness = a->thickness;
    a->gen.unstructured = a->unstructured;
    if (a->algorithm)
        a->gen.algorithm = a->algorithm;
    a->gen.optimize = !a->no_optimize;
    a->gen.remesh = a->remesh;
    a->gen.file = a->file;
    a->gen.log = cli->verbose > 1 ? crom_cli_log_line : NULL; /* gmsh's messages with -vv */
    a->gen.log_ctx = cli;
}

static void on_alarm(int sig)
{
    (void)sig;
    static const char msg[] = "crom-mesh: meshing did not finish within the --timeout; is the surface valid?\n";
    if (write(2, msg, sizeof msg - 1) < 0) {
    }
    _exit(CROM_EDATA);
}

static int run(crom_cli *cli, args *a)
{
    crom_mesh m;
    signal(SIGALRM, on_alarm);
    alarm((unsigned)(a->timeout + 0.999));
    double t0 = crom_clock_now();
    crom_meshgen_plan_info plan = {0};
    int rc = a->gen.thickness > 0 ? 0 : crom_meshgen_plan(&a->gen, &plan); /* a shell keeps its triangles */
    if (rc)
        return rc;
    if (plan.finer && plan.automatic)
        crom_cli_info(cli, "%s: %d triangles with median edge %.3g m, much finer than --size %g: remeshing the "
                           "surface at --size (--keep-surface keeps its triangles)",
                      a->file, plan.triangles, plan.median_edge, a->gen.size);
    else if (plan.finer && !a->gen.remesh)
        crom_cli_info(cli, "%s: keeping its %d triangles (median edge %.3g m, much finer than --size %g): the "
                           "mesh will be far finer than --size (--remesh remeshes the surface)",
                      a->file, plan.triangles, plan.median_edge, a->gen.size);
    rc = crom_meshgen(&a->gen, &m);
    alarm(0);
    if (rc)
        return rc;
    if (a->plane) { /* a 2-D solid: the triangles must lie in z = 0 */
        m.plane = 1;
        for (int v = 0; v < m.nv && !rc; v++)
            if (m.X[3 * (size_t)v + 2] != 0)
                rc = crom_err(CROM_EDATA, "--plane-strain: vertex %d is at z = %g, not in the plane z = 0", v,
                              m.X[3 * (size_t)v + 2]);
    }
    for (int i = 0; i < a->nregions && !rc; i++)
        rc = crom_mesh_region_spec(&m, a->regions[i]);
    if (!rc)
        rc = crom_mesh_validate(&m);
    if (rc) {
        crom_mesh_free(&m);
        return rc;
    }
    if (cli->verbose && crom_mesh_is_surface(&m)) {
        crom_cli_info(cli, "%d vertices, %d triangles, %s %g m, %.2f s", m.nv, m.ntri,
                      m.plane ? "a plane-strain solid of depth" : "thickness", m.thickness,
                      crom_clock_now() - t0);
        for (int r = 0; r < m.nregions; r++)
            crom_cli_info(cli, "region %s: %d vertices (%s)", m.regions[r].name, m.regions[r].n,
                          m.regions[r].source);
    } else if (cli->verbose) {
        double worst, mean;
        int wt;
        crom_mesh_quality(&m, &worst, &mean, &wt);
        crom_cli_info(cli, "%d vertices, %d tets, volume %.6g m^3, quality worst %.3f (tet %d) mean %.3f, %.2f s",
                      m.nv, m.nt, crom_mesh_volume(&m), worst, wt, mean, crom_clock_now() - t0);
        for (int r = 0; r < m.nregions; r++)
            crom_cli_info(cli, "region %s: %d vertices (%s)", m.regions[r].name, m.regions[r].n,
                          m.regions[r].source);
    }
    crom_out o;
    if (!(rc = crom_out_create(&o, a->out, CROM_MESH_SCHEMA, CROM_MESH_VERSION, cli->cmdline, NULL,
                               CROM_OUT_PLAIN))) {
        static const char *shape_names[] = {"box",    "plate", "sphere", "cylinder", "superquadric",
                                            "import", "sheet", "disk"};
        rc = crom_mesh_write(o.h5, &m);
        if (!rc)
            rc = crom_h5_set_str(o.h5, ".", "generator", shape_names[a->gen.shape]);
        /* a .msh volume is read as it is: no target size applies */
        int kept = a->gen.shape == CROM_MESHGEN_IMPORT && strlen(a->file) > 4 &&
                   !strcmp(a->file + strlen(a->file) - 4, ".msh");
        if (!rc && !kept)
            rc = crom_h5_set_f64(o.h5, ".", "target_size", &a->gen.size, 1);
        if (!rc)
            rc = crom_out_commit(&o);
        else
            crom_out_fail(&o);
    }
    crom_mesh_free(&m);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    parse_args(&cli, &a, argc, argv);
    int rc = run(&cli, &a);
    free(a.regions);
    return crom_cli_exit(&cli, rc);
}
