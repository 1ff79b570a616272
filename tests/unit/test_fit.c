/* test_fit.c — lib/fit: finite-difference checks of the composed training
 * losses (variable projection with Tikhonov term, joint PointNet loss) on
 * batches with dense and masked groups; fitting known analytic fields (lsq
 * neural field, POD); the canonical basis; determinism; data checks; the
 * data-parallel hook (shards, two processes emulated by two threads: the
 * only run of the sharded steps under the sanitizers, which build
 * crom-fitfield without MPI).
 *
 * Gradient checks follow test_nn.c: float networks, loss accumulated in
 * double, central differences with step 1e-3 on the float parameters, and the
 * relative error of the whole gradient vector below 2e-3 (rounding gives
 * ~1e-4; a missing or wrong term gives O(1)).
 */
#include <cblas.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "base/err.h"
#include "rom/fit.h"
#include "fixtures.h"
#include "rom/model.h"
#include "nn/nn.h"

#define FD_H 1e-3
#define FD_TOL 2e-3

typedef struct {
    crom_fit_ctx *ctx;
    crom_fit_batch *b;
    float *p;
    int n;
} fd_case;

static double loss_at(const double *x, void *v)
{
    fd_case *t = v;
    for (int i = 0; i < t->n; i++)
        t->p[i] = (float)x[i];
    double obj;
    if (crom_fit_loss(t->ctx, t->b, &obj, NULL, NULL, NULL))
        return NAN;
    return obj;
}

/* A batch with a dense group (6 points x 3 frames) and a masked one (8
 * points x 4 frames, about a third of the samples missing). */
static void make_batch(crom_fit_batch *b, crom_rng *rng, int pointnet)
{
    static int rows[2] = {6, 8}, frames[2] = {3, 4}, dense[2] = {1, 0};
    memset(b, 0, sizeof *b);
    b->ngroups = 2;
    b->rows = rows;
    b->frames = frames;
    b->dense = dense;
    b->nrows = 14;
    b->nframes = 7;
    int cells = 6 * 3 + 8 * 4;
    b->X = malloc(sizeof(float) * 3 * 14);
    b->U = malloc(sizeof(double) * 3 * cells);
    b->M = malloc(sizeof(double) * cells);
    for (int i = 0; i < 3 * 14; i++)
        b->X[i] = (float)(2.0 + i % 3 + 0.6 * (2 * crom_rng_uniform(rng) - 1));
    for (int i = 0; i < 3 * cells; i++)
        b->U[i] = 2 * crom_rng_uniform(rng) - 1;
    for (int i = 0; i < cells; i++)
        b->M[i] = 1;
    /* masked group: cells 18.. as [8][4]; keep every frame with >= 3 points */
    for (int i = 0; i < 8; i++)
        for (int j = 0; j < 4; j++)
            if (i >= 3 && crom_rng_uniform(rng) < 0.35) {
                b->M[18 + i * 4 + j] = 0;
                for (int c = 0; c < 3; c++)
                    b->U[3 * 18 + (3 * i + c) * 4 + j] = 0;
            }
    if (pointnet) {
        b->enc_points = 5;
        b->enc = malloc(sizeof(float) * 7 * 5 * 6);
        for (int i = 0; i < 7 * 5 * 6; i++)
            b->enc[i] = (float)(2 * crom_rng_uniform(rng) - 1);
    }
}

static void free_batch(crom_fit_batch *b)
{
    free(b->X);
    free(b->U);
    free(b->M);
    free(b->enc);
}

