/* meshgen.c — tetrahedral meshing through the gmsh C API (see meshgen.h).
 *
 * gmsh's session, logger and checked calls are lib/mesh/gmsh.h's. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "base/err.h"
#include "mesh/gmsh.h"
#include "mesh/meshgen.h"
#include "mesh/surface.h"

void crom_meshgen_defaults(crom_meshgen_opts *o, int shape)
{
    memset(o, 0, sizeof *o);
    o->shape = shape;
    o->dims[0] = o->dims[1] = o->dims[2] = 1.0;
    if (shape == CROM_MESHGEN_PLATE) {
        /* a plate lies in the xz-plane, thin along y (gravity is -y) */
        o->dims[1] = 0.05;
    }
    o->radius = 0.5;
    o->height = 1.0;
    o->exponent = 4.0;
    o->size = 0.1;
    o->thickness = shape == CROM_MESHGEN_SHEET || shape == CROM_MESHGEN_DISK ? 0.001 : 0;
    o->algorithm = 1;
    o->optimize = 1;
    o->remesh = CROM_MESHGEN_REMESH_AUTO;
}

int crom_meshgen_shape(const char *s)
{
    static const char *names[] = {"box", "plate", "sphere", "cylinder", "superquadric", "import", "sheet", "disk"};
    for (int i = 0; i < 8; i++)
        if (!strcmp(s, names[i]))
            return i;
    return -1;
}

static int ends_with(const char *s, const char *suf)
{
    size_t n = strlen(s), m = strlen(suf);
    return n >= m && !strcasecmp(s + n - m, suf);
}

/* ------------------------------------------------------- superquadric skin */

/* Cube point q (on the face of [-1,1]^3) pushed radially onto the surface
 * |x/a|^p+|y/b|^p+|z/c|^p = 1; grid coordinates are spaced by a blend of
 * tan() (even cells on a sphere) and uniform (even cells on a cube). */
static void sq_point(const double half[3], double p, double wa, int axis, int side,
                     double a, double b, double out[3])
{
    int u = (axis + 1) % 3, v = (axis + 2) % 3;
    double q[3];
    q[axis] = side;
    /* tan(pi/4) is not exactly 1 in floating point: keep the cube's edges
     * exact so that neighbouring faces produce bit-identical points */
    q[u] = fabs(a) == 1 ? a : wa * tan(M_PI / 4 * a) + (1 - wa) * a;
    q[v] = fabs(b) == 1 ? b : wa * tan(M_PI / 4 * b) + (1 - wa) * b;
    double r = pow(pow(fabs(q[0]), p) + pow(fabs(q[1]), p) + pow(fabs(q[2]), p), 1.0 / p);
    for (int k = 0; k < 3; k++)
        out[k] = q[k] / r * half[k];
}

/* A closed triangulated superquadric at edge length about h: the six faces
 * of a cube, each a grid, pushed onto the surface. The cell count along cube
 * axis k is shared by all faces, so neighbouring faces meet exactly. */
