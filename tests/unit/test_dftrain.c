/* test_dftrain.c — lib/datafree/dftrain and dfloss: the training loop the
 * data-free trainers share and the pieces of their losses.
 *
 *  - the loop: Adam (one and two parameter blocks) and L-BFGS minimize a
 *    quadratic Σ (θ_i − t_i)² from θ = 0 (to 1e-4 and 1e-5 of the target);
 *    the record keeps the per-block means of the terms the loss returned
 *    (blocks of ceil(steps / 100) steps), the progress ends at step `steps`
 *    and fraction 1, a non-finite loss stops the run with CROM_EDATA
 *    "training diverged at step k" and frees the record, and a time budget
 *    stops a long run early;
 *  - the draw: box-uniform samples within ±scale_k, tangent samples
 *    exactly ε e_(k mod r), every tet in order when K = nt (else tets in range), and ρ =
 *    min(1, frac / ramp) at fraction frac = k / steps, to the last bit;
 *  - the cubature: every tet drawn once gives the mesh's lumped masses and
 *    its mass; repeats weigh nt/K each; a tet out of range or more vertices
 *    than rows is refused and leaves nothing drawn;
 *  - the drawn tets' energy and gradient equal crom_fem_assemble's over
 *    every tet (by vertex at given positions, and by row at X + u), and a
 *    tet whose energy is not finite is reported;
 *  - the anchor's gradient: out_b = d_b (0 where masked), the anchor's row
 *    −Σ_b out_b;
 *  - the pinned part of a box clamped at x = 0: its 9 vertices there and
 *    the 8 boundary triangles of that face.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "base/clock.h"
#include "base/err.h"
#include "datafree/dfloss.h"
#include "datafree/dftrain.h"
#include "phys/fem.h"
#include "phys/material.h"

/* ------------------------------------------------------------ the loop */

#define NP 5
#define MAXSTEPS 4000

typedef struct {
    float *theta[2];          /* the blocks' parameters (theirs: the loop's params) */
    float *grad[2];
    int nblocks;
    double target[NP];
    long calls, fail_at;      /* fail_at: the call that returns CROM_EDATA (0: none) */
    double obj[MAXSTEPS];     /* what each call returned */
    double rho[MAXSTEPS];
    int batch, tangent, r, K, nt, uniform;
    const double *scale;
    double eps;
    int draws_ok;             /* every draw was as asked */
    double busy;              /* seconds each call waits */
    long last_step;
    double last_frac;
} quad;

static int quad_loss(void *ctx, const double *z, double rho, int K, const int *tets, crom_dftrain_terms *t)
{
    quad *Q = ctx;
    long c = Q->calls++;
    if (Q->fail_at && c + 1 == Q->fail_at)
        return crom_err(CROM_EDATA, "not finite");
    if (Q->busy > 0) {
        double t0 = crom_clock_now();
        while (crom_clock_now() - t0 < Q->busy)
            ;
    }
    for (int i = 0; i < Q->batch * Q->r; i++) {
        double s = Q->scale ? Q->scale[i % Q->r] : 1;
        if (Q->uniform && !(fabs(z[i]) <= s))
            Q->draws_ok = 0;
    }
    for (int k = 0; k < Q->tangent; k++) /* exactly ε e_(k mod r) */
        for (int j = 0; j < Q->r; j++)
            if (z[(Q->batch + k) * Q->r + j] != (j == k % Q->r ? Q->eps : 0))
                Q->draws_ok = 0;
    if ((K > 0) != (tets != NULL) || K != Q->K)
        Q->draws_ok = 0;
    for (int i = 0; tets && i < K; i++)
        if (Q->K == Q->nt ? tets[i] != i : tets[i] < 0 || tets[i] >= Q->nt)
            Q->draws_ok = 0;
    double f = 0;
    for (int b = 0; b < Q->nblocks; b++)
        for (int i = 0; i < NP; i++) {
            double d = Q->theta[b][i] - Q->target[i];
            f += d * d;
            Q->grad[b][i] = (float)(2 * d);
        }
    if (c < MAXSTEPS) {
        Q->obj[c] = f;
        Q->rho[c] = rho;
    }
    t->objective = f;
    t->energy = 0.5 * f;
    t->penalty = 0.25 * f;
    t->tangent = 0;
    return 0;
}

