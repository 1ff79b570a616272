/* locate.c — point location in tet meshes (see locate.h). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "mesh/locate.h"

#define INSIDE_TOL 1e-12

void crom_locate_free(crom_locator *L)
{
    if (!L)
        return;
    free(L->start);
    free(L->items);
    free(L->Tinv);
    memset(L, 0, sizeof *L);
}

static void cell_range(const crom_locator *L, double lo, double hi, int axis, int *a, int *b)
{
    double fa = (lo - L->lo[axis]) / L->h[axis], fb = (hi - L->lo[axis]) / L->h[axis];
    int ia = (int)floor(fa), ib = (int)floor(fb);
    int n = L->n[axis];
    *a = ia < 0 ? 0 : ia >= n ? n - 1 : ia;
    *b = ib < 0 ? 0 : ib >= n ? n - 1 : ib;
}

int crom_locate_init(crom_locator *L, const crom_mesh *m)
{
    memset(L, 0, sizeof *L);
    if (!m || m->nt < 1 || m->nv < 4)
        return crom_err(CROM_EDATA, "point location needs a mesh with at least one tet");
    L->X = m->X;
    L->tets = m->tets;
    L->nv = m->nv;
    L->nt = m->nt;
    /* inverse edge matrices */
    L->Tinv = crom_malloc(sizeof(double) * 9 * (size_t)m->nt);
    if (!L->Tinv)
        return CROM_EINTERNAL;
    for (int t = 0; t < m->nt; t++) {
        const int *v = m->tets + 4 * (size_t)t;
        const double *x0 = m->X + 3 * (size_t)v[0];
        double D[3][3];
        for (int j = 0; j < 3; j++)
            for (int i = 0; i < 3; i++)
                D[i][j] = m->X[3 * (size_t)v[j + 1] + i] - x0[i];
        double c00 = D[1][1] * D[2][2] - D[1][2] * D[2][1];
        double c01 = D[1][2] * D[2][0] - D[1][0] * D[2][2];
        double c02 = D[1][0] * D[2][1] - D[1][1] * D[2][0];
        double det = D[0][0] * c00 + D[0][1] * c01 + D[0][2] * c02;
        if (!(fabs(det) > 0) || !isfinite(det)) {
            crom_locate_free(L);
            return crom_err(CROM_EDATA, "tet %d is degenerate: cannot locate points in it", t);
        }
        double id = 1.0 / det, *M = L->Tinv + 9 * (size_t)t;
        M[0] = c00 * id;
        M[1] = (D[0][2] * D[2][1] - D[0][1] * D[2][2]) * id;
        M[2] = (D[0][1] * D[1][2] - D[0][2] * D[1][1]) * id;
        M[3] = c01 * id;
        M[4] = (D[0][0] * D[2][2] - D[0][2] * D[2][0]) * id;
        M[5] = (D[0][2] * D[1][0] - D[0][0] * D[1][2]) * id;
        M[6] = c02 * id;
        M[7] = (D[0][1] * D[2][0] - D[0][0] * D[2][1]) * id;
        M[8] = (D[0][0] * D[1][1] - D[0][1] * D[1][0]) * id;
    }
    /* grid over the bounding box, about one cell per tet */
    double lo[3], hi[3];
    crom_mesh_bbox(m, lo, hi);
    double ext[3], vol = 1, maxext = 0;
    for (int i = 0; i < 3; i++) {
        ext[i] = hi[i] - lo[i];
        maxext = ext[i] > maxext ? ext[i] : maxext;
    }
    for (int i = 0; i < 3; i++) {
        if (ext[i] < 1e-9 * maxext)
            ext[i] = 1e-9 * maxext;
        vol *= ext[i];
    }
    double h = cbrt(vol / (double)m->nt);
    long ncells = 1;
    for (int i = 0; i < 3; i++) {
        double nn = ceil(ext[i] / h);
        L->n[i] = nn < 1 ? 1 : nn > 512 ? 512 : (int)nn;
        L->h[i] = ext[i] / L->n[i] * (1 + 1e-12);
        L->lo[i] = lo[i];
        ncells *= L->n[i];
    }
    L->start = crom_calloc((size_t)ncells + 1, sizeof(int));
    if (!L->start) {
        crom_locate_free(L);
        return CROM_EINTERNAL;
    }
    /* two passes: count, then fill (CSR) */
    size_t total = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (int t = 0; t < m->nt; t++) {
            const int *v = m->tets + 4 * (size_t)t;
            int a[3], b[3];
            for (int i = 0; i < 3; i++) {
                double mn = DBL_MAX, mx = -DBL_MAX;
                for (int k = 0; k < 4; k++) {
                    double x = m->X[3 * (size_t)v[k] + i];
                    mn = x < mn ? x : mn;
                    mx = x > mx ? x : mx;
                }
                cell_range(L, mn, mx, i, &a[i], &b[i]);
            }
            for (int z = a[2]; z <= b[2]; z++)
                for (int y = a[1]; y <= b[1]; y++)
                    for (int x = a[0]; x <= b[0]; x++) {
                        long c = ((long)z * L->n[1] + y) * L->n[0] + x;
                        if (pass == 0) {
                            L->start[c + 1]++;
                            total++;
                        } else {
                            L->items[L->start[c]++] = t;
                        }
                    }
        }
        if (pass == 0) {
            if (total > 0x7fffffff) {
                crom_locate_free(L);
                return crom_err(CROM_EINTERNAL, "point-location grid too large");
            }
            for (long c = 0; c < ncells; c++)
                L->start[c + 1] += L->start[c];
            L->items = crom_malloc(sizeof(int) * (total ? total : 1));
            if (!L->items) {
                crom_locate_free(L);
                return CROM_EINTERNAL;
            }
        }
    }
    /* the fill pass advanced start[c] to the end of cell c: shift back */
    for (long c = ncells; c > 0; c--)
        L->start[c] = L->start[c - 1];
    L->start[0] = 0;
    return 0;
}

