/* test_skin.c — lib/skin, lib/dfskin, lib/cloud: the skinning-handle
 * subspace and its weights.
 *
 *  - the body frame: X̂ has zero mass mean and identity covariance;
 *  - the skinning map: W(X) against central differences of the linear blend
 *    skinning x = X + Σ_h w_h (T_h − [I|0]) [X; 1] computed from the handle
 *    transforms of crom_skin_handles, in handle and in orthonormal
 *    coordinates (whose functions are mass-orthonormal: WᵀMW = m I);
 *  - a rigid rotation of a free body lies in the subspace exactly: the
 *    decoded positions are R X + t to round-off and the energy is 0, for
 *    eigen and trained weights;
 *  - pins: every weight vanishes on the clamp (eigen: exactly 0; trained:
 *    the mask), on the training mesh and on another mesh of the body;
 *  - the trained loss: its gradient against central differences (pinned
 *    and free, with a repeat in the cubature), and its energy term equals
 *    the FEM energy of the displaced tets;
 *  - skinning eigenmodes: eigenvectors of the scalar stiffness (residual
 *    against an assembled K_s), M-orthonormal, with the constant first on a
 *    free body; handle counts out of range are refused;
 *  - point samplings: the winding-number inside test, a sampled box holds
 *    its exact volume, the virtual tets have the points' volumes, pins of a
 *    sampled surface, and bad point clouds.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "mesh/cloud.h"
#include "rom/cubature.h"
#include "datafree/dfskin.h"
#include "base/err.h"
#include "phys/fem.h"
#include "mesh/locate.h"
#include "mesh/meshgen.h"
#include "rom/model.h"
#include "nn/nn.h"
#include "base/rng.h"
#include "rom/skin.h"

static void make_bar(crom_mesh *m, double size)
{
    crom_meshgen_opts o;
    crom_meshgen_defaults(&o, CROM_MESHGEN_BOX);
    o.size = size;
    o.dims[0] = 1;
    o.dims[1] = 0.2;
    o.dims[2] = 0.2;
    int rc = crom_meshgen(&o, m);
    CHECK_MSG(rc == 0, "meshgen: %s", crom_errmsg());
}

static unsigned char *clamp_mask(const crom_mesh *m)
{
    unsigned char *f = calloc(3 * (size_t)m->nv, 1);
    for (int v = 0; v < m->nv; v++)
        if (m->X[3 * v] < -0.49)
            memset(f + 3 * v, 1, 3);
    return f;
}

/* ------------------------------------------------------------ frame */

static void test_frame(const crom_mesh *m)
{
    double *vv = malloc(sizeof(double) * m->nv), F[12];
    crom_mesh_vertex_volumes(m, vv);
    CHECK(crom_skin_frame((size_t)m->nv, m->X, vv, F) == 0);
    double mt = 0, mean[3] = {0}, cov[9] = {0};
    for (int v = 0; v < m->nv; v++) {
        double xh[3];
        for (int a = 0; a < 3; a++)
            xh[a] = F[4 * a] * m->X[3 * v] + F[4 * a + 1] * m->X[3 * v + 1] + F[4 * a + 2] * m->X[3 * v + 2] + F[4 * a + 3];
        mt += vv[v];
        for (int a = 0; a < 3; a++) {
            mean[a] += vv[v] * xh[a];
            for (int b = 0; b < 3; b++)
                cov[3 * a + b] += vv[v] * xh[a] * xh[b];
        }
    }
    double err = 0;
    for (int a = 0; a < 3; a++) {
        err = fmax(err, fabs(mean[a] / mt));
        for (int b = 0; b < 3; b++)
            err = fmax(err, fabs(cov[3 * a + b] / mt - (a == b)));
    }
    /* a 1 x 0.2 x 0.2 bar: the frame scales x by about 1/0.289 (lumped
     * volumes put more mass on the surface than a uniform density) and y, z
     * by about 5 times that; P = Σ^-1/2 is symmetric */
    fprintf(stderr, "frame: |mean|, |cov - I| <= %.2e; scales %.4f %.4f %.4f\n", err, F[0], F[5], F[10]);
    CHECK_LT(err, 1e-12);
    CHECK_NEAR(F[0], sqrt(12.0), 0.1 * sqrt(12.0));
    CHECK(F[5] > 3 * F[0] && F[10] > 3 * F[0]);
    CHECK_LT(fabs(F[1] - F[4]) + fabs(F[2] - F[8]) + fabs(F[6] - F[9]), 1e-12 * F[5]);
    double w[1] = {0};
    CHECK(crom_skin_frame(1, m->X, w, F) == CROM_EDATA); /* no mass */
    free(vv);
}

/* ------------------------------------------------- the skinning map */

typedef struct {
    const crom_model *m;
    int n;
    const double *X, *w; /* [n][3], [n][H] */
} lbs_case;

/* x = X + Σ_h w_h (T_h − [I|0]) [X; 1], from the handle transforms */
static void lbs_at(const double *q, void *v, double *out)
{
    lbs_case *t = v;
    int H = t->m->handles;
    double *T = malloc(sizeof(double) * 12 * H);
    crom_skin_handles(t->m, q, T);
    for (int i = 0; i < t->n; i++) {
        const double *X = t->X + 3 * i;
        for (int c = 0; c < 3; c++) {
            double x = X[c];
            for (int h = 0; h < H; h++) {
                const double *Th = T + 12 * h + 4 * c;
                x += t->w[(size_t)i * H + h] * (Th[0] * X[0] + Th[1] * X[1] + Th[2] * X[2] + Th[3] - X[c]);
            }
            out[3 * i + c] = x;
        }
    }
    free(T);
}