static void on_progress(void *ctx, long step, double frac, double objective)
{
    quad *Q = ctx;
    Q->last_step = step;
    Q->last_frac = frac;
}

static void quad_setup(quad *Q, crom_dftrain_loop *L, float (*params)[NP], float (*grad)[NP], crom_rng *rng,
                       int nblocks)
{
    memset(Q, 0, sizeof *Q);
    memset(params, 0, sizeof(float) * 2 * NP);
    Q->nblocks = nblocks;
    Q->draws_ok = 1;
    for (int i = 0; i < NP; i++)
        Q->target[i] = 0.9 * sin(1.7 * i + 0.3);
    Q->batch = 4;
    Q->r = 3;
    memset(L, 0, sizeof *L);
    L->loss = quad_loss;
    L->ctx = Q;
    L->nblocks = nblocks;
    for (int b = 0; b < nblocks; b++) {
        Q->theta[b] = L->params[b] = params[b];
        Q->grad[b] = L->grad[b] = grad[b];
        L->nparams[b] = NP;
    }
    L->rng = rng;
    L->batch = Q->batch;
    L->r = Q->r;
    L->progress = on_progress;
    L->progress_ctx = Q;
}

static double quad_error(const quad *Q)
{
    double e = 0;
    for (int b = 0; b < Q->nblocks; b++)
        for (int i = 0; i < NP; i++)
            e = fmax(e, fabs(Q->theta[b][i] - Q->target[i]));
    return e;
}

static void test_adam(int nblocks)
{
    quad Q;
    crom_dftrain_loop L;
    float params[2][NP], grad[2][NP];
    crom_rng rng;
    crom_rng_seed(&rng, 7);
    quad_setup(&Q, &L, params, grad, &rng, nblocks);
    static const double scale[3] = {0.5, 1, 2};
    Q.uniform = L.uniform = 1;
    Q.scale = L.scale = scale;
    Q.tangent = L.tangent = 2;
    Q.eps = L.tangent_radius = 0.01;
    Q.K = L.K = Q.nt = L.nt = 6; /* every tet, in order */
    L.ramp = 0.3;
    L.steps = 2500;
    L.lr = 0.05;
    L.hint = " (try a smaller --lr)";
    crom_dftrain_log log;
    memset(&log, 0, sizeof log);
    int rc = crom_dftrain_run(&L, &log);
    CHECK(rc == 0);
    printf("Adam, %d block(s): max |theta - t| %.2e after %ld steps, %d blocks, last objective %.3g\n", nblocks,
           quad_error(&Q), log.steps, log.nblocks, log.objective[log.nblocks - 1]);
    CHECK_LT(quad_error(&Q), 1e-4);
    CHECK(log.steps == 2500 && Q.calls == 2500);
    CHECK(log.nblocks == 100); /* blocks of 25 */
    double m0 = 0, m99 = 0;
    for (int k = 0; k < 25; k++) {
        m0 += Q.obj[k];
        m99 += Q.obj[2475 + k];
    }
    CHECK_REL(log.objective[0], m0 / 25, 1e-12);
    CHECK_REL(log.energy[0], 0.5 * m0 / 25, 1e-12);
    CHECK_REL(log.penalty[99], 0.25 * m99 / 25, 1e-12);
    CHECK(Q.last_step == 2500 && Q.last_frac == 1);
    CHECK(Q.draws_ok);
    int rho_ok = 1;
    for (int k = 0; k < 2500; k++)
        rho_ok &= Q.rho[k] == fmin(1.0, ((double)k / 2500) / 0.3);
    CHECK(rho_ok);
    crom_dftrain_log_free(&log);
}