void crom_locate_bary(const crom_locator *L, int t, const double p[3], double bary[4])
{
    const double *M = L->Tinv + 9 * (size_t)t, *x0 = L->X + 3 * (size_t)L->tets[4 * (size_t)t];
    double d[3] = {p[0] - x0[0], p[1] - x0[1], p[2] - x0[2]};
    bary[1] = M[0] * d[0] + M[1] * d[1] + M[2] * d[2];
    bary[2] = M[3] * d[0] + M[4] * d[1] + M[5] * d[2];
    bary[3] = M[6] * d[0] + M[7] * d[1] + M[8] * d[2];
    bary[0] = 1.0 - bary[1] - bary[2] - bary[3];
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Closest point of triangle (a, b, c) to p, as barycentric weights w[3]
 * (Voronoi regions of the vertices, edges and face). */
static void closest_on_triangle(const double *a, const double *b, const double *c,
                                const double *p, double w[3])
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    for (int i = 0; i < 3; i++) {
        ab[i] = b[i] - a[i];
        ac[i] = c[i] - a[i];
        ap[i] = p[i] - a[i];
        bp[i] = p[i] - b[i];
        cp[i] = p[i] - c[i];
    }
    double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        w[0] = 1, w[1] = 0, w[2] = 0;
        return;
    }
    double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        w[0] = 0, w[1] = 1, w[2] = 0;
        return;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double v = d1 / (d1 - d3);
        w[0] = 1 - v, w[1] = v, w[2] = 0;
        return;
    }
    double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        w[0] = 0, w[1] = 0, w[2] = 1;
        return;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double v = d2 / (d2 - d6);
        w[0] = 1 - v, w[1] = 0, w[2] = v;
        return;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        double v = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        w[0] = 0, w[1] = 1 - v, w[2] = v;
        return;
    }
    double den = 1.0 / (va + vb + vc);
    w[1] = vb * den;
    w[2] = vc * den;
    w[0] = 1 - w[1] - w[2];
}

double crom_locate_tri_dist2(const double a[3], const double b[3], const double c[3], const double p[3])
{
    double w[3], d2 = 0;
    closest_on_triangle(a, b, c, p, w);
    for (int i = 0; i < 3; i++) {
        double d = w[0] * a[i] + w[1] * b[i] + w[2] * c[i] - p[i];
        d2 += d * d;
    }
    return d2;
}

/* Squared distance from p to tet t, with the barycentric weights of the
 * closest point in bary[4]. */
