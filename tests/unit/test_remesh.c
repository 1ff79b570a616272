/* test_remesh.c — cut, punch, swap, refine: exact areas and volumes on
 * structured grids, bounded jaggedness and exact projected areas on gmsh
 * meshes, converging punched volumes, region bookkeeping. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "mesh/mesh.h"
#include "mesh/meshgen.h"
#include "mesh/remesh.h"

/* ------------------------------------------------------------ helpers */

static void centroid(const crom_mesh *m, int t, double c[3])
{
    const int *e = m->tets + 4 * t;
    for (int k = 0; k < 3; k++)
        c[k] = (m->X[3 * e[0] + k] + m->X[3 * e[1] + k] + m->X[3 * e[2] + k] + m->X[3 * e[3] + k]) / 4;
}

static void tri_area(const double *a, const double *b, const double *c, double n[3])
{
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    n[0] = (u[1] * v[2] - u[2] * v[1]) / 2;
    n[1] = (u[2] * v[0] - u[0] * v[2]) / 2;
    n[2] = (u[0] * v[1] - u[1] * v[0]) / 2;
}

static double boundary_area(const crom_mesh *m)
{
    int nt, *T;
    if (crom_mesh_boundary(m, &nt, &T, NULL))
        return NAN;
    double A = 0, n[3];
    for (int t = 0; t < nt; t++) {
        tri_area(m->X + 3 * T[3 * t], m->X + 3 * T[3 * t + 1], m->X + 3 * T[3 * t + 2], n);
        A += sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    free(T);
    return A;
}

static void all_positive(const crom_mesh *m, const char *what)
{
    int bad = 0;
    for (int t = 0; t < m->nt; t++) {
        const int *e = m->tets + 4 * t;
        if (!(crom_mesh_tet_volume(m->X + 3 * e[0], m->X + 3 * e[1], m->X + 3 * e[2], m->X + 3 * e[3]) > 0))
            bad++;
    }
    CHECK_MSG(bad == 0, "%s: %d tets with non-positive volume", what, bad);
    CHECK_MSG(crom_mesh_validate(m) == 0, "%s: %s", what, crom_errmsg());
}

/* Every vertex is used only by tets whose centroid lies on one side of the
 * plane X[axis] = c (a centroid on it counts with X[axis] < c): no tet
 * references a vertex of the other side. */
static int vertices_one_sided(const crom_mesh *m, int axis, double c)
{
    signed char *side = calloc((size_t)m->nv, 1);
    int bad = 0;
    for (int t = 0; t < m->nt; t++) {
        double x[3];
        centroid(m, t, x);
        signed char s = x[axis] <= c ? -1 : 1;
        for (int k = 0; k < 4; k++) {
            int v = m->tets[4 * t + k];
            if (side[v] && side[v] != s)
                bad++;
            side[v] = s;
        }
    }
    free(side);
    return bad;
}

static int nwarn;
static void count_warn(void *ctx, const char *msg)
{
    (void)ctx;
    nwarn++;
    fprintf(stderr, "  (warning: %s)\n", msg);
}

/* ------------------------------------------------------------------ cut */

static void test_cut_grid(void)
{
    crom_mesh m, c;
    fx_unit_grid(&m, 4, 1);
    double A0 = boundary_area(&m), V0 = crom_mesh_volume(&m);
    CHECK_NEAR(A0, 6, 1e-12);
    /* a wall on the grid plane x = 0.5 through the whole cube */
    double seg[4] = {0.5, -0.1, 0.5, 1.1};
    crom_remesh_cut_opts cut = {1, 1, seg, 1, 1};
    crom_remesh_cut_stats st;
    CHECK(crom_remesh_cut(&m, &cut, &c, &st, NULL, NULL) == 0);
    CHECK(st.faces_cut == 32);  /* 16 squares, 2 triangles each */
    CHECK(st.verts_dup == 25);  /* the 5 x 5 vertices on the plane */
    CHECK(st.components == 2);
    CHECK(c.nv == m.nv + 25 && c.nt == m.nt);
    CHECK_NEAR(boundary_area(&c), A0 + 2, 1e-12); /* exactly 2 x the cut area */
    CHECK(crom_mesh_volume(&c) == V0);
    CHECK(vertices_one_sided(&c, 0, 0.5) == 0);
    all_positive(&c, "grid cut");
    crom_mesh_free(&c);

    /* half of it (stage 1 of 2 ends at z = 0.5, a grid line): area + 1 */
    cut.stages = 2;
    CHECK(crom_remesh_cut(&m, &cut, &c, &st, NULL, NULL) == 0);
    CHECK(st.faces_cut == 16 && st.verts_dup == 10 && st.components == 1);
    CHECK_NEAR(boundary_area(&c), A0 + 1, 1e-12);
    crom_mesh_free(&c);

    /* a wall through the middle of a layer of cubes, where some Kuhn tets
     * have their centroid exactly on it: still two pieces */
    double mid[4] = {0.375, -0.1, 0.375, 1.1};
    crom_remesh_cut_opts cm = {1, 1, mid, 1, 1};
    CHECK(crom_remesh_cut(&m, &cm, &c, &st, NULL, NULL) == 0);
    CHECK(st.components == 2);
    CHECK(vertices_one_sided(&c, 0, 0.375) == 0);
    CHECK(crom_mesh_volume(&c) == V0);
    fprintf(stderr, "grid cut through cube centres: %d faces, boundary area %.6f\n", st.faces_cut,
            boundary_area(&c));
    crom_mesh_free(&c);

    /* the same wall along axis z: (u, v) = (x, y) */
    double segz[4] = {0.5, -0.1, 0.5, 1.1};
    crom_remesh_cut_opts cz = {2, 1, segz, 1, 1};
    CHECK(crom_remesh_cut(&m, &cz, &c, &st, NULL, NULL) == 0);
    CHECK(st.faces_cut == 32 && st.components == 2);
    CHECK_NEAR(boundary_area(&c), A0 + 2, 1e-12);
    crom_mesh_free(&c);

    /* stage 0, and a ribbon outside the mesh: output = input, warned */
    cut.stage = 0;
    nwarn = 0;
    CHECK(crom_remesh_cut(&m, &cut, &c, &st, count_warn, NULL) == 0);
    CHECK(nwarn == 1 && st.faces_cut == 0 && c.nv == m.nv && c.nt == m.nt);
    CHECK(!memcmp(c.X, m.X, sizeof(double) * 3 * m.nv) && !memcmp(c.tets, m.tets, sizeof(int) * 4 * m.nt));
    crom_mesh_free(&c);
    double away[4] = {3, 0, 3, 1};
    crom_remesh_cut_opts ca = {1, 1, away, 1, 1};
    CHECK(crom_remesh_cut(&m, &ca, &c, &st, count_warn, NULL) == 0);
    CHECK(nwarn == 2 && st.faces_cut == 0 && c.nv == m.nv);
    crom_mesh_free(&c);

    /* regions follow the copies */
    CHECK(crom_mesh_region_spec(&m, "mid=x>0.4&x<0.6") == 0);
    cut.stage = cut.stages = 1;
    CHECK(crom_remesh_cut(&m, &cut, &c, &st, NULL, NULL) == 0);
    const crom_mesh_region *r = crom_mesh_find_region(&c, "mid");
    CHECK(r && r->n == 50);
    for (int i = 0; r && i < r->n; i++)
        CHECK_NEAR(c.X[3 * r->idx[i]], 0.5, 0);
    crom_mesh_free(&c);

    /* bad options */
    cut.stage = 3;
    cut.stages = 2;
    CHECK(crom_remesh_cut(&m, &cut, &c, NULL, NULL, NULL) == CROM_EUSAGE);
    cut.stage = cut.stages = 1;
    double zero[4] = {0.5, 0.5, 0.5, 0.5};
    crom_remesh_cut_opts c0 = {1, 1, zero, 1, 1};
    CHECK(crom_remesh_cut(&m, &c0, &c, NULL, NULL, NULL) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "zero length") != NULL);
    double bad[4] = {0.5, NAN, 0.5, 1};
    crom_remesh_cut_opts cn = {1, 1, bad, 1, 1};
    CHECK(crom_remesh_cut(&m, &cn, &c, NULL, NULL, NULL) == CROM_EUSAGE);
    crom_remesh_cut_opts cx = {3, 1, seg, 1, 1};
    CHECK(crom_remesh_cut(&m, &cx, &c, NULL, NULL, NULL) == CROM_EUSAGE);
    crom_remesh_cut_opts cs = {1, 1, seg, 0, 0};
    CHECK(crom_remesh_cut(&m, &cs, &c, NULL, NULL, NULL) == CROM_EUSAGE);
    crom_mesh_free(&m);
}