static void test_lbfgs(void)
{
    quad Q;
    crom_dftrain_loop L;
    float params[2][NP], grad[2][NP];
    crom_rng rng;
    crom_rng_seed(&rng, 8);
    quad_setup(&Q, &L, params, grad, &rng, 1);
    Q.K = L.K = 3; /* a random cubature of 3 of 40 tets */
    Q.nt = L.nt = 40;
    L.steps = 4;
    L.minutes = 0.1; /* a guard: L-BFGS draws batches until it takes a step */
    L.lr = 0.5;
    L.lbfgs = 1;
    L.resample = 10;
    crom_dftrain_log log;
    memset(&log, 0, sizeof log);
    int rc = crom_dftrain_run(&L, &log);
    CHECK(rc == 0);
    printf("L-BFGS: max |theta - t| %.2e after %ld steps (%ld evaluations)\n", quad_error(&Q), log.steps, Q.calls);
    CHECK_LT(quad_error(&Q), 1e-5);
    CHECK(log.steps == 4 && log.nblocks == 4);
    CHECK(Q.draws_ok);
    crom_dftrain_log_free(&log);

    /* at the minimum itself (zero gradient) no step is ever accepted: the
     * loop ends after its idle batches, with no clock to stop it */
    quad_setup(&Q, &L, params, grad, &rng, 1);
    for (int i = 0; i < NP; i++)
        params[0][i] = (float)Q.target[i];
    for (int i = 0; i < NP; i++)
        Q.target[i] = params[0][i];
    L.steps = 10;
    L.lr = 0.5;
    L.lbfgs = 1;
    L.resample = 10;
    memset(&log, 0, sizeof log);
    rc = crom_dftrain_run(&L, &log);
    printf("L-BFGS at the minimum: rc %d, %ld steps, %ld evaluations\n", rc, log.steps, Q.calls);
    CHECK(rc == CROM_EDATA && strstr(crom_errmsg(), "no step on 100 batches"));
    CHECK(Q.calls == 100);
    crom_dftrain_log_free(&log);
}

static void test_stops(void)
{
    quad Q;
    crom_dftrain_loop L;
    float params[2][NP], grad[2][NP];
    crom_rng rng;
    crom_rng_seed(&rng, 9);
    crom_dftrain_log log;
    /* a loss that is not finite at the 7th step */
    quad_setup(&Q, &L, params, grad, &rng, 1);
    Q.fail_at = 7;
    L.steps = 100;
    L.lr = 0.01;
    L.hint = " (try this)";
    int rc = crom_dftrain_run(&L, &log);
    CHECK(rc == CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), "training diverged at step 7 (try this)") != NULL, "message: %s",
              crom_errmsg());
    CHECK(log.nblocks == 0 && log.objective == NULL);
    crom_err_clear();
    /* a time budget of 30 ms, 2 ms a step */
    quad_setup(&Q, &L, params, grad, &rng, 1);
    Q.busy = 0.002;
    L.steps = 1000000;
    L.minutes = 0.0005;
    L.lr = 0.01;
    memset(&log, 0, sizeof log);
    rc = crom_dftrain_run(&L, &log);
    printf("a 30 ms budget at 2 ms a step: %ld steps, %d blocks\n", log.steps, log.nblocks);
    CHECK(rc == 0);
    CHECK(log.steps >= 1 && log.steps < 1000 && log.nblocks == 1);
    CHECK(log.objective[0] <= Q.obj[0]); /* the mean of a decreasing objective */
    crom_dftrain_log_free(&log);
}

/* ------------------------------------------------------------ the losses' pieces */