static int superquadric_skin(const double half[3], double p, double h, crom_surface *s)
{
    double wa = p <= 2 ? 1.0 : fmax(0.0, 1.0 - (p - 2) / 6.0);
    int n[3] = {1, 1, 1};
    for (int axis = 0; axis < 3; axis++)
        for (int dir = 1; dir <= 2; dir++) {
            /* length of the face's centre line along cube axis (axis+dir)%3 */
            int k = (axis + dir) % 3;
            double len = 0, prev[3], cur[3];
            for (int i = 0; i <= 256; i++) {
                double t = -1 + 2.0 * i / 256;
                sq_point(half, p, wa, axis, 1, dir == 1 ? t : 0, dir == 2 ? t : 0, cur);
                if (i)
                    len += sqrt((cur[0] - prev[0]) * (cur[0] - prev[0]) +
                                (cur[1] - prev[1]) * (cur[1] - prev[1]) +
                                (cur[2] - prev[2]) * (cur[2] - prev[2]));
                memcpy(prev, cur, sizeof prev);
            }
            int nk = (int)ceil(len / h);
            if (nk > n[k])
                n[k] = nk;
        }
    /* even counts put grid lines on the coordinate planes, so no cell
     * straddles a crease of the surface (the octahedron p = 1 is exact) */
    for (int k = 0; k < 3; k++)
        n[k] = n[k] < 2 ? 2 : n[k] + (n[k] & 1);
    for (int axis = 0; axis < 3; axis++)
        for (int side = -1; side <= 1; side += 2) {
            int u = (axis + 1) % 3, v = (axis + 2) % 3, nu = n[u], nv = n[v];
            int base = s->nv;
            for (int j = 0; j <= nv; j++)
                for (int i = 0; i <= nu; i++) {
                    double q[3];
                    sq_point(half, p, wa, axis, side, -1 + 2.0 * i / nu, -1 + 2.0 * j / nv, q);
                    if (crom_surface_add_vertex(s, q))
                        return CROM_EINTERNAL;
                }
            for (int j = 0; j < nv; j++)
                for (int i = 0; i < nu; i++) {
                    int a00 = base + j * (nu + 1) + i, a10 = a00 + 1, a01 = a00 + nu + 1, a11 = a01 + 1;
                    /* (u, v, axis) is right-handed: counter-clockwise seen from outside on
                     * the + side; alternate the diagonal to avoid a directional bias */
                    int flip = (i + j) & 1, rc;
                    if (side > 0)
                        rc = flip ? (crom_surface_add_tri(s, a00, a10, a01) || crom_surface_add_tri(s, a10, a11, a01))
                                  : (crom_surface_add_tri(s, a00, a10, a11) || crom_surface_add_tri(s, a00, a11, a01));
                    else
                        rc = flip ? (crom_surface_add_tri(s, a00, a01, a10) || crom_surface_add_tri(s, a10, a01, a11))
                                  : (crom_surface_add_tri(s, a00, a11, a10) || crom_surface_add_tri(s, a00, a01, a11));
                    if (rc)
                        return CROM_EINTERNAL;
                }
        }
    /* points on shared cube edges were computed from identical cube points,
     * so they are bit-identical: weld them, and make sure the skin closed */
    int rc = crom_surface_weld(s);
    return rc ? rc : crom_surface_check_closed(s, "superquadric");
}

/* ------------------------------------------------------------------ gmsh */

#define G(call, what) CROM_GMSH(call, what)

/* Put a closed triangle surface into gmsh as a discrete surface, make it a
 * geometry gmsh can remesh, and bound a volume by it. */
static int gmsh_volume_from_surface(const crom_surface *s, int remesh)
{
    int ierr = 0, rc = 0;
    size_t *ntags = NULL, *etags = NULL, *enodes = NULL;
    int *stags = NULL;
    int *dimtags = NULL;
    size_t ndt = 0;
    ntags = crom_malloc(sizeof(size_t) * (size_t)s->nv);
    etags = crom_malloc(sizeof(size_t) * (size_t)s->nt);
    enodes = crom_malloc(sizeof(size_t) * 3 * (size_t)s->nt);
    if (!ntags || !etags || !enodes) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (int i = 0; i < s->nv; i++)
        ntags[i] = (size_t)i + 1;
    for (int t = 0; t < s->nt; t++) {
        etags[t] = (size_t)t + 1;
        for (int k = 0; k < 3; k++)
            enodes[3 * (size_t)t + k] = (size_t)s->T[3 * (size_t)t + k] + 1;
    }
    G(gmshModelAddDiscreteEntity(2, 1, NULL, 0, &ierr), "add the surface");
    G(gmshModelMeshAddNodes(2, 1, ntags, (size_t)s->nv, s->V, 3 * (size_t)s->nv, NULL, 0, &ierr),
      "add surface nodes");
    G(gmshModelMeshAddElementsByType(1, 2, etags, (size_t)s->nt, enodes, 3 * (size_t)s->nt, &ierr),
      "add surface triangles");
    if (!remesh) {
        /* keep the given triangles as the boundary mesh of the volume: a
         * discrete surface without parametrization is not remeshed */
        int one = 1, loop0;
        G(loop0 = gmshModelGeoAddSurfaceLoop(&one, 1, -1, &ierr), "close the surface loop");
        G(gmshModelGeoAddVolume(&loop0, 1, -1, &ierr), "make the volume");
        G(gmshModelGeoSynchronize(&ierr), "synchronize");
        goto out;
    }
    /* split the surface at sharp creases (40°) into patches gmsh can
     * parametrize, then remesh them at the target size */
    G(gmshModelMeshClassifySurfaces(40 * M_PI / 180, 1, 1, M_PI, 0, &ierr), "classify the surface");
    G(gmshModelMeshCreateGeometry(NULL, 0, &ierr), "parametrize the surface");
    G(gmshModelGetEntities(&dimtags, &ndt, 2, &ierr), "list surfaces");
    stags = crom_malloc(sizeof(int) * (ndt / 2 + 1));
    if (!stags) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    for (size_t i = 0; i < ndt / 2; i++)
        stags[i] = dimtags[2 * i + 1];
    int loop;
    G(loop = gmshModelGeoAddSurfaceLoop(stags, ndt / 2, -1, &ierr), "close the surface loop");
    G(gmshModelGeoAddVolume(&loop, 1, -1, &ierr), "make the volume");
    G(gmshModelGeoSynchronize(&ierr), "synchronize");
out:
    if (dimtags)
        gmshFree(dimtags);
    free(stags);
    free(ntags);
    free(etags);
    free(enodes);
    return rc;
}