/* outward area vector of face l of a positively oriented tet */
static void face_area(const crom_mesh *m, int t, int l, double n[3])
{
    static const int f[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    const int *e = m->tets + 4 * t;
    tri_area(m->X + 3 * e[f[l][0]], m->X + 3 * e[f[l][1]], m->X + 3 * e[f[l][2]], n);
}

static void test_cut_plate(void)
{
    const double xc = 0.0123, L = 1.0, thick = 0.05;
    crom_mesh m, c;
    double dims[3] = {1, thick, 1};
    fx_gen(CROM_MESHGEN_PLATE, dims, 0.05, &m);
    double A0 = boundary_area(&m), V0 = crom_mesh_volume(&m);

    /* a straight through-cut */
    double seg[4] = {xc, -0.6, xc, 0.6};
    crom_remesh_cut_opts cut = {1, 1, seg, 1, 1};
    unsigned char *flags;
    int nf;
    CHECK(crom_remesh_cut_faces(&m, &cut, &flags, &nf) == 0);
    double cutA = 0, projA = 0, n[3];
    for (int t = 0; t < m.nt; t++)
        for (int l = 0; l < 4; l++)
            if (flags[4 * t + l]) {
                double x[3];
                face_area(&m, t, l, n);
                centroid(&m, t, x);
                if (x[0] < xc) { /* the faces side x < xc exposes */
                    cutA += sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
                    projA += n[0];
                }
            }
    free(flags);
    crom_remesh_cut_stats st;
    CHECK(crom_remesh_cut(&m, &cut, &c, &st, NULL, NULL) == 0);
    double gain = boundary_area(&c) - A0, ideal = 2 * L * thick;
    fprintf(stderr, "plate cut: %d faces, %d vertex copies, area gain %.6f = %.3f x 2*L*t, "
                    "projected %.15f\n",
            st.faces_cut, st.verts_dup, gain, gain / ideal, projA);
    CHECK(st.faces_cut == nf);
    CHECK_NEAR(gain, 2 * cutA, 1e-12);     /* each cut face became two boundary faces */
    CHECK_NEAR(projA, L * thick, 1e-12);   /* the exposed side's projected area is exact */
    CHECK(gain >= ideal * (1 - 1e-12));    /* a jagged surface is never smaller */
    /* ... and at most 75% larger: a surface made of tet faces has a mean
     * |cos| of about 0.6 to the ribbon normal on unstructured meshes
     * (measured 1.03-1.63 x on gmsh plates, 1.58-1.73 x on boxes) */
    CHECK_LT(gain, 1.75 * ideal);
    CHECK(crom_mesh_volume(&c) == V0);     /* no tet moved */
    CHECK(st.components == 2);
    CHECK(vertices_one_sided(&c, 0, xc) == 0);
    all_positive(&c, "plate cut");
    crom_mesh_free(&c);

    /* a Y tear: stem from the bottom edge to the fork, two branches */
    double y[12] = {xc, -0.6, xc, 0.0, xc, 0.0, xc - 0.3, 0.3, xc, 0.0, xc + 0.3, 0.3};
    const int N = 4;
    unsigned char *prev = NULL;
    int pf = -1, pd = -1, mono = 1, subset = 1;
    for (int k = 0; k <= N; k++) {
        crom_remesh_cut_opts cy = {1, 3, y, N, k};
        unsigned char *fl;
        CHECK(crom_remesh_cut_faces(&m, &cy, &fl, &nf) == 0);
        CHECK(crom_remesh_cut(&m, &cy, &c, &st, NULL, NULL) == 0);
        fprintf(stderr, "Y tear stage %d/%d: %d faces cut, %d vertex copies, %d component(s)\n", k, N,
                st.faces_cut, st.verts_dup, st.components);
        mono &= st.faces_cut >= pf && st.verts_dup >= pd;
        for (int s = 0; prev && s < 4 * m.nt; s++)
            subset &= !prev[s] || fl[s];
        CHECK(st.components == 1); /* the branches end inside: one piece */
        CHECK(crom_mesh_volume(&c) == V0);
        pf = st.faces_cut;
        pd = st.verts_dup;
        free(prev);
        prev = fl;
        crom_mesh_free(&c);
    }
    CHECK_MSG(mono, "cut faces and copies must not decrease with the stage");
    CHECK_MSG(subset, "each stage must cut every face the previous one cut");
    CHECK(pf > 0);
    /* stage N of the Y is the union of its three branches */
    int same = 1, total = 0;
    unsigned char *one[3];
    for (int b = 0; b < 3; b++) {
        crom_remesh_cut_opts cb = {1, 1, y + 4 * b, 1, 1};
        CHECK(crom_remesh_cut_faces(&m, &cb, &one[b], &nf) == 0);
        total += nf;
    }
    for (int s = 0; s < 4 * m.nt; s++)
        same &= prev[s] == (one[0][s] | one[1][s] | one[2][s]);
    CHECK_MSG(same, "stage N of the Y differs from the union of its branches");
    CHECK(total >= pf); /* faces at the fork may be cut by two branches */
    for (int b = 0; b < 3; b++)
        free(one[b]);
    free(prev);
    crom_mesh_free(&m);
}

/* ---------------------------------------------------------------- punch */

static void test_punch(void)
{
    const double R = 0.3, exact = 4.0 / 3.0 * M_PI * R * R * R;
    const double h[3] = {0.2, 0.1, 0.05};
    double err[3];
    crom_remesh_punch_shape ball = {CROM_REMESH_PUNCH_SPHERE, {0.013, -0.021, 0.017, R}};
    for (int i = 0; i < 3; i++) {
        crom_mesh m, p;
        fx_gen(CROM_MESHGEN_BOX, NULL, h[i], &m);
        CHECK(crom_mesh_region_spec(&m, "top=y>0.45") == 0);
        CHECK(crom_mesh_region_spec(&m, "core=sphere:0,0,0,0.1") == 0);
        int nrem = 0;
        nwarn = 0;
        CHECK(crom_remesh_punch(&m, &ball, 1, &p, &nrem, count_warn, NULL) == 0);
        double removed = crom_mesh_volume(&m) - crom_mesh_volume(&p);
        err[i] = fabs(removed - exact) / exact;
        fprintf(stderr, "punch h=%.3f: removed %d of %d tets, volume %.6f vs %.6f, relative error %.3e\n",
                h[i], nrem, m.nt, removed, exact, err[i]);
        all_positive(&p, "punched box");
        CHECK(nwarn == 1 && !crom_mesh_find_region(&p, "core")); /* emptied: dropped with a warning */
        /* top keeps exactly the surviving vertices with y > 0.45 */
        const crom_mesh_region *top = crom_mesh_find_region(&p, "top");
        int k = 0, ok = top != NULL;
        for (int v = 0; ok && v < p.nv; v++)
            if (p.X[3 * v + 1] > 0.45)
                ok &= k < top->n && top->idx[k++] == v;
        CHECK_MSG(ok && top && k == top->n, "region top after punching");
        /* every surviving vertex is used, no vertex is inside the hole's core */
        CHECK(crom_remesh_components(&p, NULL) == 1);
        crom_mesh_free(&p);
        crom_mesh_free(&m);
    }
    CHECK_LT(err[1], err[0]);
    CHECK_LT(err[2], err[1]);
    CHECK_LT(err[2], 0.03);

    /* a slab through the middle leaves two pieces; punching all is refused */
    crom_mesh m, p;
    fx_unit_grid(&m, 4, 1);
    crom_remesh_punch_shape slab = {CROM_REMESH_PUNCH_BOX, {0.3, -1, -1, 0.7, 2, 2}};
    CHECK(crom_remesh_punch(&m, &slab, 1, &p, NULL, NULL, NULL) == 0);
    CHECK(crom_remesh_components(&p, NULL) == 2);
    CHECK_NEAR(crom_mesh_volume(&p), 0.5, 1e-14);
    crom_mesh_free(&p);
    crom_remesh_punch_shape all = {CROM_REMESH_PUNCH_BOX, {-1, -1, -1, 2, 2, 2}};
    CHECK(crom_remesh_punch(&m, &all, 1, &p, NULL, NULL, NULL) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), "nothing would remain") != NULL);
    crom_remesh_punch_shape neg = {CROM_REMESH_PUNCH_SPHERE, {0, 0, 0, 0}};
    CHECK(crom_remesh_punch(&m, &neg, 1, &p, NULL, NULL, NULL) == CROM_EUSAGE);
    crom_remesh_punch_shape flat = {CROM_REMESH_PUNCH_BOX, {0, 0, 0, 1, 0, 1}};
    CHECK(crom_remesh_punch(&m, &flat, 1, &p, NULL, NULL, NULL) == CROM_EUSAGE);
    crom_mesh_free(&m);
}

