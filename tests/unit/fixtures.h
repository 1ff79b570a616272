/* fixtures.h — the meshes and fields crom's unit tests share: structured
 * Kuhn grids (no gmsh needed), gmsh shapes, and analytic displacement
 * fields for the tests of lib/locate, lib/model and lib/fit. Include after
 * check.h. */
#ifndef CROM_FIXTURES_H
#define CROM_FIXTURES_H

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "mesh/mesh.h"
#include "mesh/meshgen.h"
#include "base/rng.h"
#include "rom/samples.h"

#ifdef _LAPACKE_H_ /* for the tests that include <lapacke.h> (its complex.h defines I) */
/* smallest eigenvalue of a symmetric n×n matrix (NAN when LAPACK fails) */
static inline double fx_min_eig(const double *M, int n)
{
    double *A = malloc(sizeof(double) * (size_t)n * n), *w = malloc(sizeof(double) * (size_t)n), e = NAN;
    memcpy(A, M, sizeof(double) * (size_t)n * n);
    if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'N', 'U', n, A, n, w) == 0)
        e = w[0];
    free(A);
    free(w);
    return e;
}
#endif

/* Uniformly random rotation from a normalized Gaussian quaternion. */
static inline void fx_random_rotation(crom_rng *r, double R[9])
{
    double q[4], n = 0;
    for (int i = 0; i < 4; i++) {
        q[i] = crom_rng_normal(r);
        n += q[i] * q[i];
    }
    n = sqrt(n);
    double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    double M[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                   2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                   2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)};
    memcpy(R, M, sizeof M);
}

/* nx x ny x nz boxes of sides h [3] from lo [3] (lo NULL: the origin),
 * each split into 6 tets along its main diagonal (Kuhn subdivision), vertex
 * (i, j, k) at index (k (ny+1) + j)(nx+1) + i. Interior vertices are moved
 * by up to jitter * h at random (rng; jitter 0: rng may be NULL). keep(i,
 * j, k) (may be NULL) says which boxes to keep, for non-convex shapes;
 * unused vertices are then dropped. orient: make every tet positively
 * oriented (0 leaves half of the Kuhn tets negative, for tests of
 * crom_mesh_orient). */
static inline void fx_grid(crom_mesh *m, int nx, int ny, int nz, const double lo[3], const double h[3],
                           double jitter, crom_rng *rng, int (*keep)(int, int, int), int orient)
{
    static const double zero[3] = {0, 0, 0};
    if (!lo)
        lo = zero;
    memset(m, 0, sizeof *m);
    int vx = nx + 1, vy = ny + 1, vz = nz + 1;
    m->nv = vx * vy * vz;
    m->X = malloc(sizeof(double) * 3 * (size_t)m->nv);
    for (int k = 0; k < vz; k++)
        for (int j = 0; j < vy; j++)
            for (int i = 0; i < vx; i++) {
                double *x = m->X + 3 * (size_t)((k * vy + j) * vx + i);
                int in = jitter != 0 && i > 0 && i < nx && j > 0 && j < ny && k > 0 && k < nz;
                int c[3] = {i, j, k};
                for (int a = 0; a < 3; a++)
                    x[a] = lo[a] + c[a] * h[a] + (in ? jitter * h[a] * (2 * crom_rng_uniform(rng) - 1) : 0);
            }
    m->tets = malloc(sizeof(int) * 4 * 6 * (size_t)nx * ny * nz);
    static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (int k = 0; k < nz; k++)
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++) {
                if (keep && !keep(i, j, k))
                    continue;
                for (int p = 0; p < 6; p++) {
                    int c[3] = {i, j, k}, *t = m->tets + 4 * (size_t)m->nt;
                    for (int s = 0; s < 4; s++) {
                        if (s > 0)
                            c[perms[p][s - 1]]++;
                        t[s] = (c[2] * vy + c[1]) * vx + c[0];
                    }
                    if (orient && crom_mesh_tet_volume(m->X + 3 * t[0], m->X + 3 * t[1], m->X + 3 * t[2],
                                                       m->X + 3 * t[3]) < 0) {
                        int tmp = t[2];
                        t[2] = t[3];
                        t[3] = tmp;
                    }
                    m->nt++;
                }
            }
    if (keep)
        crom_mesh_compact(m);
}

/* A box [lo, lo + n h] of cubes of side h, jittered and kept as fx_grid,
 * positively oriented. */