/* The physical groups of the model gmsh holds, as regions of m named by
 * their physical names (or physicalDIM_TAG): the vertices of each, through
 * map (gmsh node tag -> vertex of m, -1: none; tags up to maxtag). */
static int add_physical_groups(crom_mesh *m, const int *map, size_t maxtag)
{
    int ierr = 0, rc = 0, *dimtags = NULL;
    size_t ndt = 0;
    G(gmshModelGetPhysicalGroups(&dimtags, &ndt, -1, &ierr), "read physical groups");
    for (size_t g = 0; g < ndt / 2 && !rc; g++) {
        int dim = dimtags[2 * g], tag = dimtags[2 * g + 1];
        char *pname = NULL, name[80];
        G(gmshModelGetPhysicalName(dim, tag, &pname, &ierr), "read a physical name");
        if (pname && *pname) {
            size_t j = 0;
            for (const char *c = pname; *c && j < sizeof name - 1; c++)
                name[j++] = (isalnum((unsigned char)*c) || *c == '-' || *c == '.') ? *c : '_';
            name[j] = 0;
        } else {
            snprintf(name, sizeof name, "physical%d_%d", dim, tag);
        }
        if (pname)
            gmshFree(pname);
        size_t *gt = NULL, gn = 0, gc = 0;
        double *gcoord = NULL;
        G(gmshModelMeshGetNodesForPhysicalGroup(dim, tag, &gt, &gn, &gcoord, &gc, &ierr),
          "read physical group nodes");
        int *idx = crom_malloc(sizeof(int) * (gn + 1)), k = 0;
        for (size_t i = 0; idx && i < gn; i++)
            if (gt[i] <= maxtag && map[gt[i]] >= 0)
                idx[k++] = map[gt[i]];
        char src[128];
        snprintf(src, sizeof src, "gmsh:%s", name);
        if (!idx)
            rc = CROM_EINTERNAL;
        else if (k > 0)
            rc = crom_mesh_add_region(m, name, src, idx, k);
        free(idx);
        if (gt)
            gmshFree(gt);
        if (gcoord)
            gmshFree(gcoord);
    }
out:
    if (dimtags)
        gmshFree(dimtags);
    return rc;
}

static int gmsh_extract(crom_mesh *m, int import_groups)
{
    crom_gmsh_mesh g;
    int rc = crom_gmsh_mesh_read(4, "tetrahedra", &g);
    if (!rc && g.ne == 0)
        rc = crom_err(CROM_EDATA, "gmsh produced no linear tetrahedra (is the input a closed volume?)");
    if (!rc) {
        memset(m, 0, sizeof *m);
        m->nv = (int)g.nn;
        m->nt = (int)g.ne;
        m->X = crom_malloc(sizeof(double) * 3 * g.nn);
        m->tets = crom_malloc(sizeof(int) * 4 * g.ne);
        if (!m->X || !m->tets)
            rc = CROM_EINTERNAL;
    }
    if (!rc) {
        memcpy(m->X, g.coord, sizeof(double) * 3 * g.nn);
        for (size_t k = 0; k < 4 * g.ne; k++)
            m->tets[k] = g.map[g.enodes[k]];
    }
    if (!rc && import_groups)
        rc = add_physical_groups(m, g.map, g.maxtag);
    crom_gmsh_mesh_free(&g);
    return rc;
}