static void check_gradient(const char *label, int pointnet, double tik, int withcut, uint64_t seed)
{
    crom_rng rng;
    crom_rng_seed(&rng, seed);
    /* withcut: a field with the features of a wall at x = 3 (the points lie
     * in [1.4, 4.6]^3), taken at side points of their own */
    crom_cutfeat cut = {2, 1, {{3, 1, 3, 5}}};
    int widths[] = {3 + (withcut ? 1 : 0), 7, 7, 9}; /* r = 3 */
    crom_nn_spec spec, ps, hs;
    CHECK(crom_nn_spec_set(&spec, 4, widths, CROM_NN_ELU) == 0);
    const int pw[] = {6, 8, 8}, hw[] = {8, 6, 3};
    size_t nW = crom_nn_spec_nparams(&spec), nP = 0;
    if (pointnet) {
        CHECK(crom_nn_pointnet_spec(&ps, &hs, 3, pw, 3, hw) == 0);
        nP = crom_nn_pointnet_nparams(&ps, &hs);
    }
    float *params = calloc(nW + nP, sizeof(float)), *gf = calloc(nW + nP, sizeof(float));
    crom_nn_mlp W;
    crom_nn_pointnet P;
    CHECK(crom_nn_mlp_init(&W, &spec, params, &rng) == 0);
    float sh[4] = {3, 4, 5, 0}, sc[4] = {0.7f, 0.8f, 0.9f, 1};
    CHECK(crom_nn_mlp_set_norm(&W, sh, sc) == 0);
    if (pointnet)
        CHECK(crom_nn_pointnet_init(&P, &ps, &hs, params + nW, &rng) == 0);
    crom_fit_batch b;
    make_batch(&b, &rng, pointnet);
    crom_fit_ctx ctx;
    CHECK(crom_fit_ctx_init(&ctx, &W, pointnet ? &P : NULL, 14, 7, 50, pointnet ? 5 : 1, tik, 1) == 0);
    if (withcut) {
        CHECK(crom_fit_ctx_set_cut(&ctx, NULL) == CROM_EUSAGE); /* 4 inputs need the cut */
        CHECK(crom_fit_ctx_set_cut(&ctx, &cut) == 0);
        b.S = malloc(sizeof(float) * 3 * 14);
        for (int i = 0; i < 3 * 14; i++)
            b.S[i] = b.X[i] + (i % 3 == 0 ? 0.3f : 0);
    }
    double obj, mis, q[7 * 3];
    CHECK(crom_fit_loss(&ctx, &b, &obj, &mis, gf, q) == 0);
    CHECK(isfinite(obj) && obj >= mis && mis > 0);
    int n = (int)(nW + nP);
    double *g = malloc(sizeof(double) * n), *fg = malloc(sizeof(double) * n), *x = malloc(sizeof(double) * n);
    for (int i = 0; i < n; i++) {
        g[i] = gf[i];
        x[i] = params[i];
    }
    fd_case t = {&ctx, &b, params, n};
    check_fd_gradient(loss_at, &t, x, n, FD_H, fg);
    double e = check_relerr(g, fg, n, 1e-12);
    double eW = check_relerr(g, fg, (int)nW, 1e-12);
    printf("  %-34s objective %.4f (misfit %.4f): gradient relerr %.2e (field part %.2e)\n", label, obj, mis, e, eW);
    CHECK_MSG(e < FD_TOL, "%s: gradient relerr %.3g", label, e);
    CHECK_MSG(eW < FD_TOL, "%s: field gradient relerr %.3g", label, eW);
    if (!pointnet) {
        /* q is the minimizer: moving it raises the data term plus penalty */
        CHECK(obj <= mis + 10 * tik); /* penalty is small next to the misfit */
    }
    free(g);
    free(fg);
    free(x);
    free(params);
    free(gf);
    free_batch(&b);
    free(b.S);
    crom_fit_ctx_free(&ctx);
    if (pointnet)
        crom_nn_pointnet_free(&P);
    crom_nn_mlp_free(&W);
}

static void test_gradients(void)
{
    printf("training losses: gradients vs finite differences\n");
    check_gradient("lsq (variable projection)", 0, 0, 0, 41);
    check_gradient("lsq with Tikhonov 0.05", 0, 0.05, 0, 42);
    check_gradient("joint PointNet + field (eq. 4)", 1, 0, 0, 43);
    check_gradient("lsq, a field with cut features", 0, 0, 1, 44);
}