static void test_cubature(void)
{
    crom_mesh m;
    fx_box_mesh(&m, 2, 2, 1, NULL, 0.5, 0, NULL, NULL); /* 24 tets, 18 vertices */
    crom_material mat;
    CHECK(crom_material_init(&mat, 1e6, 0.3, 1000) == 0);
    crom_fem fem;
    CHECK(crom_fem_init(&fem, &m, &mat) == 0);
    int nt = fem.nt, nv = fem.nv, *all = malloc(sizeof(int) * (size_t)nt);
    for (int k = 0; k < nt; k++)
        all[k] = k;
    crom_dfloss_cub c;
    CHECK(crom_dfloss_cub_init(&c, nv, nv) == 0);
    /* every tet once: the lumped masses */
    CHECK(crom_dfloss_cub_draw(&c, &fem, mat.rho, nt, all) == 0);
    CHECK(c.ns == nv && c.wK == 1);
    double merr = 0;
    for (int i = 0; i < c.ns; i++)
        merr = fmax(merr, fabs(c.mloc[i] - fem.mass[c.vs[i]]) / fem.mass[c.vs[i]]);
    CHECK_LT(merr, 1e-14);
    CHECK_REL(c.mhat, fem.total_mass, 1e-12);
    CHECK_REL(c.mhat, 1000 * 0.5, 1e-12); /* 1 x 1 x 0.5 m of 1000 kg/m^3 */
    /* repeats: each of K drawn tets stands for nt/K */
    int rep[3] = {5, 5, 11};
    CHECK(crom_dfloss_cub_draw(&c, &fem, mat.rho, 3, rep) == 0);
    CHECK_REL(c.mhat, nt / 3.0 * mat.rho * (2 * fem.vol[5] + fem.vol[11]), 1e-12);
    CHECK(c.ns <= 8);
    /* refused draws leave nothing drawn */
    int bad[2] = {0, nt};
    CHECK(crom_dfloss_cub_draw(&c, &fem, mat.rho, 2, bad) == CROM_EUSAGE);
    int clean = c.ns == 0;
    for (int v = 0; v < nv; v++)
        clean &= c.loc[v] == -1;
    CHECK(clean);
    crom_dfloss_cub small;
    CHECK(crom_dfloss_cub_init(&small, nv, 5) == 0);
    int two[2] = {0, 23};
    CHECK(crom_dfloss_cub_draw(&small, &fem, mat.rho, 2, two) == CROM_EUSAGE);
    CHECK_MSG(strstr(crom_errmsg(), "more than 5 vertices") != NULL, "message: %s", crom_errmsg());
    clean = small.ns == 0;
    for (int v = 0; v < nv; v++)
        clean &= small.loc[v] == -1;
    CHECK(clean);
    crom_err_clear();
    crom_dfloss_cub_free(&small);

    /* the drawn tets' energy against the assembled one */
    double *x = malloc(sizeof(double) * 3 * (size_t)nv), *u = malloc(sizeof(double) * 3 * (size_t)nv);
    double *g = calloc(3 * (size_t)nv, sizeof(double)), *g1 = calloc(3 * (size_t)nv, sizeof(double));
    double *ur = malloc(sizeof(double) * 3 * (size_t)nv), *gr = calloc(3 * (size_t)nv, sizeof(double));
    for (int v = 0; v < nv; v++)
        for (int d = 0; d < 3; d++) {
            const double *X = m.X + 3 * (size_t)v;
            u[3 * v + d] = 0.02 * sin(3 * X[0] + d) * (X[1] + 0.3 * X[2]);
            x[3 * v + d] = X[d] + u[3 * v + d];
        }
    double E = 0, E1, E2;
    crom_fem_opts fo = {0, 0, NULL, 1};
    CHECK(crom_fem_assemble(&fem, x, &fo, &E, g, NULL) == 0);
    CHECK(crom_dfloss_tets(&fem, nt, all, 1.0, NULL, x, NULL, &E1, g1) == 0);
    CHECK(crom_dfloss_cub_draw(&c, &fem, mat.rho, nt, all) == 0);
    for (int i = 0; i < c.ns; i++)
        memcpy(ur + 3 * i, u + 3 * (size_t)c.vs[i], sizeof(double) * 3);
    CHECK(crom_dfloss_tets(&fem, nt, all, 1.0, m.X, ur, c.loc, &E2, gr) == 0);
    double gerr = 0, gerr2 = 0, gmax = 0;
    for (int i = 0; i < 3 * nv; i++) {
        gmax = fmax(gmax, fabs(g[i]));
        gerr = fmax(gerr, fabs(g1[i] - g[i]));
    }
    for (int i = 0; i < c.ns; i++)
        for (int d = 0; d < 3; d++)
            gerr2 = fmax(gerr2, fabs(gr[3 * i + d] - g[3 * (size_t)c.vs[i] + d]));
    printf("drawn tets against assembly: E %.6g J (by vertex %.2e, by row %.2e relative), gradient %.2e, %.2e of "
           "%.3g\n", E, fabs(E1 - E) / E, fabs(E2 - E) / E, gerr, gerr2, gmax);
    CHECK(E > 0);
    CHECK_REL(E1, E, 1e-12);
    CHECK_REL(E2, E, 1e-12);
    CHECK_LT(gerr, 1e-10 * gmax);
    CHECK_LT(gerr2, 1e-10 * gmax);
    /* a tet with a position that is not finite: reported, the sum stops there */
    x[3 * (size_t)fem.tets[4 * 1]] = NAN;
    CHECK(crom_dfloss_tets(&fem, nt, all, 1.0, NULL, x, NULL, &E1, g1) == 1);
    CHECK(isfinite(E1));
    crom_dfloss_cub_clear(&c);
    crom_dfloss_cub_free(&c);
    free(x);
    free(u);
    free(g);
    free(g1);
    free(ur);
    free(gr);
    free(all);
    crom_fem_free(&fem);
    crom_mesh_free(&m);
}