static int check_opts(const crom_meshgen_opts *o)
{
    if (!(o->size > 0) || !isfinite(o->size))
        return crom_err(CROM_EUSAGE, "--size must be a positive edge length, got %g", o->size);
    switch (o->shape) {
    case CROM_MESHGEN_BOX:
    case CROM_MESHGEN_PLATE:
    case CROM_MESHGEN_SUPERQUADRIC:
        for (int k = 0; k < 3; k++)
            if (!(o->dims[k] > 0) || !isfinite(o->dims[k]))
                return crom_err(CROM_EUSAGE, "--dims must be three positive extents");
        if (o->shape == CROM_MESHGEN_SUPERQUADRIC && (!(o->exponent >= 1) || o->exponent > 200))
            return crom_err(CROM_EUSAGE, "--exponent must be in [1, 200], got %g", o->exponent);
        break;
    case CROM_MESHGEN_SPHERE:
    case CROM_MESHGEN_CYLINDER:
        if (!(o->radius > 0) || !isfinite(o->radius))
            return crom_err(CROM_EUSAGE, "--radius must be positive");
        if (o->shape == CROM_MESHGEN_CYLINDER && (!(o->height > 0) || !isfinite(o->height)))
            return crom_err(CROM_EUSAGE, "--height must be positive");
        break;
    case CROM_MESHGEN_IMPORT:
        if (!o->file)
            return crom_err(CROM_EUSAGE, "import needs a file");
        break;
    default:
        return crom_err(CROM_EUSAGE, "unknown shape");
    }
    /* guard against accidental giant meshes: estimate the tet count */
    double L = o->shape == CROM_MESHGEN_SPHERE || o->shape == CROM_MESHGEN_CYLINDER
                   ? 2 * o->radius
                   : fmax(o->dims[0], fmax(o->dims[1], o->dims[2]));
    if (o->shape != CROM_MESHGEN_IMPORT && L / o->size > 400)
        return crom_err(CROM_EUSAGE, "--size %g is too small for a %g m shape (more than 400 edges across)",
                        o->size, L);
    return 0;
}

/* The rule of CROM_MESHGEN_REMESH_AUTO: remesh a surface much finer than size. */
static int much_finer(double med, double size) { return med < size / CROM_MESHGEN_REMESH_FINER; }

int crom_meshgen_plan(crom_meshgen_opts *o, crom_meshgen_plan_info *info)
{
    memset(info, 0, sizeof *info);
    int surface = o->shape == CROM_MESHGEN_IMPORT && o->file &&
                  (ends_with(o->file, ".stl") || ends_with(o->file, ".obj"));
    if (!surface) {
        if (o->remesh == CROM_MESHGEN_REMESH_AUTO)
            o->remesh = 0;
        return 0;
    }
    crom_surface s = {0};
    int rc = crom_surface_read(o->file, &s);
    if (rc)
        return rc;
    double med = crom_surface_median_edge(&s);
    info->triangles = s.nt;
    crom_surface_free(&s);
    if (med < 0)
        return crom_err(CROM_EINTERNAL, "out of memory");
    info->median_edge = med;
    info->finer = much_finer(med, o->size);
    if (o->remesh == CROM_MESHGEN_REMESH_AUTO) {
        info->automatic = 1;
        o->remesh = info->finer;
    }
    return 0;
}

/* What a shape starts from before gmsh: an imported .stl/.obj surface
 * (closed) or a superquadric's skin into s; *import_groups for a .msh or
 * .geo file gmsh reads itself. */
static int shape_input(const crom_meshgen_opts *o, crom_surface *s, int *import_groups)
{
    int rc;
    *import_groups = 0;
    if (o->shape == CROM_MESHGEN_IMPORT) {
        struct stat st;
        if (stat(o->file, &st) != 0) /* gmshOpen is silent on missing files */
            return crom_err(CROM_ENOINPUT, "%s: %s", o->file, strerror(errno));
        if (ends_with(o->file, ".stl") || ends_with(o->file, ".obj")) {
            if ((rc = crom_surface_read(o->file, s)))
                return rc;
            return crom_surface_check_closed(s, o->file);
        }
        if (ends_with(o->file, ".msh") || ends_with(o->file, ".geo")) {
            *import_groups = 1;
            return 0;
        }
        return crom_err(CROM_EUSAGE, "%s: unknown format (expected .stl, .obj, .msh or .geo)", o->file);
    }
    if (o->shape == CROM_MESHGEN_SUPERQUADRIC) {
        double half[3] = {o->dims[0] / 2, o->dims[1] / 2, o->dims[2] / 2};
        return superquadric_skin(half, o->exponent, o->size, s);
    }
    return 0;
}