static void check_map(const crom_model *m, int n, const double *X, const char *what)
{
    int r = m->rank, H = m->handles;
    double *w = malloc(sizeof(double) * n * H), *W = malloc(sizeof(double) * n * 3 * r);
    double *J = malloc(sizeof(double) * n * 3 * r), *q = malloc(sizeof(double) * r), *x = malloc(sizeof(double) * 3 * n);
    CHECK(crom_skin_weights(m, (size_t)n, X, w, NULL) == 0);
    CHECK(crom_model_eval(m, (size_t)n, X, W, NULL) == 0);
    crom_rng rng;
    crom_rng_seed(&rng, 4);
    for (int i = 0; i < r; i++)
        q[i] = 0.05 * crom_rng_normal(&rng);
    lbs_case t = {m, n, X, w};
    check_fd_jacobian(lbs_at, &t, q, r, 3 * n, 1e-4, J);
    double e = check_relerr(W, J, 3 * n * r, 1e-12);
    /* and the map itself: x = X + W q */
    lbs_at(q, &t, x);
    double ex = 0;
    for (int i = 0; i < 3 * n; i++) {
        double u = 0;
        for (int k = 0; k < r; k++)
            u += W[(size_t)i * r + k] * q[k];
        ex = fmax(ex, fabs(X[i] + u - x[i]));
    }
    /* q = 0 is the rest shape exactly */
    memset(q, 0, sizeof(double) * r);
    lbs_at(q, &t, x);
    double e0 = 0;
    for (int i = 0; i < 3 * n; i++)
        e0 = fmax(e0, fabs(x[i] - X[i]));
    fprintf(stderr, "%s: W(X) vs differences of the skinning map %.2e, |X + W q - x(q)| %.2e, rest %.1e (rank %d)\n",
            what, e, ex, e0, r);
    CHECK_LT(e, 1e-8);
    CHECK_LT(ex, 1e-12);
    CHECK(e0 == 0);
    free(w);
    free(W);
    free(J);
    free(q);
    free(x);
}

/* W^T M W / m over the mesh: the identity in orthonormal coordinates */
static double gram_error(const crom_model *m, const crom_mesh *mesh)
{
    int r = m->rank, nv = mesh->nv;
    double *W = malloc(sizeof(double) * nv * 3 * r), *vv = malloc(sizeof(double) * nv), *G = calloc(r * r, 8), mt = 0;
    crom_mesh_vertex_volumes(mesh, vv);
    CHECK(crom_model_eval(m, (size_t)nv, mesh->X, W, NULL) == 0);
    for (int v = 0; v < nv; v++) {
        mt += vv[v];
        for (int c = 0; c < 3; c++) {
            const double *Wr = W + ((size_t)v * 3 + c) * r;
            for (int a = 0; a < r; a++)
                for (int b = 0; b < r; b++)
                    G[a * r + b] += vv[v] * Wr[a] * Wr[b];
        }
    }
    double e = 0;
    for (int a = 0; a < r; a++)
        for (int b = 0; b < r; b++)
            e = fmax(e, fabs(G[a * r + b] / mt - (a == b)));
    free(W);
    free(vv);
    free(G);
    return e;
}

/* positions X + W q of the mesh and their elastic energy */
static double energy_at(const crom_model *m, const crom_mesh *mesh, const crom_material *mat, const double *q,
                        double *x)
{
    int r = m->rank, nv = mesh->nv;
    double *W = malloc(sizeof(double) * nv * 3 * r);
    CHECK(crom_model_eval(m, (size_t)nv, mesh->X, W, NULL) == 0);
    for (int i = 0; i < 3 * nv; i++) {
        double u = 0;
        for (int k = 0; k < r; k++)
            u += W[(size_t)i * r + k] * q[k];
        x[i] = mesh->X[i] + u;
    }
    crom_fem fem;
    CHECK(crom_fem_init(&fem, mesh, mat) == 0);
    double E = NAN;
    crom_fem_opts fo = {0, 0, NULL, 1};
    CHECK(crom_fem_assemble(&fem, x, &fo, &E, NULL, NULL) == 0);
    crom_fem_free(&fem);
    free(W);
    return E;
}

/* A rotation by 0.7 rad about (1, 2, 3) and a translation of the whole free
 * body: in orthonormal coordinates q[cS + s], s < 4, are the affine part
 * (ψ = X̂, 1), so q = [(R − I) P⁻¹ | (R − I) c + t] exactly. */