static double tet_distance2(const crom_locator *L, int t, const double *p, double bary[4])
{
    crom_locate_bary(L, t, p, bary);
    if (bary[0] >= 0 && bary[1] >= 0 && bary[2] >= 0 && bary[3] >= 0)
        return 0;
    static const int face[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
    const int *v = L->tets + 4 * (size_t)t;
    double best = DBL_MAX;
    for (int f = 0; f < 4; f++) {
        const double *a = L->X + 3 * (size_t)v[face[f][0]], *b = L->X + 3 * (size_t)v[face[f][1]],
                     *c = L->X + 3 * (size_t)v[face[f][2]];
        double w[3], q[3];
        closest_on_triangle(a, b, c, p, w);
        for (int i = 0; i < 3; i++)
            q[i] = w[0] * a[i] + w[1] * b[i] + w[2] * c[i] - p[i];
        double d2 = dot3(q, q);
        if (d2 < best) {
            best = d2;
            double nb[4] = {0, 0, 0, 0};
            for (int k = 0; k < 3; k++)
                nb[face[f][k]] = w[k];
            memcpy(bary, nb, sizeof nb);
        }
    }
    return best;
}

int crom_locate_point(const crom_locator *L, const double p[3], int *tet, double bary[4],
                      double *dist)
{
    int c3[3], inside_grid = 1;
    for (int i = 0; i < 3; i++) {
        double f = (p[i] - L->lo[i]) / L->h[i];
        int k = (int)floor(f);
        if (!(f >= 0) || k >= L->n[i])
            inside_grid = 0;
        c3[i] = !(f >= 0) ? 0 : k >= L->n[i] ? L->n[i] - 1 : k;
    }
    if (inside_grid) {
        long c = ((long)c3[2] * L->n[1] + c3[1]) * L->n[0] + c3[0];
        int best = -1;
        double bestmin = -INFINITY, b[4];
        for (int k = L->start[c]; k < L->start[c + 1]; k++) {
            int t = L->items[k];
            crom_locate_bary(L, t, p, b);
            double mn = fmin(fmin(b[0], b[1]), fmin(b[2], b[3]));
            if (mn >= -INSIDE_TOL && mn > bestmin) {
                bestmin = mn;
                best = t;
                memcpy(bary, b, sizeof b);
            }
        }
        if (best >= 0) {
            *tet = best;
            if (dist)
                *dist = 0;
            return 1;
        }
    }
    /* nearest tet: search shells of cells around c3 outwards; every tet whose
     * cells all lie beyond shell k is at least k * hmin away */
    double hmin = fmin(L->h[0], fmin(L->h[1], L->h[2]));
    int kmax = L->n[0] > L->n[1] ? L->n[0] : L->n[1];
    kmax = kmax > L->n[2] ? kmax : L->n[2];
    double best2 = INFINITY, b[4];
    int best = -1;
    for (int k = 0; k <= kmax; k++) {
        for (int z = c3[2] - k; z <= c3[2] + k; z++) {
            if (z < 0 || z >= L->n[2])
                continue;
            for (int y = c3[1] - k; y <= c3[1] + k; y++) {
                if (y < 0 || y >= L->n[1])
                    continue;
                for (int x = c3[0] - k; x <= c3[0] + k; x++) {
                    if (x < 0 || x >= L->n[0])
                        continue;
                    if (abs(x - c3[0]) < k && abs(y - c3[1]) < k && abs(z - c3[2]) < k)
                        continue; /* interior of the shell: already visited */
                    long c = ((long)z * L->n[1] + y) * L->n[0] + x;
                    for (int i = L->start[c]; i < L->start[c + 1]; i++) {
                        int t = L->items[i];
                        double d2 = tet_distance2(L, t, p, b);
                        if (d2 < best2 || (d2 == best2 && t < best)) {
                            best2 = d2;
                            best = t;
                            memcpy(bary, b, sizeof b);
                        }
                    }
                }
            }
        }
        if (best >= 0 && sqrt(best2) <= k * hmin)
            break;
    }
    *tet = best;
    if (dist)
        *dist = sqrt(best2);
    /* a point inside the grid that no cell tet contains within tolerance but
     * at distance 0 lies on the mesh (rounding): call it inside */
    return best2 == 0 ? 1 : 0;
}

void crom_locate_interp(const crom_locator *L, size_t n, const double *P, int dim,
                        const double *f, double *out, size_t *noutside)
{
    size_t nout = 0;
    for (size_t i = 0; i < n; i++) {
        int t;
        double b[4];
        if (!crom_locate_point(L, P + 3 * i, &t, b, NULL))
            nout++;
        const int *v = L->tets + 4 * (size_t)t;
        double *o = out + i * (size_t)dim;
        for (int d = 0; d < dim; d++)
            o[d] = 0;
        for (int k = 0; k < 4; k++) {
            const double *fv = f + (size_t)v[k] * dim;
            for (int d = 0; d < dim; d++)
                o[d] += b[k] * fv[d];
        }
    }
    if (noutside)
        *noutside = nout;
}