/* The geometry of the shape in the current gmsh model: an OpenCASCADE
 * solid, a volume bounded by the surface s, or the file gmsh reads. */
static int make_geometry(const crom_meshgen_opts *o, crom_surface *s, int import_groups)
{
    int ierr = 0, rc = 0;
    const double *d = o->dims;
    switch (o->shape) {
    case CROM_MESHGEN_BOX:
    case CROM_MESHGEN_PLATE:
        G(gmshModelOccAddBox(-d[0] / 2, -d[1] / 2, -d[2] / 2, d[0], d[1], d[2], -1, &ierr),
          "make the box");
        G(gmshModelOccSynchronize(&ierr), "synchronize");
        break;
    case CROM_MESHGEN_SPHERE:
        G(gmshModelOccAddSphere(0, 0, 0, o->radius, -1, -M_PI / 2, M_PI / 2, 2 * M_PI, &ierr),
          "make the sphere");
        G(gmshModelOccSynchronize(&ierr), "synchronize");
        break;
    case CROM_MESHGEN_CYLINDER:
        G(gmshModelOccAddCylinder(0, -o->height / 2, 0, 0, o->height, 0, o->radius, -1, 2 * M_PI,
                                  &ierr),
          "make the cylinder");
        G(gmshModelOccSynchronize(&ierr), "synchronize");
        break;
    case CROM_MESHGEN_SUPERQUADRIC:
        rc = gmsh_volume_from_surface(s, 0);
        break;
    case CROM_MESHGEN_IMPORT:
        if (import_groups) {
            G(gmshOpen(o->file, &ierr), "read the file");
        } else {
            /* keep the file's triangles, subdivided down to the target
             * size, or let gmsh reparametrize and remesh them (better
             * elements, but it can spin on bad input: bounded by crom-mesh
             * --timeout); automatically: remesh a surface much finer than
             * the target, whose kept triangles would make a far finer mesh */
            int remesh = o->remesh;
            if (remesh == CROM_MESHGEN_REMESH_AUTO) {
                double med = crom_surface_median_edge(s);
                if (med < 0)
                    return crom_err(CROM_EINTERNAL, "out of memory");
                remesh = much_finer(med, o->size);
            }
            if (!remesh && (rc = crom_surface_refine(s, o->size)))
                return rc;
            rc = gmsh_volume_from_surface(s, remesh);
        }
        break;
    }
out:
    return rc;
}

/* 1 when the current gmsh model already holds tets (a .msh volume mesh). */
static int have_tets(void)
{
    int ierr = 0, *types = NULL, found = 0;
    size_t nty = 0;
    size_t **et = NULL, *etn = NULL, net = 0, **en = NULL, *enn = NULL, nen = 0;
    gmshModelMeshGetElements(&types, &nty, &et, &etn, &net, &en, &enn, &nen, 3, -1, &ierr);
    for (size_t i = 0; i < nty; i++)
        if (types[i] == 4 && etn[i] > 0)
            found = 1;
    for (size_t i = 0; i < net; i++)
        gmshFree(et[i]);
    for (size_t i = 0; i < nen; i++)
        gmshFree(en[i]);
    if (types) gmshFree(types);
    if (et) gmshFree(et);
    if (etn) gmshFree(etn);
    if (en) gmshFree(en);
    if (enn) gmshFree(enn);
    return found;
}