static void check_rigid(const crom_model *m, const crom_mesh *mesh, const crom_material *mat, const char *what)
{
    CHECK(m->skin_constant == 1 && m->skin_C);
    int r = m->rank, nv = mesh->nv;
    double ax[3] = {1, 2, 3}, nrm = sqrt(14.0), th = 0.7, R[9], t[3] = {0.1, -0.3, 0.2};
    for (int k = 0; k < 3; k++)
        ax[k] /= nrm;
    double cs = cos(th), sn = sin(th);
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            R[3 * a + b] = cs * (a == b) + (1 - cs) * ax[a] * ax[b] +
                           sn * (a == b ? 0 : ((b - a + 3) % 3 == 1 ? -ax[3 - a - b] : ax[3 - a - b]));
    /* P⁻¹ and c from the frame X̂ = P X + p0: c = −P⁻¹ p0 */
    const double *F = m->skin_frame;
    double P[9], Pi[9];
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            P[3 * a + b] = F[4 * a + b];
    double det = P[0] * (P[4] * P[8] - P[5] * P[7]) - P[1] * (P[3] * P[8] - P[5] * P[6]) + P[2] * (P[3] * P[7] - P[4] * P[6]);
    Pi[0] = (P[4] * P[8] - P[5] * P[7]) / det;
    Pi[1] = (P[2] * P[7] - P[1] * P[8]) / det;
    Pi[2] = (P[1] * P[5] - P[2] * P[4]) / det;
    Pi[3] = (P[5] * P[6] - P[3] * P[8]) / det;
    Pi[4] = (P[0] * P[8] - P[2] * P[6]) / det;
    Pi[5] = (P[2] * P[3] - P[0] * P[5]) / det;
    Pi[6] = (P[3] * P[7] - P[4] * P[6]) / det;
    Pi[7] = (P[1] * P[6] - P[0] * P[7]) / det;
    Pi[8] = (P[0] * P[4] - P[1] * P[3]) / det;
    double c[3];
    for (int a = 0; a < 3; a++)
        c[a] = -(Pi[3 * a] * F[3] + Pi[3 * a + 1] * F[7] + Pi[3 * a + 2] * F[11]);
    double *q = calloc(r, sizeof(double)), *x = malloc(sizeof(double) * 3 * nv);
    for (int cc = 0; cc < 3; cc++) {
        for (int s = 0; s < 3; s++) {
            double v = 0;
            for (int k = 0; k < 3; k++)
                v += (R[3 * cc + k] - (cc == k)) * Pi[3 * k + s];
            q[cc * m->skin_S + s] = v;
        }
        double v = t[cc];
        for (int k = 0; k < 3; k++)
            v += (R[3 * cc + k] - (cc == k)) * c[k];
        q[cc * m->skin_S + 3] = v;
    }
    double E = energy_at(m, mesh, mat, q, x), err = 0;
    for (int v = 0; v < nv; v++)
        for (int a = 0; a < 3; a++) {
            double y = t[a];
            for (int b = 0; b < 3; b++)
                y += R[3 * a + b] * mesh->X[3 * v + b];
            err = fmax(err, fabs(x[3 * v + a] - y));
        }
    double EV = mat->E * crom_mesh_volume(mesh);
    fprintf(stderr, "%s: a rotation of 0.7 rad and a translation: |x - (R X + t)| <= %.2e m, energy %.2e J "
                    "(E V = %.3g J)\n", what, err, E, EV);
    /* 0 to round-off: the terms of Ψ at a rotation cancel to ~1e-16 of μ */
    CHECK_LT(err, 1e-12);
    CHECK_LT(fabs(E), 1e-14 * EV);
    free(q);
    free(x);
}

/* The reduced gradient and Hessian of one tet with a skinning basis in
 * orthonormal coordinates (crom_cubature_tet takes them by component blocks)
 * against W4ᵀ g and W4ᵀ He W4 summed entry by entry. */
static void check_tet_blocks(const crom_model *m, const crom_mesh *mesh, const crom_material *mat)
{
    int r = m->rank, t = mesh->nt / 2;
    double Xe[12], *W4 = malloc(sizeof(double) * 12 * r), Dm[9], V;
    for (int a = 0; a < 4; a++)
        memcpy(Xe + 3 * a, mesh->X + 3 * mesh->tets[4 * t + a], sizeof(double) * 3);
    CHECK(crom_model_eval(m, 4, Xe, W4, NULL) == 0);
    CHECK(crom_fem_tet_rest(Xe, Dm, &V) == 0);
    double *q = malloc(sizeof(double) * r), *g = calloc(r, 8), *H = calloc((size_t)r * r, 8);
    double *work = malloc(sizeof(double) * (168 + 12 * (size_t)r));
    crom_rng rng;
    crom_rng_seed(&rng, 8);
    for (int i = 0; i < r; i++)
        q[i] = 0.02 * crom_rng_normal(&rng);
    double E = crom_cubature_tet(mat, Xe, W4, r, Dm, V, 0.7, q, 0, g, H, work);
    double xe[12], ge[12], He[144], Ee;
    for (int i = 0; i < 12; i++) {
        xe[i] = Xe[i];
        for (int k = 0; k < r; k++)
            xe[i] += W4[i * r + k] * q[k];
    }
    CHECK(crom_fem_tet_eval(mat, xe, Dm, V, 0, &Ee, ge, He) == 0);
    double eg = 0, eh = 0, gs = 0, hs = 0;
    for (int k = 0; k < r; k++) {
        double v = 0;
        for (int i = 0; i < 12; i++)
            v += 0.7 * W4[i * r + k] * ge[i];
        eg = fmax(eg, fabs(g[k] - v));
        gs = fmax(gs, fabs(v));
        for (int l = 0; l < r; l++) {
            double h = 0;
            for (int i = 0; i < 12; i++)
                for (int j = 0; j < 12; j++)
                    h += 0.7 * W4[i * r + k] * He[i * 12 + j] * W4[j * r + l];
            eh = fmax(eh, fabs(H[k * r + l] - h));
            hs = fmax(hs, fabs(h));
        }
    }
    fprintf(stderr, "one tet, rank %d by component blocks: energy %.6g (%.6g), |g - W^T g_e| %.1e of %.3g, "
                    "|H - W^T H_e W| %.1e of %.3g\n", r, E, Ee, eg, gs, eh, hs);
    CHECK_NEAR(E, Ee, 1e-12 * Ee);
    /* the block structure the kernel detects: component c only in [cS, cS + S) */
    int S = m->skin_S, outside = 0;
    for (int i = 0; i < 12; i++)
        for (int k = 0; k < r; k++)
            outside += W4[i * r + k] != 0 && k / S != i % 3;
    CHECK(outside == 0);
    CHECK_LT(eg, 1e-12 * gs);
    CHECK_LT(eh, 1e-12 * hs);
    free(W4);
    free(q);
    free(g);
    free(H);
    free(work);
}