static void test_anchor(void)
{
    /* 3 samples and the anchor, 4 outputs each; output 1 masked */
    double d[12];
    for (int i = 0; i < 12; i++)
        d[i] = 0.25 * i - 1;
    unsigned char mask[4] = {0, 1, 0, 0};
    float out[16];
    crom_dfloss_anchor_grad(4, 4, d, mask, out);
    int ok = 1;
    for (int b = 0; b < 3; b++)
        for (int i = 0; i < 4; i++)
            ok &= out[4 * b + i] == (i == 1 ? 0.0f : (float)d[4 * b + i]);
    CHECK(ok);
    for (int i = 0; i < 4; i++)
        CHECK_NEAR(out[12 + i], -(out[i] + out[4 + i] + out[8 + i]), 1e-6);
    CHECK(out[13] == 0);
    crom_dfloss_anchor_grad(4, 4, d, NULL, out);
    CHECK(out[5] == (float)d[5]);
}

static void test_pinned_part(void)
{
    crom_mesh m;
    fx_box_mesh(&m, 2, 2, 2, NULL, 0.5, 0, NULL, NULL); /* [0, 1]^3, 27 vertices */
    unsigned char *fixed = calloc(3 * (size_t)m.nv, 1);
    for (int v = 0; v < m.nv; v++)
        if (m.X[3 * v] < 1e-9)
            memset(fixed + 3 * v, 1, 3);
    int npins, ntri;
    double *pinX, *triX;
    CHECK(crom_dfloss_pinned_part(&m, fixed, 2, 1, &npins, &pinX, &ntri, &triX) == 0);
    int on_face = 1;
    for (int i = 0; i < npins; i++)
        on_face &= pinX[3 * i] == 0;
    for (int i = 0; i < 3 * ntri; i++)
        on_face &= triX[3 * i] == 0;
    printf("pinned part of a box clamped at x = 0: %d vertices, %d triangles\n", npins, ntri);
    CHECK(npins == 9 && ntri == 8 && on_face);
    free(pinX);
    free(triX);
    CHECK(crom_dfloss_pinned_part(&m, NULL, 0, 0, &npins, &pinX, &ntri, &triX) == 0);
    CHECK(npins == 0 && ntri == 0);
    CHECK(crom_dfloss_pinned(fixed, 0) == 1 && crom_dfloss_pinned(NULL, 0) == 0);
    free(pinX);
    free(triX);
    free(fixed);
    crom_mesh_free(&m);
}

