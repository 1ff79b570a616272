/* test_elastic.c — the elastic energy of a linear subspace over a cubature in
 * the space of deformation gradients (lib/rom/elastic.c): energy, gradient
 * and Hessian against the per-tet corner formulation W_eᵀ H_e W_e
 * (crom_cubature_tet, an independent path through fem.c's 12 x 12 element
 * kernel), and against finite differences, for a general basis and for a
 * component-block basis W_v = I₃ ⊗ ψ_vᵀ (the skinning subspace's form). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "base/err.h"
#include "phys/fem.h"
#include "rom/cubature.h"
#include "rom/elastic.h"

#define S 6          /* functions per component */
#define RB (3 * S)   /* block basis rank */
#define RD 11        /* general basis rank */

/* ψ_s(X): 1, X, Y, Z, X², XY (scaled to the bar) */
static void psi(const double *X, double f[S])
{
    double x = X[0], y = X[1] / 0.3, z = X[2] / 0.3;
    f[0] = 1;
    f[1] = x;
    f[2] = y;
    f[3] = z;
    f[4] = x * x;
    f[5] = x * y;
}

static void block_basis(const crom_mesh *m, double *W)
{
    memset(W, 0, sizeof(double) * (size_t)m->nv * 3 * RB);
    for (int v = 0; v < m->nv; v++) {
        double f[S];
        psi(m->X + 3 * v, f);
        for (int c = 0; c < 3; c++)
            for (int s = 0; s < S; s++)
                W[((size_t)v * 3 + c) * RB + c * S + s] = f[s];
    }
}

/* a general basis: every column mixes components and functions */
static void general_basis(const crom_mesh *m, double *W, crom_rng *rng)
{
    double mix[3][RD][S];
    for (int c = 0; c < 3; c++)
        for (int j = 0; j < RD; j++)
            for (int s = 0; s < S; s++)
                mix[c][j][s] = crom_rng_normal(rng);
    for (int v = 0; v < m->nv; v++) {
        double f[S];
        psi(m->X + 3 * v, f);
        for (int c = 0; c < 3; c++)
            for (int j = 0; j < RD; j++) {
                double w = 0;
                for (int s = 0; s < S; s++)
                    w += mix[c][j][s] * f[s];
                W[((size_t)v * 3 + c) * RD + j] = w;
            }
    }
}

/* the reference: Σ_k w_k crom_cubature_tet over the cubature */
static double reference(const crom_cubature *c, const crom_material *mat, const double *q, int project, double *g,
                        double *H)
{
    int r = c->r;
    double *W4 = malloc(sizeof(double) * 12 * r), *kw = malloc(sizeof(double) * (168 + 12 * (size_t)r));
    if (g)
        memset(g, 0, sizeof(double) * r);
    if (H)
        memset(H, 0, sizeof(double) * r * r);
    double E = 0;
    for (int k = 0; k < c->k; k++) {
        double Xe[12], Dk[9];
        crom_cubature_gather(c, k, Xe, W4, Dk);
        E += c->weight[k] * crom_cubature_tet(mat, Xe, W4, r, Dk, c->vol[k], c->weight[k], q, project, g, H, kw);
    }
    free(W4);
    free(kw);
    return E;
}

typedef struct {
    crom_elastic *e;
    const crom_material *mat;
    int r;
} fd_ctx;

static double fd_energy(const double *q, void *p)
{
    fd_ctx *c = p;
    double E;
    return crom_elastic_eval(c->e, c->mat, q, 0, &E, NULL, NULL) ? NAN : E;
}

static void fd_gradient(const double *q, void *p, double *g)
{
    fd_ctx *c = p;
    double E;
    memset(g, 0, sizeof(double) * c->r);
    crom_elastic_eval(c->e, c->mat, q, 0, &E, g, NULL);
}