/* -------------------------------------------------- skinning eigenmodes */

static void test_eigen(const crom_mesh *m, const crom_mesh *other, const crom_material *mat)
{
    crom_model free_m, pin_m;
    long solves = 0;
    /* a free body: the constant and H - 1 eigenvectors */
    int rc = crom_dfskin_eigen(m, mat, NULL, NULL, 5, &free_m, &solves);
    CHECK_MSG(rc == 0, "eigen: %s", crom_errmsg());
    CHECK(free_m.handles == 5 && free_m.skin_constant == 1 && free_m.rank == 60 && free_m.skin_w);
    int nv = m->nv, H = 5;
    double cmax = 0;
    for (int v = 0; v < nv; v++)
        cmax = fmax(cmax, fabs(free_m.skin_w[(size_t)v * H] - 1));
    CHECK(cmax == 0);
    /* eigenvectors of the scalar stiffness: K_s w = λ M w, assembled here
     * from the FEM Hessian's diagonal blocks, and mass-mean orthonormal */
    crom_fem fem;
    CHECK(crom_fem_init(&fem, m, mat) == 0);
    double *K = malloc(sizeof(double) * fem.nnz);
    crom_fem_opts fo = {0, 0, NULL, 1};
    CHECK(crom_fem_assemble(&fem, m->X, &fo, NULL, NULL, K) == 0);
    double *Kw = calloc((size_t)nv * H, sizeof(double));
    for (int col = 0; col < fem.n; col++)
        for (int k = fem.colptr[col]; k < fem.colptr[col + 1]; k++) {
            int row = fem.rowind[k];
            if (row % 3 != col % 3)
                continue;
            int i = row / 3, j = col / 3;
            for (int h = 0; h < H; h++) {
                Kw[(size_t)i * H + h] += K[k] * free_m.skin_w[(size_t)j * H + h];
                if (i != j)
                    Kw[(size_t)j * H + h] += K[k] * free_m.skin_w[(size_t)i * H + h];
            }
        }
    double worst = 0, orth = 0;
    for (int h = 0; h < H; h++) {
        double lam = free_m.skin_eig[h], rn = 0, kn = 0;
        for (int v = 0; v < nv; v++) {
            double d = Kw[(size_t)v * H + h] - lam * fem.mass[v] * free_m.skin_w[(size_t)v * H + h];
            rn += d * d;
            kn += Kw[(size_t)v * H + h] * Kw[(size_t)v * H + h];
        }
        if (h > 0)
            worst = fmax(worst, sqrt(rn / kn));
        else
            worst = fmax(worst, sqrt(rn) / (fem.mass[0] * 1e6)); /* K_s 1 = 0 */
        for (int g = 0; g <= h; g++) {
            double s = 0;
            for (int v = 0; v < nv; v++)
                s += fem.mass[v] * free_m.skin_w[(size_t)v * H + h] * free_m.skin_w[(size_t)v * H + g];
            orth = fmax(orth, fabs(s / fem.total_mass - (g == h)));
        }
        if (h > 0)
            CHECK(lam > 0 && (h == 1 || lam >= free_m.skin_eig[h - 1]));
    }
    fprintf(stderr, "eigen weights (free): residual |K_s w - lambda M w| / |K_s w| <= %.2e, mass-mean "
                    "orthonormal to %.2e, eigenvalues %.4g .. %.4g 1/s^2, %ld solves\n",
            worst, orth, free_m.skin_eig[1], free_m.skin_eig[H - 1], solves);
    CHECK_LT(worst, 1e-6);
    CHECK_LT(orth, 1e-8);
    free(K);
    free(Kw);
    crom_fem_free(&fem);
    /* the map, handle coordinates then orthonormal ones */
    int n = 40;
    double *X = malloc(sizeof(double) * 3 * n);
    crom_rng rng;
    crom_rng_seed(&rng, 2);
    for (int i = 0; i < n; i++) {
        X[3 * i] = 0.9 * (crom_rng_uniform(&rng) - 0.5);
        X[3 * i + 1] = 0.18 * (crom_rng_uniform(&rng) - 0.5);
        X[3 * i + 2] = 0.18 * (crom_rng_uniform(&rng) - 0.5);
    }
    check_map(&free_m, n, X, "eigen skinning map, handle coordinates");
    double *vv = malloc(sizeof(double) * nv);
    crom_mesh_vertex_volumes(m, vv);
    char id0[17];
    memcpy(id0, free_m.model_id, 17);
    CHECK(crom_skin_orthonormalize(&free_m, (size_t)nv, m->X, vv, 1e-6) == 0);
    CHECK(strcmp(id0, free_m.model_id) != 0 && free_m.rank == 3 * free_m.skin_S && free_m.skin_S <= 4 * H);
    check_map(&free_m, n, X, "eigen skinning map, orthonormal coordinates");
    double ge = gram_error(&free_m, m);
    fprintf(stderr, "orthonormal coordinates: %d functions for %d handles, |W^T M W / m - I| <= %.2e\n",
            free_m.skin_S, H, ge);
    CHECK_LT(ge, 1e-9);
    check_tet_blocks(&free_m, m, mat);
    check_rigid(&free_m, m, mat, "eigen skinning, free body");
    check_rigid(&free_m, other, mat, "eigen skinning laid on another mesh");
    free(vv);
    free(X);
    /* a clamped bar: every weight exactly 0 on the clamp, also laid on
     * another mesh (interpolated from the clamped face) */
    unsigned char *fixed = clamp_mask(m);
    rc = crom_dfskin_eigen(m, mat, NULL, fixed, 4, &pin_m, NULL);
    CHECK_MSG(rc == 0, "eigen (clamped): %s", crom_errmsg());
    CHECK(pin_m.skin_constant == 0 && pin_m.rank == 48);
    double wpin = 0, wother = 0, wfar = 0;
    for (int v = 0; v < nv; v++)
        for (int h = 0; h < 4; h++) {
            if (fixed[3 * v])
                wpin = fmax(wpin, fabs(pin_m.skin_w[(size_t)v * 4 + h]));
            else
                wfar = fmax(wfar, fabs(pin_m.skin_w[(size_t)v * 4 + h]));
        }
    double *wo = malloc(sizeof(double) * other->nv * 4);
    CHECK(crom_skin_weights(&pin_m, (size_t)other->nv, other->X, wo, NULL) == 0);
    for (int v = 0; v < other->nv; v++)
        if (other->X[3 * v] < -0.49)
            for (int h = 0; h < 4; h++)
                wother = fmax(wother, fabs(wo[(size_t)v * 4 + h]));
    fprintf(stderr, "eigen weights (clamped): |w| on the clamp %.1e, on another mesh's clamp %.1e, elsewhere up to %.3g\n",
            wpin, wother, wfar);
    CHECK(wpin == 0);
    CHECK_LT(wother, 1e-14);
    CHECK(wfar > 1);
    /* handle counts: none, and more than the free DOFs allow */
    crom_model bad;
    CHECK(crom_dfskin_eigen(m, mat, NULL, fixed, 0, &bad, NULL) == CROM_EUSAGE);
    int nfree = 0;
    for (int v = 0; v < nv; v++)
        nfree += !fixed[3 * v];
    CHECK(crom_dfskin_eigen(m, mat, NULL, fixed, nfree / 4 + 1, &bad, NULL) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "free degrees of freedom") != NULL);
    free(wo);
    free(fixed);
    crom_model_free(&free_m);
    crom_model_free(&pin_m);
}