/* ----------------------------------------------------------------- swap */

static void test_swap(void)
{
    crom_mesh in, other, out;
    fx_gen(CROM_MESHGEN_BOX, NULL, 0.25, &in);
    CHECK(crom_mesh_region_spec(&in, "bottom=y<-0.45") == 0);
    CHECK(crom_mesh_region_spec(&in, "base=bottom") == 0);       /* a name: followed */
    CHECK(crom_mesh_region_spec(&in, "side=x>0.45") == 0);       /* empty on OTHER */
    int one = 0;
    CHECK(crom_mesh_add_region(&in, "grp", "gmsh:grp", &one, 1) == 0); /* not transferable */
    double dims[3] = {2, 0.5, 0.25};
    fx_gen(CROM_MESHGEN_BOX, dims, 0.1, &other);
    CHECK(crom_mesh_region_spec(&other, "own=x>0.9") == 0);
    double V = crom_mesh_volume(&other);

    /* 90 degrees about y: the x-extent becomes the z-extent, exactly */
    crom_remesh_xform x;
    crom_remesh_xform_init(&x);
    x.axis[1] = 1;
    x.deg = 90;
    x.translate[1] = -0.3;
    nwarn = 0;
    CHECK(crom_remesh_swap(&in, &other, &x, &out, count_warn, NULL) == 0);
    CHECK(nwarn == 2); /* grp (gmsh) and side (selects nothing) */
    double lo[3], hi[3];
    crom_mesh_bbox(&out, lo, hi);
    CHECK_NEAR(hi[0] - lo[0], 0.25, 1e-15);
    CHECK_NEAR(hi[1] - lo[1], 0.5, 1e-15);
    CHECK_NEAR(hi[2] - lo[2], 2, 1e-15);
    CHECK_NEAR(lo[1], -0.55, 1e-15);
    CHECK_NEAR(crom_mesh_volume(&out), V, 1e-12);
    all_positive(&out, "rotated");
    CHECK(crom_mesh_find_region(&out, "own") != NULL && !crom_mesh_find_region(&out, "side") &&
          !crom_mesh_find_region(&out, "grp"));
    /* bottom and base select exactly the transformed vertices with y < -0.45 */
    const char *names[2] = {"bottom", "base"};
    for (int q = 0; q < 2; q++) {
        const crom_mesh_region *r = crom_mesh_find_region(&out, names[q]);
        int k = 0, ok = r != NULL;
        for (int v = 0; ok && v < out.nv; v++)
            if (out.X[3 * v + 1] < -0.45)
                ok &= k < r->n && r->idx[k++] == v;
        CHECK_MSG(ok && r && k == r->n && k > 0, "region %s re-evaluated on the swapped mesh", names[q]);
        CHECK(r && !strcmp(r->source, "y<-0.45"));
    }
    crom_mesh_free(&out);

    /* a general reflection-free transform: volume scales by s^3, tets stay
     * positive */
    crom_remesh_xform_init(&x);
    x.scale = 1.5;
    x.axis[0] = 1;
    x.axis[1] = 1;
    x.deg = 33;
    x.translate[0] = 0.2;
    CHECK(crom_remesh_swap(&in, &other, &x, &out, NULL, NULL) == 0);
    CHECK_REL(crom_mesh_volume(&out), V * 1.5 * 1.5 * 1.5, 1e-12);
    all_positive(&out, "scaled and rotated");
    crom_mesh_free(&out);

    /* --fit: the largest extents match, centred on the input's box */
    crom_remesh_xform_init(&x);
    x.fit = 1;
    CHECK(crom_remesh_swap(&in, &other, &x, &out, NULL, NULL) == 0);
    crom_mesh_bbox(&out, lo, hi);
    CHECK_NEAR(lo[0], -0.5, 1e-12);
    CHECK_NEAR(hi[0], 0.5, 1e-12);
    CHECK_NEAR(hi[1] - lo[1], 0.25, 1e-12);   /* 0.5 x 0.5 */
    CHECK_NEAR(hi[2] - lo[2], 0.125, 1e-12);  /* 0.5 x 0.25 */
    CHECK_NEAR(lo[1] + hi[1], 0, 1e-12);
    CHECK_NEAR(lo[2] + hi[2], 0, 1e-12);
    crom_mesh_free(&out);

    /* bad transforms */
    crom_remesh_xform_init(&x);
    x.scale = 0;
    CHECK(crom_remesh_swap(&in, &other, &x, &out, NULL, NULL) == CROM_EUSAGE);
    x.scale = 1;
    x.deg = 10;
    CHECK(crom_remesh_swap(&in, &other, &x, &out, NULL, NULL) == CROM_EUSAGE); /* zero axis */
    crom_mesh_free(&in);
    crom_mesh_free(&other);
}