static inline void fx_box_mesh(crom_mesh *m, int nx, int ny, int nz, const double lo[3], double h,
                               double jitter, crom_rng *rng, int (*keep)(int, int, int))
{
    const double hh[3] = {h, h, h};
    fx_grid(m, nx, ny, nz, lo, hh, jitter, rng, keep, 1);
}

/* The unit cube [0,1]^3 as n^3 Kuhn-split cubes, oriented or not. */
static inline void fx_unit_grid(crom_mesh *m, int n, int orient)
{
    const double h[3] = {1.0 / n, 1.0 / n, 1.0 / n};
    fx_grid(m, n, n, n, NULL, h, 0, NULL, NULL, orient);
}

/* A gmsh mesh of shape (CROM_MESHGEN_BOX ...) with extents dims (NULL: the
 * shape's default) at edge length size. Returns crom_meshgen's code, after
 * a CHECK that it is 0. */
static inline int fx_gen(int shape, const double dims[3], double size, crom_mesh *m)
{
    crom_meshgen_opts o;
    crom_meshgen_defaults(&o, shape);
    if (dims)
        memcpy(o.dims, dims, sizeof o.dims);
    o.size = size;
    int rc = crom_meshgen(&o, m);
    CHECK_MSG(rc == 0, "meshgen shape %d size %g: %s", shape, size, crom_errmsg());
    return rc;
}

/* Smooth analytic displacement modes on xi = X / L (component c of mode k). */
#define FX_NMODES 8
static inline void fx_mode(int k, const double *X, double L, double *u)
{
    double x = X[0] / L, y = X[1] / L, z = X[2] / L, pi = 3.14159265358979323846;
    double m[FX_NMODES][3] = {
        {0, x * x, 0},
        {-z * y, 0, x * y},
        {x, -0.3 * y, -0.3 * z},
        {y, 0, 0},
        {x * (1 - y * y), 0, z * (1 - y * y)},
        {0, 0, sin(pi * x)},
        {0, x * sin(pi * z), 0},
        {z * cos(pi * y), 0, 0},
    };
    memcpy(u, m[k], sizeof(double) * 3);
}

/* Append F frames of u = sum_k a_fk phi_k (K modes, a_fk = amp decay^k N(0,1))
 * sampled at every vertex of mesh m (source index src, which must already be
 * in S->src) to S. S->N must be m->nv for every source appended. */
static inline void fx_add_frames(crom_samples *S, int src, int F, int K, double decay, double amp,
                          double L, crom_rng *rng)
{
    const crom_mesh *m = &S->src[src];
    int N = m->nv, F0 = S->F;
    S->N = N;
    S->F += F;
    S->X = realloc(S->X, sizeof(float) * 3 * (size_t)S->F * N);
    S->U = realloc(S->U, sizeof(float) * 3 * (size_t)S->F * N);
    S->vertex = realloc(S->vertex, sizeof(int) * (size_t)S->F * N);
    S->source = realloc(S->source, sizeof(int) * (size_t)S->F);
    S->time = realloc(S->time, sizeof(double) * (size_t)S->F);
    for (int f = F0; f < S->F; f++) {
        double a[FX_NMODES];
        for (int k = 0; k < K; k++)
            a[k] = amp * pow(decay, k) * crom_rng_normal(rng);
        for (int v = 0; v < N; v++) {
            size_t j = (size_t)f * N + v;
            double u[3] = {0, 0, 0}, p[3];
            for (int k = 0; k < K; k++) {
                fx_mode(k, m->X + 3 * (size_t)v, L, p);
                for (int c = 0; c < 3; c++)
                    u[c] += a[k] * p[c];
            }
            for (int c = 0; c < 3; c++) {
                S->X[3 * j + c] = (float)m->X[3 * (size_t)v + c];
                S->U[3 * j + c] = (float)u[c];
            }
            S->vertex[j] = v;
        }
        S->source[f] = src;
        S->time[f] = 0.01 * f;
    }
}

/* Start a sample set with nsrc source meshes (moved into S). */
static inline void fx_samples_init(crom_samples *S, crom_mesh *meshes, int nsrc)
{
    memset(S, 0, sizeof *S);
    S->nsources = nsrc;
    S->src = calloc((size_t)nsrc, sizeof(crom_mesh));
    S->src_file = calloc((size_t)nsrc, sizeof(char *));
    for (int k = 0; k < nsrc; k++) {
        S->src[k] = meshes[k];
        memset(&meshes[k], 0, sizeof meshes[k]);
        S->src_file[k] = strdup("fixture");
    }
    snprintf(S->mode, sizeof S->mode, "vertices");
}

#endif