/* The collapse floor: Σ_k log²(μ_k / τ) over the normalized eigenvalues
 * μ_k of r G / tr G below τ. G = Y Yᵀ of r secants Y [r][n]; the gradient
 * 2 A Y (A = w dh/dG) against central differences in Y, with one row
 * nearly a combination of the others (a collapsed direction) and without;
 * zero for an isotropic G and for a G whose eigenvalues are all above τ; an
 * exact value for a diagonal G. */
typedef struct {
    int r, n;
    double tau, w;
} floor_case;

static void gram_of(const floor_case *f, const double *Y, double *G)
{
    for (int k = 0; k < f->r; k++)
        for (int l = 0; l < f->r; l++) {
            double s = 0;
            for (int i = 0; i < f->n; i++)
                s += Y[k * f->n + i] * Y[l * f->n + i];
            G[k * f->r + l] = s;
        }
}

static double floor_at(const double *Y, void *v)
{
    floor_case *f = v;
    double G[16], A[16], work[20];
    gram_of(f, Y, G);
    return f->w * crom_dfloss_rest_floor(f->r, G, f->tau, f->w, A, work);
}

static void test_rest_floor(void)
{
    floor_case f = {4, 6, 0.3, 0.7};
    crom_rng rng;
    crom_rng_seed(&rng, 23);
    double Y[24], G[16], A[16], work[20], ga[24], gf[24];
    for (int pass = 0; pass < 2; pass++) {
        for (int i = 0; i < 24; i++)
            Y[i] = crom_rng_normal(&rng);
        if (pass == 1) /* row 3 nearly row 0 + row 1: a collapsed direction */
            for (int i = 0; i < 6; i++)
                Y[18 + i] = Y[i] + Y[6 + i] + 0.01 * crom_rng_normal(&rng);
        gram_of(&f, Y, G);
        double h = crom_dfloss_rest_floor(f.r, G, f.tau, f.w, A, work);
        for (int k = 0; k < f.r; k++)
            for (int i = 0; i < f.n; i++) {
                double s = 0;
                for (int l = 0; l < f.r; l++)
                    s += 2 * A[k * f.r + l] * Y[l * f.n + i];
                ga[k * f.n + i] = s;
            }
        check_fd_gradient(floor_at, &f, Y, 24, 1e-6, gf);
        double e = check_relerr(ga, gf, 24, 1e-12);
        printf("collapse floor (%s): %.4g, gradient vs FD %.2e\n", pass ? "near-collapsed" : "random", h, e);
        CHECK(h > 0 && isfinite(h));
        CHECK_LT(e, 1e-5);
    }
    /* isotropic: 0; diagonal (1, 1, 1, 0.01): μ = 4 · 0.01 / 3.01 below τ = 0.3 */
    double D[16] = {0};
    for (int k = 0; k < 4; k++)
        D[k * 5] = 1;
    CHECK(crom_dfloss_rest_floor(4, D, 0.3, 1, A, work) == 0);
    D[15] = 0.01;
    double mu = 4 * 0.01 / 3.01, want = log(mu / 0.3) * log(mu / 0.3);
    CHECK_REL(crom_dfloss_rest_floor(4, D, 0.3, 1, A, work), want, 1e-12);
    D[15] = 0.5; /* μ = 2 / 3.5 = 0.57 > 0.3: nothing */
    CHECK(crom_dfloss_rest_floor(4, D, 0.3, 1, A, work) == 0);
    double Z[16] = {0};
    CHECK(isnan(crom_dfloss_rest_floor(4, Z, 0.3, 1, A, work)));
}

int main(void)
{
    check_begin("test_dftrain");
    test_adam(1);
    test_adam(2);
    test_lbfgs();
    test_stops();
    test_cubature();
    test_anchor();
    test_pinned_part();
    test_rest_floor();
    return check_done();
}