/* --------------------------------------------------------------- refine */

typedef struct {
    double p[3];
    int a, b;
} mid;

static int mid_cmp(const void *x, const void *y)
{
    const mid *p = x, *q = y;
    for (int k = 0; k < 3; k++)
        if (p->p[k] != q->p[k])
            return p->p[k] < q->p[k] ? -1 : 1;
    return 0;
}

static void test_refine(void)
{
    crom_mesh m, r;
    fx_gen(CROM_MESHGEN_SPHERE, NULL, 0.2, &m);
    CHECK(crom_mesh_region_spec(&m, "cap=y>0.2") == 0);
    CHECK(crom_mesh_region_spec(&m, "slab=box:-1,-0.1,-1,1,0.1,1") == 0);
    double V = crom_mesh_volume(&m), w0, w1, mean;
    int wt;
    crom_mesh_quality(&m, &w0, &mean, &wt);
    int rc = crom_remesh_refine(&m, 1, &r, NULL, NULL);
    CHECK_MSG(rc == 0, "refine: %s", crom_errmsg());
    if (rc)
        exit(1);
    crom_mesh_quality(&r, &w1, &mean, &wt);
    fprintf(stderr, "refine: %d -> %d tets, %d -> %d vertices, volume %.15f -> %.15f, worst quality %.3f -> %.3f\n",
            m.nt, r.nt, m.nv, r.nv, V, crom_mesh_volume(&r), w0, w1);
    CHECK(r.nt == 8 * m.nt);
    CHECK_REL(crom_mesh_volume(&r), V, 1e-13);
    CHECK(!memcmp(r.X, m.X, sizeof(double) * 3 * m.nv)); /* every vertex kept, same index */
    all_positive(&r, "refined");
    CHECK(w1 >= 0.5 * w0);

    /* the edges of m, with their midpoints, sorted by position */
    mid *e = malloc(sizeof(mid) * 6 * m.nt);
    int ne = 0;
    for (int t = 0; t < m.nt; t++)
        for (int i = 0; i < 4; i++)
            for (int j = i + 1; j < 4; j++) {
                int a = m.tets[4 * t + i], b = m.tets[4 * t + j];
                mid *q = &e[ne++];
                q->a = a < b ? a : b;
                q->b = a < b ? b : a;
                for (int k = 0; k < 3; k++)
                    q->p[k] = (m.X[3 * a + k] + m.X[3 * b + k]) / 2;
            }
    qsort(e, ne, sizeof *e, mid_cmp);
    int u = 0;
    for (int i = 0; i < ne; i++)
        if (i == 0 || e[i].a != e[u - 1].a || e[i].b != e[u - 1].b)
            e[u++] = e[i];
    CHECK(r.nv == m.nv + u); /* one new vertex per edge */
    /* each new vertex is an edge midpoint; it is in a region iff both ends are */
    const char *names[2] = {"cap", "slab"};
    int found = 0, rule = 1;
    for (int w = m.nv; w < r.nv; w++) {
        mid key;
        memcpy(key.p, r.X + 3 * w, sizeof key.p);
        mid *hit = bsearch(&key, e, u, sizeof *e, mid_cmp);
        if (!hit)
            continue;
        found++;
        for (int q = 0; q < 2; q++) {
            const crom_mesh_region *g0 = crom_mesh_find_region(&m, names[q]), *g1 = crom_mesh_find_region(&r, names[q]);
            int a_in = 0, b_in = 0, w_in = 0;
            for (int j = 0; j < g0->n; j++) {
                a_in |= g0->idx[j] == hit->a;
                b_in |= g0->idx[j] == hit->b;
            }
            for (int j = 0; j < g1->n; j++)
                w_in |= g1->idx[j] == w;
            rule &= w_in == (a_in && b_in);
        }
    }
    CHECK_MSG(found == r.nv - m.nv, "%d of %d new vertices are exact edge midpoints", found, r.nv - m.nv);
    CHECK_MSG(rule, "midpoint region membership rule");
    for (int q = 0; q < 2; q++) { /* original members are unchanged */
        const crom_mesh_region *g0 = crom_mesh_find_region(&m, names[q]), *g1 = crom_mesh_find_region(&r, names[q]);
        CHECK(g1->n >= g0->n && !memcmp(g1->idx, g0->idx, sizeof(int) * g0->n));
    }
    free(e);
    crom_mesh_free(&r);

    /* twice: x 64 */
    CHECK(crom_remesh_refine(&m, 2, &r, NULL, NULL) == 0);
    CHECK(r.nt == 64 * m.nt);
    CHECK_REL(crom_mesh_volume(&r), V, 1e-13);
    crom_mesh_quality(&r, &w1, &mean, &wt);
    fprintf(stderr, "refine x2: %d tets, worst quality %.3f\n", r.nt, w1);
    all_positive(&r, "refined twice");
    crom_mesh_free(&r);
    CHECK(crom_remesh_refine(&m, 0, &r, NULL, NULL) == CROM_EUSAGE);
    crom_mesh_free(&m);

    /* a structured grid: exact volume, quality bound */
    fx_unit_grid(&m, 3, 1);
    crom_mesh_quality(&m, &w0, &mean, &wt);
    CHECK(crom_remesh_refine(&m, 1, &r, NULL, NULL) == 0);
    crom_mesh_quality(&r, &w1, &mean, &wt);
    fprintf(stderr, "refine grid: worst quality %.3f -> %.3f\n", w0, w1);
    CHECK_NEAR(crom_mesh_volume(&r), 1, 1e-13);
    CHECK(w1 >= 0.5 * w0);
    crom_mesh_free(&r);
    crom_mesh_free(&m);
}

static void test_helpers(void)
{
    crom_mesh m;
    fx_unit_grid(&m, 2, 1);
    CHECK(crom_remesh_components(&m, NULL) == 1);
    CHECK(crom_mesh_region_spec(&m, "a=x<0.1") == 0 && crom_mesh_region_spec(&m, "b=x>0.9") == 0);
    CHECK(crom_remesh_remove_region(&m, "a") == 1 && crom_remesh_remove_region(&m, "a") == 0);
    CHECK(m.nregions == 1 && !strcmp(m.regions[0].name, "b"));
    crom_mesh_free(&m);
}

int main(void)
{
    check_begin("test_remesh");
    test_helpers();
    test_cut_grid();
    test_cut_plate();
    test_punch();
    test_swap();
    test_refine();
    return check_done();
}