static void check_basis(const crom_mesh *m, const double *W, int r, int want_block, crom_rng *rng)
{
    crom_cubature cub;
    crom_cubature_opts o = {CROM_CUBATURE_RANDOM, 25, 0, 0, NULL, 0, 1e6, 0.3, NULL, 0};
    CHECK(crom_cubature_build(&cub, m, W, r, "test", &o, rng) == 0);
    crom_elastic e;
    CHECK(crom_elastic_init(&e, &cub) == 0);
    CHECK_MSG(e.block == want_block, "block structure detected %d, expected %d", e.block, want_block);
    crom_material mat;
    CHECK(crom_material_init(&mat, 1e6, 0.3, 1000) == 0);
    double *q = malloc(sizeof(double) * r), *g = malloc(sizeof(double) * r), *gr = malloc(sizeof(double) * r);
    double *H = malloc(sizeof(double) * r * r), *Hr = malloc(sizeof(double) * r * r);
    double *gfd = malloc(sizeof(double) * r), *Hfd = malloc(sizeof(double) * r * r);
    for (int trial = 0; trial < 3; trial++) {
        for (int i = 0; i < r; i++) /* strains of about 5-20 %, some tets compressed hard */
            q[i] = (0.03 + 0.04 * trial) * crom_rng_normal(rng);
        for (int project = 0; project <= 1; project++) {
            double E, Er;
            memset(g, 0, sizeof(double) * r);
            memset(H, 0, sizeof(double) * r * r);
            CHECK(crom_elastic_eval(&e, &mat, q, project, &E, g, H) == 0);
            Er = reference(&cub, &mat, q, project, gr, Hr);
            CHECK_REL(E, Er, 1e-11);
            double eg = check_relerr(g, gr, r, 1e-300), eH = check_relerr(H, Hr, r * r, 1e-300);
            CHECK_MSG(eg < 1e-11, "gradient vs corner formulation: %.3g", eg);
            CHECK_MSG(eH < 1e-11, "Hessian vs corner formulation: %.3g", eH);
            double asym = 0, hmax = 0; /* the Hessian is symmetric (to round-off) */
            for (int i = 0; i < r; i++)
                for (int j = 0; j < r; j++) {
                    asym = fmax(asym, fabs(H[i * r + j] - H[j * r + i]));
                    hmax = fmax(hmax, fabs(H[i * r + j]));
                }
            CHECK_MSG(asym <= 1e-13 * hmax, "Hessian asymmetry %.3g of %.3g", asym, hmax);
            if (project) { /* projected: positive semi-definite (a Cholesky of H + tiny I succeeds) */
                double dmax = 0;
                for (int i = 0; i < r; i++)
                    dmax = fmax(dmax, H[i * r + i]);
                for (int i = 0; i < r; i++)
                    H[i * r + i] += 1e-10 * dmax;
                int ok = 1;
                for (int j = 0; j < r && ok; j++) { /* in-place Cholesky */
                    double d = H[j * r + j];
                    for (int k = 0; k < j; k++)
                        d -= H[j * r + k] * H[j * r + k];
                    if (!(d > 0)) {
                        ok = 0;
                        break;
                    }
                    H[j * r + j] = sqrt(d);
                    for (int i = j + 1; i < r; i++) {
                        double s = H[i * r + j];
                        for (int k = 0; k < j; k++)
                            s -= H[i * r + k] * H[j * r + k];
                        H[i * r + j] = s / H[j * r + j];
                    }
                }
                CHECK_MSG(ok, "projected reduced Hessian is not positive semi-definite");
            }
        }
        /* finite differences of the unprojected derivatives */
        fd_ctx c = {&e, &mat, r};
        double E;
        memset(g, 0, sizeof(double) * r);
        memset(H, 0, sizeof(double) * r * r);
        crom_elastic_eval(&e, &mat, q, 0, &E, g, H);
        check_fd_gradient(fd_energy, &c, q, r, 1e-6, gfd);
        check_fd_jacobian(fd_gradient, &c, q, r, r, 1e-6, Hfd);
        double eg = check_relerr(g, gfd, r, 1e-300), eH = check_relerr(H, Hfd, r * r, 1e-300);
        CHECK_MSG(eg < 1e-6, "gradient vs finite differences: %.3g", eg);
        CHECK_MSG(eH < 1e-6, "Hessian vs finite differences: %.3g", eH);
        printf("r = %d (%s), |q| ~ %.2f: corner formulation vs F space: E %.1e, FD gradient %.2e, FD Hessian %.2e\n",
               r, e.block ? "block" : "general", 0.03 + 0.04 * trial, fabs(E / reference(&cub, &mat, q, 0, NULL, NULL) - 1),
               eg, eH);
    }
    /* at rest: zero energy and force */
    memset(q, 0, sizeof(double) * r);
    memset(g, 0, sizeof(double) * r);
    double E0;
    CHECK(crom_elastic_eval(&e, &mat, q, 0, &E0, g, NULL) == 0);
    double gmax = 0;
    for (int i = 0; i < r; i++)
        gmax = fmax(gmax, fabs(g[i]));
    CHECK_MSG(fabs(E0) < 1e-9 && gmax < 1e-6, "rest: E %.3g, |g| %.3g", E0, gmax);
    free(q);
    free(g);
    free(gr);
    free(H);
    free(Hr);
    free(gfd);
    free(Hfd);
    crom_elastic_free(&e);
    crom_cubature_free(&cub);
}

int main(void)
{
    check_begin("test_elastic");
    crom_mesh m;
    const double dims[3] = {1, 0.3, 0.3};
    if (fx_gen(CROM_MESHGEN_BOX, dims, 0.15, &m))
        return check_done();
    crom_rng rng;
    crom_rng_seed(&rng, 11);
    double *W = malloc(sizeof(double) * (size_t)m.nv * 3 * RB);
    block_basis(&m, W);
    check_basis(&m, W, RB, 1, &rng);
    free(W);
    W = malloc(sizeof(double) * (size_t)m.nv * 3 * RD);
    general_basis(&m, W, &rng);
    check_basis(&m, W, RD, 0, &rng);
    free(W);
    crom_mesh_free(&m);
    return check_done();
}