/* ------------------------------------------------------- trained loss */

typedef struct {
    crom_dfskin_ctx *c;
    float *p;
    int np, B, K;
    const double *q;
    const int *tets;
} loss_case;

static double loss_at(const double *x, void *v)
{
    loss_case *t = v;
    for (int i = 0; i < t->np; i++)
        t->p[i] = (float)x[i];
    crom_dftrain_terms tm;
    if (crom_dfskin_loss(t->c, t->B, t->q, t->K, t->tets, &tm, NULL))
        return NAN;
    return tm.objective;
}

static void gradient_check(const crom_mesh *m, const crom_material *mat, int pinned)
{
    unsigned char *fixed = pinned ? clamp_mask(m) : NULL;
    crom_dfskin_problem P = {m, *mat, fixed, 0, 0, NULL, 0, NULL, NULL};
    crom_dfskin_opts o;
    crom_dfskin_defaults(&o);
    o.handles = 3;
    o.sigma = 0.05;
    o.pin_length = 0.3;     /* a wide mask: many vertices inside it */
    o.ortho_weight = 0.7;
    int Ht = 3 - !pinned, B = 3, r = 12 * 3;
    int ww[] = {3, 10, 10, Ht};
    crom_nn_spec ws;
    CHECK(crom_nn_spec_set(&ws, 4, ww, CROM_NN_ELU) == 0);
    crom_nn_mlp net;
    crom_rng rng;
    crom_rng_seed(&rng, 11);
    CHECK(crom_nn_mlp_init(&net, &ws, NULL, &rng) == 0);
    int K = m->nt / 2 + 3, *tets = malloc(sizeof(int) * K);
    for (int k = 0; k < K; k++)
        tets[k] = (int)crom_rng_below(&rng, (uint64_t)m->nt);
    tets[K - 1] = tets[0]; /* a repeat */
    crom_dfskin_ctx c;
    int rc = crom_dfskin_ctx_init(&c, &P, &o, &net, B, K);
    CHECK_MSG(rc == 0, "ctx: %s", crom_errmsg());
    CHECK(c.constant == !pinned && c.Ht == Ht);
    double q[3 * 36];
    for (int i = 0; i < B * r; i++)
        q[i] = 0.03 * crom_rng_normal(&rng);
    int np = (int)net.nparams;
    float *g = malloc(sizeof(float) * np);
    double *ga = malloc(sizeof(double) * np), *gf = malloc(sizeof(double) * np), *x = malloc(sizeof(double) * np);
    crom_dftrain_terms tm;
    rc = crom_dfskin_loss(&c, B, q, K, tets, &tm, g);
    CHECK_MSG(rc == 0, "loss: %s", crom_errmsg());
    for (int i = 0; i < np; i++) {
        ga[i] = g[i];
        x[i] = net.params[i];
    }
    loss_case lc = {&c, net.params, np, B, K, q, tets};
    check_fd_gradient(loss_at, &lc, x, np, 3e-4, gf);
    for (int i = 0; i < np; i++)
        net.params[i] = (float)x[i];
    double e = check_relerr(ga, gf, np, 1e-12);
    /* the energy term: the mean FEM energy of the drawn tets (each standing
     * for nt/K) at X + W(X) q_b, W from the model the network makes with
     * its weights whitened over the drawn tets: G = Σ m w wᵀ / m over their
     * corners (lumped masses, repeats counted) = L Lᵀ, ŵ = L⁻¹ w */
    crom_model mod;
    CHECK(crom_skin_model_mlp(&mod, &net, 3, c.constant, c.F, c.npins, c.pinX, c.ntri, c.triX, c.pin_length) == 0);
    double *w = malloc(sizeof(double) * m->nv * 3), *mv = calloc(m->nv, sizeof(double)), G[9] = {0}, Em = 0, mt = 0;
    CHECK(crom_skin_weights(&mod, (size_t)m->nv, m->X, w, NULL) == 0);
    crom_fem fem;
    CHECK(crom_fem_init(&fem, m, mat) == 0);
    for (int k = 0; k < K; k++)
        for (int a = 0; a < 4; a++)
            mv[m->tets[4 * tets[k] + a]] += fem.vol[tets[k]] / 4;
    for (int v = 0; v < m->nv; v++) {
        mt += mv[v];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                G[3 * a + b] += mv[v] * w[3 * v + a] * w[3 * v + b];
    }
    double Lc[9] = {0}; /* Cholesky of G / mt, by hand */
    for (int a = 0; a < 3; a++)
        for (int b = 0; b <= a; b++) {
            double v = G[3 * a + b] / mt;
            for (int k = 0; k < b; k++)
                v -= Lc[3 * a + k] * Lc[3 * b + k];
            Lc[3 * a + b] = a == b ? sqrt(v) : v / Lc[3 * b + b];
        }
    for (int v = 0; v < m->nv; v++) { /* forward substitution: ŵ = L⁻¹ w */
        double *wv = w + 3 * v;
        wv[0] /= Lc[0];
        wv[1] = (wv[1] - Lc[3] * wv[0]) / Lc[4];
        wv[2] = (wv[2] - Lc[6] * wv[0] - Lc[7] * wv[1]) / Lc[8];
    }
    double *W = malloc(sizeof(double) * m->nv * 3 * r);
    CHECK(crom_skin_basis(3, c.F, NULL, 0, (size_t)m->nv, m->X, w, W) == 0);
    for (int b = 0; b < B; b++)
        for (int k = 0; k < K; k++) {
            double xe[12];
            for (int a = 0; a < 4; a++) {
                int v = m->tets[4 * tets[k] + a];
                for (int d = 0; d < 3; d++) {
                    double u = 0;
                    for (int j = 0; j < r; j++)
                        u += W[((size_t)v * 3 + d) * r + j] * q[b * r + j];
                    xe[3 * a + d] = m->X[3 * v + d] + u;
                }
            }
            Em += (double)m->nt / K * crom_fem_tet_energy(mat, xe, fem.Dminv + 9 * tets[k], fem.vol[tets[k]]) / B;
        }
    free(mv);
    fprintf(stderr, "skinning loss (%s): objective %.5g (mean energy %.5g J, FEM %.5g J; |G - I|^2 %.4g), gradient "
                    "vs FD %.2e over %d parameters\n", pinned ? "clamped" : "free", tm.objective, tm.energy, Em,
            tm.penalty, e, np);
    CHECK_LT(e, 2e-3);
    CHECK_NEAR(tm.energy, Em, 1e-6 * fabs(Em)); /* the loss runs the network in float, eval in double */
    CHECK(tm.penalty > 0 && tm.energy > 0);
    if (pinned) { /* the mask: zero on the clamp */
        int onpin = 1, inside = 0;
        for (int v = 0; v < m->nv; v++) {
            if (fixed[3 * v])
                onpin &= c.mask[v] == 0;
            inside += c.mask[v] > 0 && c.mask[v] < 1;
        }
        CHECK(onpin && inside > 0);
    }
    CHECK(crom_dfskin_loss(&c, B, q, K + 1, tets, &tm, NULL) == CROM_EUSAGE);
    crom_fem_free(&fem);
    crom_model_free(&mod);
    crom_dfskin_ctx_free(&c);
    crom_nn_mlp_free(&net);
    free(W);
    free(w);
    free(tets);
    free(g);
    free(ga);
    free(gf);
    free(x);
    free(fixed);
}