/* A sample set of F frames of K analytic modes on an n^3 box of side 1. */
static void analytic_set(crom_samples *S, int n, int F, int K, double decay, uint64_t seed)
{
    crom_rng rng;
    crom_rng_seed(&rng, seed);
    crom_mesh m;
    double lo[3] = {-0.5, -0.5, -0.5};
    fx_box_mesh(&m, n, n, n, lo, 1.0 / n, 0.15, &rng, NULL);
    fx_samples_init(S, &m, 1);
    fx_add_frames(S, 0, F, K, decay, 0.03, 0.5, &rng);
}

/* Keep N random vertices of each frame (crom-sample's default mode). */
static void subsample(crom_samples *S, int N, uint64_t seed)
{
    crom_rng rng;
    crom_rng_seed(&rng, seed);
    int n0 = S->N, *perm = malloc(sizeof(int) * n0);
    for (int i = 0; i < n0; i++)
        perm[i] = i;
    for (int f = 0; f < S->F; f++) {
        crom_rng_shuffle(&rng, perm, n0);
        for (int i = 0; i < N; i++) {
            size_t a = (size_t)f * N + i, b = (size_t)f * n0 + perm[i];
            memmove(S->X + 3 * a, S->X + 3 * b, sizeof(float) * 3);
            memmove(S->U + 3 * a, S->U + 3 * b, sizeof(float) * 3);
            S->vertex[a] = S->vertex[b];
        }
    }
    S->N = N;
    free(perm);
}