int crom_meshgen_sheet(const crom_meshgen_opts *o, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    double W = o->dims[0], Hh = o->dims[1], h = o->size;
    if (!(W > 0 && Hh > 0 && h > 0 && isfinite(W) && isfinite(Hh)))
        return crom_err(CROM_EUSAGE, "sheet: the extents and --size must be positive");
    if (!(o->thickness > 0) || !isfinite(o->thickness))
        return crom_err(CROM_EUSAGE, "sheet: --thickness must be positive (got %g)", o->thickness);
    double nxd = fmax(1, round(W / h)), nyd = fmax(1, round(Hh / (h * sqrt(3) / 2)));
    if (nxd * nyd > 2e7)
        return crom_err(CROM_EUSAGE, "sheet: %.0f x %.0f rows of triangles is too many; raise --size", nxd, nyd);
    int nx = (int)nxd, ny = (int)nyd; /* nx triangles' bases per row, ny rows */
    double dx = W / nx, dy = Hh / ny;
    /* row j: even rows have nx + 1 vertices at i dx, odd rows nx + 2 at 0, (i + ½) dx, W */
    int *start = crom_malloc(sizeof(int) * (size_t)(ny + 2));
    if (!start)
        return CROM_EINTERNAL;
    start[0] = 0;
    for (int j = 0; j <= ny; j++)
        start[j + 1] = start[j] + (j % 2 ? nx + 2 : nx + 1);
    m->nv = start[ny + 1];
    m->ntri = 2 * nx * ny + ny; /* per row: 2 nx − 1 whole triangles and two halves */
    m->X = crom_malloc(sizeof(double) * 3 * (size_t)m->nv);
    m->tris = crom_malloc(sizeof(int) * 3 * (size_t)m->ntri);
    m->tets = crom_malloc(sizeof(int) * 4);
    if (!m->X || !m->tris || !m->tets) {
        free(start);
        crom_mesh_free(m);
        return CROM_EINTERNAL;
    }
    m->thickness = o->thickness;
    for (int j = 0; j <= ny; j++)
        for (int k = 0; k < start[j + 1] - start[j]; k++) {
            double *p = m->X + 3 * (size_t)(start[j] + k);
            p[0] = (j % 2 == 0 ? k * dx : k == 0 ? 0 : k == nx + 1 ? W : (k - 0.5) * dx) - 0.5 * W;
            p[1] = j * dy - 0.5 * Hh;
            p[2] = 0;
        }
    int t = 0;
#define TRI(a, b, c) (m->tris[3 * t] = (a), m->tris[3 * t + 1] = (b), m->tris[3 * t + 2] = (c), t++)
    for (int j = 0; j < ny; j++) {
        int lo = start[j], up = start[j + 1];
        if (j % 2 == 0) { /* E below (nx + 1), O above (nx + 2) */
            TRI(lo, up + 1, up);
            for (int i = 0; i < nx; i++) {
                TRI(lo + i, lo + i + 1, up + i + 1);
                TRI(lo + i + 1, up + i + 2, up + i + 1);
            }
        } else { /* O below, E above */
            TRI(lo, lo + 1, up);
            for (int i = 0; i < nx; i++) {
                TRI(lo + i + 1, up + i + 1, up + i);
                TRI(lo + i + 1, lo + i + 2, up + i + 1);
            }
        }
    }
#undef TRI
    free(start);
    return crom_mesh_validate(m);
}

/* A shell from the 3-node triangles of a gmsh .msh file, kept as they are
 * (like a .msh volume: no target size applies), its physical groups made
 * regions. The triangles must be consistently oriented (an open or closed
 * surface, each edge shared by at most two); a file holding tetrahedra is a
 * volume, imported without --thickness. */
static int msh_shell(const crom_meshgen_opts *o, crom_mesh *m)
{
    FILE *f = fopen(o->file, "rb"); /* gmsh only logs a file it cannot open */
    if (!f)
        return crom_err(CROM_ENOINPUT, "%s: %s", o->file, strerror(errno));
    fclose(f);
    int rc = crom_gmsh_begin(o->log), ierr = 0;
    if (rc)
        return rc;
    crom_gmsh_mesh g = {0};
    crom_surface s = {0};
    G(gmshOpen(o->file, &ierr), "read the file");
    if (have_tets()) {
        rc = crom_err(CROM_EUSAGE, "%s holds a volume mesh (tetrahedra): import it without --thickness", o->file);
        goto out;
    }
    if ((rc = crom_gmsh_mesh_read(2, "triangles", &g)))
        goto out;
    if (g.ne == 0) {
        rc = crom_err(CROM_EDATA, "%s holds no 3-node triangles for a shell (is it a gmsh .msh surface?)", o->file);
        goto out;
    }
    if (g.ne > 4000000 || g.nn > 12000000) {
        rc = crom_err(CROM_EUSAGE, "%s: %zu triangles on %zu nodes is more than a shell of crom takes", o->file, g.ne,
                      g.nn);
        goto out;
    }
    s.nv = (int)g.nn;
    s.nt = (int)g.ne;
    s.V = crom_malloc(sizeof(double) * 3 * g.nn);
    s.T = crom_malloc(sizeof(int) * 3 * g.ne);
    if (!s.V || !s.T) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    memcpy(s.V, g.coord, sizeof(double) * 3 * g.nn);
    for (size_t k = 0; k < 3 * g.ne; k++)
        s.T[k] = g.map[g.enodes[k]];
    if ((rc = crom_surface_check_oriented(&s, o->file)))
        goto out;
    m->nv = s.nv;
    m->ntri = s.nt;
    m->thickness = o->thickness;
    m->X = s.V;
    m->tris = s.T;
    s.V = NULL;
    s.T = NULL;
    if (!(m->tets = crom_malloc(sizeof(int) * 4))) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    if (!(rc = add_physical_groups(m, g.map, g.maxtag)) && !(rc = crom_mesh_compact(m)))
        rc = crom_mesh_validate(m);
out:
    crom_gmsh_mesh_free(&g);
    crom_surface_free(&s);
    crom_gmsh_end(o->log, o->log_ctx);
    if (rc)
        crom_mesh_free(m);
    return rc;
}