/* a short training of a free body: the constant handle makes rigid motions
 * exact, whatever the network learned; a clamped one holds its clamp */
static void test_trained(const crom_mesh *m, const crom_mesh *other, const crom_material *mat)
{
    crom_dfskin_problem P = {m, *mat, NULL, 0, 0, NULL, 0, NULL, NULL};
    crom_dfskin_opts o;
    crom_dfskin_defaults(&o);
    o.handles = 4;
    o.steps = 60;
    o.tets = 100;
    crom_model tm;
    crom_dftrain_log log;
    int rc = crom_dfskin_train(&P, &o, &tm, &log);
    CHECK_MSG(rc == 0, "train: %s", crom_errmsg());
    CHECK(tm.skin_constant == 1 && tm.rank == 48 && log.steps == 60);
    double *vv = malloc(sizeof(double) * m->nv);
    crom_mesh_vertex_volumes(m, vv);
    CHECK(crom_skin_orthonormalize(&tm, (size_t)m->nv, m->X, vv, 1e-6) == 0);
    check_rigid(&tm, m, mat, "trained skinning, free body");
    check_rigid(&tm, other, mat, "trained skinning laid on another mesh");
    crom_dftrain_log_free(&log);
    crom_model_free(&tm);
    /* clamped */
    unsigned char *fixed = clamp_mask(m);
    P.fixed = fixed;
    rc = crom_dfskin_train(&P, &o, &tm, &log);
    CHECK_MSG(rc == 0, "train (clamped): %s", crom_errmsg());
    CHECK(tm.skin_constant == 0 && tm.npin_triangles > 0);
    double *wo = malloc(sizeof(double) * other->nv * 4), wmax = 0, wfar = 0;
    CHECK(crom_skin_weights(&tm, (size_t)other->nv, other->X, wo, NULL) == 0);
    for (int v = 0; v < other->nv; v++)
        for (int h = 0; h < 4; h++) {
            if (other->X[3 * v] < -0.49)
                wmax = fmax(wmax, fabs(wo[v * 4 + h]));
            else
                wfar = fmax(wfar, fabs(wo[v * 4 + h]));
        }
    fprintf(stderr, "trained weights (clamped) on another mesh: |w| on its clamp %.1e, elsewhere up to %.3g\n", wmax,
            wfar);
    CHECK_LT(wmax, 1e-14);
    CHECK(wfar > 0.1);
    crom_dftrain_log_free(&log);
    crom_model_free(&tm);
    o.handles = 0;
    CHECK(crom_dfskin_train(&P, &o, &tm, &log) == CROM_EUSAGE);
    P.fixed = NULL;
    o.handles = 1; /* only the constant */
    CHECK(crom_dfskin_train(&P, &o, &tm, &log) == CROM_EUSAGE);
    free(wo);
    free(vv);
    free(fixed);
}