static void test_analytic_fits(void)
{
    printf("fitting 4 analytic modes (30 frames, 343 vertices)\n");
    crom_samples S;
    analytic_set(&S, 6, 30, 4, 1.0, 51);
    /* POD: exact to round-off at r = 4, and r = 5 is beyond the data's rank */
    crom_model pod;
    double cap;
    CHECK(crom_fit_pod(&S, 4, &pod, &cap) == 0);
    printf("  pod r=4: reconstruction error %.2e, energy captured %.9f\n", pod.reconstruction_error, cap);
    CHECK_LT(pod.reconstruction_error, 1e-5);
    CHECK_NEAR(cap, 1.0, 1e-9);
    /* POD modes are orthonormal in the volume-mean inner product */
    {
        double *w = malloc(sizeof(double) * pod.mesh.nv), G[16] = {0};
        double V = crom_mesh_vertex_volumes(&pod.mesh, w);
        for (int v = 0; v < pod.mesh.nv; v++)
            for (int c = 0; c < 3; c++)
                for (int a = 0; a < 4; a++)
                    for (int bb = 0; bb < 4; bb++)
                        G[a * 4 + bb] += w[v] / V * pod.basis_v[(v * 3 + c) * 4 + a] *
                                         pod.basis_v[(v * 3 + c) * 4 + bb];
        double worst = 0;
        for (int a = 0; a < 4; a++)
            for (int bb = 0; bb < 4; bb++)
                worst = fmax(worst, fabs(G[a * 4 + bb] - (a == bb)));
        printf("  pod modes: |M-Gram - I| %.1e\n", worst);
        CHECK_LT(worst, 1e-12);
        free(w);
    }
    crom_model_free(&pod);
    crom_model bad;
    CHECK(crom_fit_pod(&S, 5, &bad, NULL) == CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), "numerical rank 4") != NULL, "%s", crom_errmsg());

    /* lsq neural field, r = 4 */
    crom_fit_opts o;
    crom_fit_defaults(&o);
    o.rank = 4;
    o.epochs = 1200;
    o.batch = 30;
    o.lr = 1e-2;
    o.width = 40;
    crom_model M;
    double t0 = crom_clock_now();
    CHECK(crom_fit_mlp(&S, &o, &M) == 0);
    printf("  lsq mlp r=4: reconstruction error %.4f after %d epochs (%.1f s)\n", M.reconstruction_error,
           M.nepochs, crom_clock_now() - t0);
    CHECK_LT(M.reconstruction_error, 0.02);
    CHECK(M.nepochs == 1200 && M.loss[M.nepochs - 1] < M.loss[0]);
    /* the canonical basis: orthonormal over the training points, q variance
     * decreasing */
    {
        const crom_mesh *m = &S.src[0];
        double *Wv = malloc(sizeof(double) * m->nv * 12), G[16] = {0};
        CHECK(crom_model_eval(&M, (size_t)m->nv, m->X, Wv, NULL) == 0);
        for (int v = 0; v < m->nv; v++)
            for (int c = 0; c < 3; c++)
                for (int a = 0; a < 4; a++)
                    for (int bb = 0; bb < 4; bb++)
                        G[a * 4 + bb] += Wv[(v * 3 + c) * 4 + a] * Wv[(v * 3 + c) * 4 + bb] / m->nv;
        double worst = 0;
        for (int a = 0; a < 16; a++)
            worst = fmax(worst, fabs(G[a] - (a % 5 == 0)));
        double *q = malloc(sizeof(double) * S.F * 4), var[4] = {0}, err;
        CHECK(crom_fit_error(&M, &S, 1e-6, 0, 1, &err, NULL, q) == 0);
        CHECK_NEAR(err, M.reconstruction_error, 1e-12);
        for (int f = 0; f < S.F; f++)
            for (int a = 0; a < 4; a++)
                var[a] += q[f * 4 + a] * q[f * 4 + a];
        printf("  canonical basis: |mean W^T W - I| %.1e, q variances %.3g %.3g %.3g %.3g\n", worst,
               var[0], var[1], var[2], var[3]);
        CHECK_LT(worst, 1e-4);
        CHECK(var[0] >= var[1] && var[1] >= var[2] && var[2] >= var[3]);
        free(Wv);
        free(q);
    }
    /* same seed, same parameters; another seed, another model */
    o.epochs = 20;
    crom_model A, B, C;
    CHECK(crom_fit_mlp(&S, &o, &A) == 0);
    CHECK(crom_fit_mlp(&S, &o, &B) == 0);
    o.seed = 2;
    CHECK(crom_fit_mlp(&S, &o, &C) == 0);
    CHECK(A.mlp.nparams == B.mlp.nparams &&
          memcmp(A.mlp.params, B.mlp.params, sizeof(float) * A.mlp.nparams) == 0);
    CHECK(!strcmp(A.model_id, B.model_id) && strcmp(A.model_id, C.model_id));
    crom_model_free(&A);
    crom_model_free(&B);
    crom_model_free(&C);
    crom_model_free(&M);

    /* random vertex subsets per frame (masked shared groups) */
    subsample(&S, 200, 52);
    crom_fit_defaults(&o);
    o.rank = 4;
    o.epochs = 1000;
    o.batch = 30;
    o.lr = 1e-2;
    o.width = 40;
    t0 = crom_clock_now();
    CHECK(crom_fit_mlp(&S, &o, &M) == 0);
    printf("  lsq mlp r=4 on 200 random vertices per frame: error %.4f (%.1f s)\n", M.reconstruction_error,
           crom_clock_now() - t0);
    CHECK_LT(M.reconstruction_error, 0.03);
    crom_model_free(&M);
    /* POD refuses samples that miss vertices */
    CHECK(crom_fit_pod(&S, 4, &bad, NULL) == CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), "--points all") != NULL, "%s", crom_errmsg());
    crom_samples_free(&S);
}