int crom_meshgen_shell_import(const crom_meshgen_opts *o, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    if (!o->file)
        return crom_err(CROM_EUSAGE, "import needs a file");
    if (!(o->thickness > 0) || !isfinite(o->thickness))
        return crom_err(CROM_EUSAGE, "a shell import needs a positive --thickness (got %g)", o->thickness);
    if (ends_with(o->file, ".msh"))
        return msh_shell(o, m);
    if (!(ends_with(o->file, ".stl") || ends_with(o->file, ".obj")))
        return crom_err(CROM_EUSAGE, "%s: a shell is imported from the triangles of an .stl, .obj or .msh surface",
                        o->file);
    crom_surface s = {0};
    int rc = crom_surface_read(o->file, &s);
    if (!rc)
        rc = crom_surface_check_oriented(&s, o->file);
    if (!rc)
        rc = crom_surface_refine(&s, o->size);
    if (!rc) {
        m->nv = s.nv;
        m->ntri = s.nt;
        m->thickness = o->thickness;
        m->X = crom_malloc(sizeof(double) * 3 * (size_t)s.nv);
        m->tris = crom_malloc(sizeof(int) * 3 * (size_t)s.nt);
        m->tets = crom_malloc(sizeof(int) * 4);
        if (!m->X || !m->tris || !m->tets)
            rc = CROM_EINTERNAL;
    }
    if (!rc) {
        memcpy(m->X, s.V, sizeof(double) * 3 * (size_t)s.nv);
        memcpy(m->tris, s.T, sizeof(int) * 3 * (size_t)s.nt);
        rc = crom_mesh_compact(m);
    }
    if (!rc)
        rc = crom_mesh_validate(m);
    crom_surface_free(&s);
    if (rc)
        crom_mesh_free(m);
    return rc;
}

/* A flat shell meshed by gmsh in the xy-plane: a disk of o->radius, or
 * (rect) the rectangle dims[0] × dims[1], both centred at the origin */