/* ---------------------------------------------------------- clouds */

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    fputs(text, f);
    fclose(f);
}

/* an ASCII STL of the box [x0, x1] x [-0.1, 0.1] x [-0.1, 0.1]; open drops
 * one face */
static void write_box_stl(const char *path, double x0, double x1, int open)
{
    double c[8][3];
    for (int i = 0; i < 8; i++) {
        c[i][0] = i & 1 ? x1 : x0;
        c[i][1] = i & 2 ? 0.1 : -0.1;
        c[i][2] = i & 4 ? 0.1 : -0.1;
    }
    /* outward faces as quads (corner indices, counter-clockwise from outside) */
    static const int q[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    FILE *f = fopen(path, "w");
    fprintf(f, "solid box\n");
    for (int k = 0; k < 6 - open; k++)
        for (int t = 0; t < 2; t++) {
            int a = q[k][0], b = q[k][1 + t], d = q[k][2 + t];
            fprintf(f, " facet normal 0 0 0\n  outer loop\n");
            fprintf(f, "   vertex %g %g %g\n   vertex %g %g %g\n   vertex %g %g %g\n", c[a][0], c[a][1], c[a][2],
                    c[b][0], c[b][1], c[b][2], c[d][0], c[d][1], c[d][2]);
            fprintf(f, "  endloop\n endfacet\n");
        }
    fprintf(f, "endsolid box\n");
    fclose(f);
}

static void test_cloud(void)
{
    char dir[] = "/tmp/crom-skin-XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char stl[256], open_stl[256], xyz[256], bad[256];
    snprintf(stl, sizeof stl, "%s/bar.stl", dir);
    snprintf(open_stl, sizeof open_stl, "%s/open.stl", dir);
    snprintf(xyz, sizeof xyz, "%s/pts.xyz", dir);
    snprintf(bad, sizeof bad, "%s/bad.xyz", dir);
    write_box_stl(stl, -0.5, 0.5, 0);
    write_box_stl(open_stl, -0.5, 0.5, 1);
    crom_cloud c;
    int rc = crom_cloud_from_surface(stl, 2000, 5, &c);
    CHECK_MSG(rc == 0, "surface: %s", crom_errmsg());
    double vs = 0, lo = INFINITY, hi = -INFINITY;
    int out = 0;
    for (int i = 0; i < c.n; i++) {
        vs += c.vol[i];
        lo = fmin(lo, c.X[3 * i]);
        hi = fmax(hi, c.X[3 * i]);
        out += fabs(c.X[3 * i]) > 0.5 || fabs(c.X[3 * i + 1]) > 0.1 || fabs(c.X[3 * i + 2]) > 0.1;
    }
    fprintf(stderr, "sampled box: %d points (asked 2000), volume %.15g (exact 0.04), x in [%.4f, %.4f]\n", c.n, vs, lo,
            hi);
    CHECK_NEAR(vs, 0.04, 1e-15);
    CHECK_NEAR(c.volume, 0.04, 1e-15);
    CHECK(out == 0 && c.n > 1500 && c.n < 3000 && lo < -0.45 && hi > 0.45);
    /* the winding number: inside, outside, near a face */
    double pin[3] = {0.49, 0.09, -0.09}, pout[3] = {0.51, 0, 0}, pfar[3] = {3, 2, 1};
    CHECK(crom_cloud_inside(c.nsv, c.SV, c.nst, c.ST, pin));
    CHECK(!crom_cloud_inside(c.nsv, c.SV, c.nst, c.ST, pout));
    CHECK(!crom_cloud_inside(c.nsv, c.SV, c.nst, c.ST, pfar));
    /* virtual tets: the points' volumes, centred on them */
    crom_mesh vm;
    CHECK(crom_cloud_stencils(&c, 3, &vm) == 0);
    CHECK(vm.nt == c.n && vm.nv == 4 * c.n && crom_mesh_validate(&vm) == 0);
    double vmax = 0, cmax = 0;
    for (int i = 0; i < c.n; i++) {
        const double *x = vm.X + 12 * (size_t)i;
        vmax = fmax(vmax, fabs(crom_mesh_tet_volume(x, x + 3, x + 6, x + 9) - c.vol[i]) / c.vol[i]);
        for (int k = 0; k < 3; k++)
            cmax = fmax(cmax, fabs((x[k] + x[3 + k] + x[6 + k] + x[9 + k]) / 4 - c.X[3 * i + k]));
    }
    CHECK_LT(vmax, 1e-12);
    CHECK_LT(cmax, 1e-15);
    /* pins: the clamped face's two triangles; an interior pin's points */
    const char *p1[] = {"x<-0.49"}, *p2[] = {"sphere:0,0,0,0.05"}, *p3[] = {"clamp"};
    int npin, ntri;
    double *pX, *tX;
    CHECK(crom_cloud_pins(&c, 1, p1, &npin, &pX, &ntri, &tX) == 0);
    CHECK(ntri == 2 && npin == 0);
    free(pX);
    free(tX);
    CHECK(crom_cloud_pins(&c, 1, p2, &npin, &pX, &ntri, &tX) == 0);
    CHECK(ntri == 0 && npin > 0);
    free(pX);
    free(tX);
    CHECK(crom_cloud_pins(&c, 1, p3, &npin, &pX, &ntri, &tX) == CROM_EUSAGE); /* no named regions */
    /* training on it: a clamped body, masked by the face */
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.3, 1000);
    CHECK(crom_cloud_pins(&c, 1, p1, &npin, &pX, &ntri, &tX) == 0);
    crom_dfskin_problem P = {&vm, mat, NULL, 1, npin, pX, ntri, tX, NULL};
    crom_dfskin_opts o;
    crom_dfskin_defaults(&o);
    o.handles = 3;
    o.steps = 20;
    o.tets = 200;
    crom_model tm;
    crom_dftrain_log log;
    rc = crom_dfskin_train(&P, &o, &tm, &log);
    CHECK_MSG(rc == 0, "train on points: %s", crom_errmsg());
    CHECK(tm.skin_constant == 0 && tm.npin_triangles == 2);
    double face[3] = {-0.5, 0.03, -0.07}, w[3];
    CHECK(crom_skin_weights(&tm, 1, face, w, NULL) == 0);
    CHECK_LT(fabs(w[0]) + fabs(w[1]) + fabs(w[2]), 1e-14);
    crom_dftrain_log_free(&log);
    crom_model_free(&tm);
    free(pX);
    free(tX);
    crom_mesh_free(&vm);
    crom_cloud_free(&c);
    /* an open surface */
    CHECK(crom_cloud_from_surface(open_stl, 100, 1, &c) == CROM_EDATA);
    fprintf(stderr, "open surface: %s\n", crom_errmsg());
    /* point clouds: with volumes; without; bad values */
    write_text(xyz, "# x y z volume\n0 0 0 0.001\n0.1, 0, 0, 0.002\n\n0 0.1 0 0.003 # last\n");
    CHECK(crom_cloud_read(xyz, &c) == 0);
    CHECK(c.n == 3 && fabs(c.volume - 0.006) < 1e-15 && c.X[3] == 0.1 && c.vol[2] == 0.003 && c.nst == 0);
    crom_cloud_free(&c);
    write_text(bad, "0 0 0 0.001\n0.1 0 0\n");
    CHECK(crom_cloud_read(bad, &c) == CROM_EDATA);
    CHECK(strstr(crom_errmsg(), ":2: a point without a volume") != NULL);
    write_text(bad, "0 0 0 -1\n");
    CHECK(crom_cloud_read(bad, &c) == CROM_EDATA);
    write_text(bad, "# nothing\n");
    CHECK(crom_cloud_read(bad, &c) == CROM_EDATA);
    remove(stl);
    remove(open_stl);
    remove(xyz);
    remove(bad);
    remove(dir);
}

int main(void)
{
    check_begin("test_skin");
    crom_mesh m, other, tiny;
    make_bar(&m, 0.1);
    make_bar(&other, 0.07);
    make_bar(&tiny, 0.2);
    crom_material mat;
    crom_material_init(&mat, 1e6, 0.3, 1000);
    test_frame(&m);
    gradient_check(&tiny, &mat, 1);
    gradient_check(&tiny, &mat, 0);
    test_eigen(&m, &other, &mat);
    test_trained(&m, &other, &mat);
    test_cloud();
    crom_mesh_free(&m);
    crom_mesh_free(&other);
    crom_mesh_free(&tiny);
    return check_done();
}