static void test_checks(void)
{
    printf("data checks\n");
    crom_samples S;
    analytic_set(&S, 2, 3, 2, 1.0, 61);
    CHECK(crom_fit_check(&S, 2) == 0);
    CHECK(crom_fit_check(&S, 4) == CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), "rank 4 exceeds") != NULL, "%s", crom_errmsg());
    memset(S.U, 0, sizeof(float) * 3 * S.N); /* frame 0 at rest */
    CHECK(crom_fit_check(&S, 3) == CROM_EDATA);
    S.F = 1;
    CHECK(crom_fit_check(&S, 1) == CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), "single frame") != NULL, "%s", crom_errmsg());
    S.F = 0;
    CHECK(crom_fit_check(&S, 1) == CROM_EDATA);
    CHECK_MSG(strstr(crom_errmsg(), "no frames") != NULL, "%s", crom_errmsg());
    S.F = 3;
    crom_samples_free(&S);
}

/* Two processes emulated by the two threads of an OpenMP team: the
 * allreduce adds both buffers into shared memory between barriers (as
 * MPI_Allreduce, both get the same sums: a + b is b + a bit for bit). */
typedef struct {
    double *sum;
    size_t cap;
} two_procs;

static int sum_two(void *ctx, double *buf, size_t n)
{
    two_procs *t = ctx;
    if (n > t->cap)
        return crom_err(CROM_EINTERNAL, "test allreduce of %zu doubles exceeds %zu", n, t->cap);
#pragma omp barrier
#pragma omp single
    memset(t->sum, 0, sizeof(double) * n);
#pragma omp critical
    for (size_t i = 0; i < n; i++)
        t->sum[i] += buf[i];
#pragma omp barrier
    memcpy(buf, t->sum, sizeof(double) * n);
#pragma omp barrier
    return 0;
}

/* Train on S with o as two processes; rc, models and stats per process. */
static void train_two(const crom_samples *S, const crom_fit_opts *o, const crom_fit_opts *o1, int rc[2],
                      crom_model M[2], crom_fit_stats st[2])
{
    two_procs tp = {malloc(sizeof(double) * (1 << 18)), 1 << 18};
#pragma omp parallel num_threads(2)
    {
        int p = omp_get_thread_num();
        crom_fit_opts q = p && o1 ? *o1 : *o;
        q.proc = p;
        q.nprocs = 2;
        q.allreduce = sum_two;
        q.allreduce_ctx = &tp;
        q.stats = &st[p];
        rc[p] = crom_fit_mlp(S, &q, &M[p]);
    }
    free(tp.sum);
}

/* Relative difference of two models' field parameters. */
static double param_diff(const crom_model *a, const crom_model *b)
{
    double d = 0, n = 0;
    for (size_t i = 0; i < a->mlp.nparams; i++) {
        d += ((double)a->mlp.params[i] - b->mlp.params[i]) * ((double)a->mlp.params[i] - b->mlp.params[i]);
        n += (double)a->mlp.params[i] * a->mlp.params[i];
    }
    return sqrt(d / n);
}