static int gmsh_shell(const crom_meshgen_opts *o, int rect, crom_mesh *m)
{
    memset(m, 0, sizeof *m);
    const char *what = rect ? "sheet" : "disk";
    double extent = rect ? fmax(o->dims[0], o->dims[1]) : o->radius;
    if (!(extent > 0) || !isfinite(extent) || (rect && !(o->dims[0] > 0 && o->dims[1] > 0)) || !(o->size > 0) ||
        !isfinite(o->size))
        return crom_err(CROM_EUSAGE, "%s: the %s and --size must be positive", what, rect ? "extents" : "radius");
    if (!(o->thickness > 0) || !isfinite(o->thickness))
        return crom_err(CROM_EUSAGE, "%s: --thickness must be positive (got %g)", what, o->thickness);
    if (extent / o->size > 3000)
        return crom_err(CROM_EUSAGE, "%s: %g / --size = %g is too many triangles; raise --size", what, extent,
                        extent / o->size);
    int rc = crom_gmsh_begin(o->log), ierr = 0;
    if (rc)
        return rc;
    crom_gmsh_mesh g = {0};
    gmshModelAdd("crom", &ierr);
    gmshOptionSetNumber("Mesh.MeshSizeMax", o->size, &ierr);
    gmshOptionSetNumber("Mesh.MeshSizeMin", o->size * 0.25, &ierr);
    gmshOptionSetNumber("Mesh.MeshSizeFromCurvature", 0, &ierr);
    gmshOptionSetNumber("Mesh.MeshSizeFromPoints", 0, &ierr);
    if (rect)
        G(gmshModelOccAddRectangle(-o->dims[0] / 2, -o->dims[1] / 2, 0, o->dims[0], o->dims[1], -1, 0, &ierr),
          "make the rectangle");
    else
        G(gmshModelOccAddDisk(0, 0, 0, o->radius, o->radius, -1, &ierr), "make the disk");
    G(gmshModelOccSynchronize(&ierr), "synchronize");
    G(gmshModelMeshGenerate(2, &ierr), "mesh the surface");
    if ((rc = crom_gmsh_mesh_read(2, "triangles", &g)))
        goto out;
    size_t nn = g.nn, ne = g.ne;
    m->nv = (int)nn;
    m->ntri = (int)ne;
    m->thickness = o->thickness;
    m->X = crom_malloc(sizeof(double) * 3 * (nn ? nn : 1));
    m->tris = crom_malloc(sizeof(int) * 3 * (ne ? ne : 1));
    m->tets = crom_malloc(sizeof(int) * 4);
    if (!m->X || !m->tris || !m->tets) {
        rc = CROM_EINTERNAL;
        goto out;
    }
    if (ne == 0) {
        rc = crom_err(CROM_EDATA, "gmsh produced no triangles for the %s", what);
        goto out;
    }
    for (size_t i = 0; i < nn; i++) {
        memcpy(m->X + 3 * i, g.coord + 3 * i, 3 * sizeof(double));
        m->X[3 * i + 2] = 0;
    }
    for (size_t t = 0; t < ne; t++) { /* every triangle facing +z */
        int v[3];
        for (int k = 0; k < 3; k++)
            v[k] = g.map[g.enodes[3 * t + k]];
        const double *a = m->X + 3 * (size_t)v[0], *b = m->X + 3 * (size_t)v[1], *c = m->X + 3 * (size_t)v[2];
        double nz = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        m->tris[3 * t] = v[0];
        m->tris[3 * t + 1] = nz >= 0 ? v[1] : v[2];
        m->tris[3 * t + 2] = nz >= 0 ? v[2] : v[1];
    }
    if (!(rc = crom_mesh_compact(m)))
        rc = crom_mesh_validate(m);
out:
    crom_gmsh_mesh_free(&g);
    crom_gmsh_end(o->log, o->log_ctx);
    if (rc)
        crom_mesh_free(m);
    return rc;
}

int crom_meshgen_disk(const crom_meshgen_opts *o, crom_mesh *m) { return gmsh_shell(o, 0, m); }

int crom_meshgen(const crom_meshgen_opts *o, crom_mesh *m)
{
    if (o->shape == CROM_MESHGEN_SHEET && o->unstructured)
        return gmsh_shell(o, 1, m);
    if (o->shape == CROM_MESHGEN_SHEET)
        return crom_meshgen_sheet(o, m);
    if (o->shape == CROM_MESHGEN_DISK)
        return crom_meshgen_disk(o, m);
    if (o->shape == CROM_MESHGEN_IMPORT && o->thickness > 0)
        return crom_meshgen_shell_import(o, m);
    memset(m, 0, sizeof *m);
    int rc = check_opts(o), ierr = 0;
    if (rc)
        return rc;
    crom_surface s = {0};
    int import_groups;
    if ((rc = shape_input(o, &s, &import_groups)) || (rc = crom_gmsh_begin(o->log))) {
        crom_surface_free(&s);
        return rc;
    }
    gmshModelAdd("crom", &ierr);
    gmshOptionSetNumber("Mesh.MeshSizeMax", o->size, &ierr);
    gmshOptionSetNumber("Mesh.MeshSizeMin", o->size * 0.25, &ierr);
    gmshOptionSetNumber("Mesh.MeshSizeFromCurvature", 0, &ierr);
    gmshOptionSetNumber("Mesh.MeshSizeFromPoints", 0, &ierr);
    gmshOptionSetNumber("Mesh.Algorithm3D", o->algorithm, &ierr);
    gmshOptionSetNumber("Mesh.Optimize", o->optimize, &ierr);
    if ((rc = make_geometry(o, &s, import_groups)))
        goto out;
    /* a .msh may already hold a volume mesh: keep it rather than remesh */
    if (!(import_groups && have_tets()))
        G(gmshModelMeshGenerate(3, &ierr), "mesh the volume");
    if ((rc = gmsh_extract(m, import_groups)))
        goto out;
    if ((rc = crom_mesh_compact(m)) || (rc = crom_mesh_orient(m, NULL)))
        goto out;
out:
    crom_gmsh_end(o->log, o->log_ctx);
    crom_surface_free(&s);
    if (rc)
        crom_mesh_free(m);
    return rc;
}