static void test_shards(void)
{
    printf("shards: one process and two emulated ones train the same model\n");
    int team = 1;
#pragma omp parallel num_threads(2)
#pragma omp single
    team = omp_get_num_threads();
    if (team != 2) {
        printf("  skipped: OpenMP gave %d threads, not 2\n", team);
        return;
    }
    int blas = openblas_get_num_threads();
    openblas_set_num_threads(1); /* two callers at once */
    crom_samples S;
    analytic_set(&S, 5, 14, 3, 1.0, 71);
    subsample(&S, 80, 72); /* masked shared groups */
    crom_fit_opts o;
    crom_fit_defaults(&o);
    o.rank = 3;
    o.epochs = 12;
    o.batch = 7;
    o.lr = 1e-2;
    o.width = 16;
    o.depth = 3;
    for (int pn = 0; pn < 2; pn++) {
        o.encoder = pn ? CROM_MODEL_ENC_POINTNET : CROM_MODEL_ENC_LSQ;
        o.enc_points = 20;
        o.epochs = pn ? 3 : 12;
        for (int shards = 2; shards <= 3; shards++) {
            o.shards = shards;
            crom_model A, M[2];
            crom_fit_stats st[2];
            int rc[2];
            CHECK(crom_fit_mlp(&S, &o, &A) == 0);
            train_two(&S, &o, NULL, rc, M, st);
            CHECK(rc[0] == 0 && rc[1] == 0);
            if (rc[0] || rc[1])
                continue;
            double d = param_diff(&A, &M[0]), de = 0;
            if (pn) {
                crom_nn_pointnet *a = &A.enc, *b = &M[0].enc;
                double dd = 0, nn = 0;
                for (size_t i = 0; i < a->nparams; i++) {
                    dd += ((double)a->params[i] - b->params[i]) * ((double)a->params[i] - b->params[i]);
                    nn += (double)a->params[i] * a->params[i];
                }
                de = sqrt(dd / nn);
            }
            printf("  %s, %d shards: |two - one| / |one| of the field %.2g, of the encoder %.2g; %zu doubles a "
                   "step\n", pn ? "pointnet" : "lsq", shards, d, de, st[0].allreduce_doubles);
            CHECK_LT(d, 1e-5);
            CHECK_LT(de, 1e-5);
            /* every process took the same steps: the same bits */
            CHECK(!memcmp(M[0].mlp.params, M[1].mlp.params, sizeof(float) * M[0].mlp.nparams));
            CHECK(!strcmp(M[0].model_id, M[1].model_id));
            CHECK(st[0].allreduce_doubles == A.mlp.nparams + (pn ? A.enc.nparams : 0) + CROM_FIT_EXTRAS);
            CHECK(st[0].steps == st[1].steps && st[0].samples == st[1].samples);
            if (!pn && shards == 2) {
                /* the comparison means something: one shard, or another
                 * seed, gives another model */
                crom_fit_opts q = o;
                crom_model B;
                q.shards = 1;
                CHECK(crom_fit_mlp(&S, &q, &B) == 0);
                printf("  1 shard against 2: %.2g\n", param_diff(&A, &B));
                CHECK(param_diff(&A, &B) > 1e-3);
                crom_model_free(&B);
                q = o;
                q.seed = 2;
                CHECK(crom_fit_mlp(&S, &q, &B) == 0);
                CHECK(param_diff(&A, &B) > 1e-2);
                crom_model_free(&B);
            }
            crom_model_free(&A);
            crom_model_free(&M[0]);
            crom_model_free(&M[1]);
        }
    }
    /* failures are shared: other options on one process, or a setup that
     * fails on one, stop both at once instead of leaving one waiting */
    o.encoder = CROM_MODEL_ENC_LSQ;
    o.epochs = 4;
    o.shards = 2;
    crom_fit_opts o1 = o;
    o1.epochs = 5;
    crom_model M[2];
    crom_fit_stats st[2];
    int rc[2];
    train_two(&S, &o, &o1, rc, M, st);
    CHECK(rc[0] == CROM_EUSAGE && rc[1] == CROM_EUSAGE);
    o1 = o;
    o1.shards = 8; /* more than the 7 frames of a batch */
    train_two(&S, &o, &o1, rc, M, st);
    CHECK(rc[0] == CROM_EINTERNAL && st[0].remote_failure == 1);
    CHECK(rc[1] == CROM_EUSAGE && st[1].remote_failure == 0);
    /* and serially: a shard needs a frame */
    o.shards = 8;
    CHECK(crom_fit_mlp(&S, &o, &M[0]) == CROM_EUSAGE);
    CHECK_MSG(strstr(crom_errmsg(), "--shards 8 exceeds the 7 frames of a batch") != NULL, "%s", crom_errmsg());
    crom_samples_free(&S);
    openblas_set_num_threads(blas);
}

int main(void)
{
    check_begin("test_fit");
    test_gradients();
    test_checks();
    test_analytic_fits();
    test_shards();
    return check_done();
}
