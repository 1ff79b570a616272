/* dftrain.c — the training loop of the data-free trainers (see dftrain.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/err.h"
#include "base/lbfgs.h"
#include "datafree/dftrain.h"
#include "io/io.h"
#include "nn/nn.h"

/* ============================================================ set-up */

double crom_dftrain_diag(const crom_mesh *m)
{
    double lo[3], hi[3];
    crom_mesh_bbox(m, lo, hi);
    return sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                (hi[2] - lo[2]) * (hi[2] - lo[2]));
}

int crom_dftrain_spec(crom_nn_spec *spec, int in, int width, int depth, int out, crom_nn_act act)
{
    int widths[CROM_NN_MAX_LAYERS + 1];
    if (depth < 1 || depth > CROM_NN_MAX_LAYERS)
        return crom_err(CROM_EUSAGE, "a network of %d layers (at most %d)", depth, CROM_NN_MAX_LAYERS);
    widths[0] = in;
    for (int l = 1; l < depth; l++)
        widths[l] = width;
    widths[depth] = out;
    return crom_nn_spec_set(spec, depth + 1, widths, act);
}

int crom_dftrain_norm_box(crom_nn_mlp *net, const crom_mesh *m)
{
    float sh[3], sc[3];
    double lo[3], hi[3];
    crom_mesh_bbox(m, lo, hi);
    double corners[6] = {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]};
    int rc = crom_nn_norm_fit(corners, 2, 3, sh, sc);
    return rc ? rc : crom_nn_mlp_set_norm(net, sh, sc);
}

void crom_dftrain_scale_last(crom_nn_mlp *net, float f)
{
    crom_nn_layer *ly = &net->layer[net->spec.nlayers - 1];
    for (int i = 0; i < ly->out * ly->in; i++)
        ly->W[i] *= f;
    for (int i = 0; i < ly->out; i++)
        ly->b[i] *= f;
}

void crom_dftrain_seed(uint64_t seed, crom_rng *init, crom_rng *samples)
{
    crom_rng_seed(init, seed);
    crom_rng_seed(samples, seed ^ 0x5eed5a3b1e5ULL);
}

int crom_dftrain_threads(int n) { return n < 1 ? 1 : n > 256 ? 256 : n; }

/* ============================================================ the record */

void crom_dftrain_log_free(crom_dftrain_log *l)
{
    if (!l)
        return;
    free(l->objective);
    free(l->energy);
    free(l->penalty);
    free(l->seconds);
    memset(l, 0, sizeof *l);
}

int crom_dftrain_log_write(hid_t loc, const crom_dftrain_log *log)
{
    hsize_t d = (hsize_t)log->nblocks;
    if (d == 0)
        return 0;
    int rc = crom_h5_put_f64(loc, "training/objective", 1, &d, log->objective);
    if (!rc)
        rc = crom_h5_put_f64(loc, "training/energy", 1, &d, log->energy);
    if (!rc)
        rc = crom_h5_put_f64(loc, "training/penalty", 1, &d, log->penalty);
    if (!rc)
        rc = crom_h5_put_f64(loc, "training/seconds", 1, &d, log->seconds);
    return rc;
}

/* ============================================================ the run */

/* A run in progress: the loop, its record, the clock, the block being
 * summed, and the batch of the step. */
typedef struct {
    const crom_dftrain_loop *L;
    crom_dftrain_log *log;
    int block, inblock;
    double budget, tstart, sobj, sen, spen;
    double *z, rho;
    int *tets;
} run;

static void run_free(run *R)
{
    free(R->z);
    free(R->tets);
}

/* The record for L->steps steps, the batch's buffers, the clock.
 * CROM_EINTERNAL. */
static int run_begin(run *R, const crom_dftrain_loop *L, crom_dftrain_log *log)
{
    memset(R, 0, sizeof *R);
    R->L = L;
    R->log = log;
    R->block = L->steps >= 100 ? (L->steps + 99) / 100 : 1;
    int maxblocks = L->steps / R->block + 2;
    log->nblocks = 0;
    log->steps = 0;
    log->seconds_total = 0;
    log->objective = crom_malloc(sizeof(double) * (size_t)maxblocks);
    log->energy = crom_malloc(sizeof(double) * (size_t)maxblocks);
    log->penalty = crom_malloc(sizeof(double) * (size_t)maxblocks);
    log->seconds = crom_malloc(sizeof(double) * (size_t)maxblocks);
    R->z = crom_malloc(sizeof(double) * ((size_t)(L->batch + L->tangent) * (size_t)L->r + 1));
    R->tets = L->K > 0 ? crom_malloc(sizeof(int) * (size_t)L->K) : NULL;
    if (!log->objective || !log->energy || !log->penalty || !log->seconds || !R->z || (L->K > 0 && !R->tets))
        return CROM_EINTERNAL;
    R->budget = L->minutes > 0 ? 60 * L->minutes : 0;
    R->tstart = crom_clock_now();
    return 0;
}

/* Before step k: 0 when the time budget is spent, else 1 with the
 * fraction of the schedule done in *frac. */
static int run_next(run *R, long k, double *frac)
{
    double f = (double)k / R->L->steps, el = crom_clock_now() - R->tstart;
    if (R->budget > 0) {
        if (el >= R->budget)
            return 0;
        f = fmax(f, el / R->budget);
    }
    *frac = f;
    return 1;
}

static void close_block(run *R)
{
    crom_dftrain_log *log = R->log;
    int j = log->nblocks++;
    log->objective[j] = R->sobj / R->inblock;
    log->energy[j] = R->sen / R->inblock;
    log->penalty[j] = R->spen / R->inblock;
    log->seconds[j] = crom_clock_wall(crom_clock_now() - R->tstart);
    R->sobj = R->sen = R->spen = 0;
    R->inblock = 0;
}

/* After step k: record its terms, report progress at the end of a block. */
static void run_record(run *R, long k, const crom_dftrain_terms *t)
{
    const crom_dftrain_loop *L = R->L;
    R->sobj += t->objective;
    R->sen += t->energy;
    R->spen += t->penalty;
    if (++R->inblock == R->block || k + 1 == L->steps) {
        close_block(R);
        if (L->progress) {
            double f = (double)(k + 1) / L->steps;
            if (R->budget > 0)
                f = fmax(f, (crom_clock_now() - R->tstart) / R->budget);
            L->progress(L->progress_ctx, k + 1, fmin(f, 1.0), R->log->objective[R->log->nblocks - 1]);
        }
    }
}

/* After the last step (k steps taken): close the record. CROM_EUSAGE if
 * no step was taken (the time budget ran out first). */
static int run_end(run *R, long k)
{
    if (R->inblock > 0) /* stopped by the clock inside a block */
        close_block(R);
    R->log->steps = k;
    R->log->seconds_total = crom_clock_now() - R->tstart;
    return k > 0 ? 0 : crom_err(CROM_EUSAGE, "no training step fitted in the time budget");
}

/* The learning rate at fraction frac of the run: base, halved after each
 * quarter. */
static double learning_rate(double base, double frac)
{
    int q = (int)floor(4 * frac);
    if (q > 3)
        q = 3;
    if (q < 0)
        q = 0;
    return base * ldexp(1.0, -q);
}

/* A fresh batch at fraction frac: the samples, the tangent samples, the
 * tets of a fresh random cubature, and ρ. */
static void draw(run *R, double frac)
{
    const crom_dftrain_loop *L = R->L;
    int r = L->r, n = L->batch * r;
    R->rho = L->ramp > 0 ? fmin(1.0, frac / L->ramp) : 1;
    for (int i = 0; i < n; i++) {
        double s = L->scale ? L->scale[i % r] : 1;
        R->z[i] = L->uniform ? s * (2 * crom_rng_uniform(L->rng) - 1)
                  : L->scale ? s * crom_rng_normal(L->rng) : crom_rng_normal(L->rng);
    }
    for (int k = 0; k < L->tangent; k++) /* the secants from rest along the axes: ε e_(k mod r) */
        for (int j = 0; j < r; j++)
            R->z[n + k * r + j] = j == k % r ? L->tangent_radius : 0;
    for (int i = 0; R->tets && i < L->K; i++)
        R->tets[i] = L->K == L->nt ? i : (int)crom_rng_below(L->rng, (uint64_t)L->nt);
}

static int loss(run *R, crom_dftrain_terms *t)
{
    return R->L->loss(R->L->ctx, R->z, R->rho, R->L->K, R->tets, t);
}

/* ============================================================ Adam */

/* Adam on a fresh batch every step, the learning rate halved after each
 * quarter of the schedule; *kout the steps taken. */
static int train_adam(run *R, long *kout)
{
    const crom_dftrain_loop *L = R->L;
    crom_nn_adam adam[2];
    memset(adam, 0, sizeof adam);
    int rc = 0;
    for (int j = 0; !rc && j < L->nblocks; j++)
        rc = crom_nn_adam_init(&adam[j], L->nparams[j]);
    long k = 0;
    R->tstart = crom_clock_now(); /* the clock starts after the set-up */
    for (; !rc && k < L->steps; k++) {
        double frac;
        if (!run_next(R, k, &frac))
            break;
        draw(R, frac);
        crom_dftrain_terms tm;
        if ((rc = loss(R, &tm))) {
            if (rc == CROM_EDATA)
                crom_err_ctx("training diverged at step %ld%s", k + 1, L->hint ? L->hint : "");
            break;
        }
        double lr = learning_rate(L->lr, frac);
        for (int j = 0; j < L->nblocks; j++)
            crom_nn_adam_step(&adam[j], L->params[j], L->grad[j], lr);
        run_record(R, k, &tm);
    }
    for (int j = 0; j < 2; j++)
        crom_nn_adam_free(&adam[j]);
    *kout = k;
    return rc;
}

/* ============================================================ L-BFGS */

/* The state of L-BFGS over the np parameters of the first block: the
 * memory, the point x with its objective f and gradient g, the trial
 * point xt with ft, gt and its terms, and the direction d. */
typedef struct {
    crom_lbfgs M;
    size_t np;
    double *x, *g, *xt, *gt, *d;
    double f, ft;
    crom_dftrain_terms tt;
} lbfgs_state;

static void lbfgs_free(lbfgs_state *S)
{
    crom_lbfgs_free(&S->M);
    free(S->x);
    free(S->g);
    free(S->xt);
    free(S->gt);
    free(S->d);
}

static int lbfgs_init(lbfgs_state *S, const crom_dftrain_loop *L)
{
    memset(S, 0, sizeof *S);
    size_t np = S->np = L->nparams[0];
    int rc = crom_lbfgs_init(&S->M, np, 10);
    S->x = crom_malloc(sizeof(double) * np);
    S->g = crom_malloc(sizeof(double) * np);
    S->xt = crom_malloc(sizeof(double) * np);
    S->gt = crom_malloc(sizeof(double) * np);
    S->d = crom_malloc(sizeof(double) * np);
    if (!rc && (!S->x || !S->g || !S->xt || !S->gt || !S->d))
        rc = CROM_EINTERNAL;
    for (size_t i = 0; !rc && i < np; i++)
        S->x[i] = L->params[0][i];
    return rc;
}

/* The loss and gradient (double) at parameters x, through the float
 * network. Returns 0, or CROM_EDATA where it is not finite (an inverted
 * element): the line search then shortens the step. */
static int lbfgs_eval(run *R, size_t np, const double *x, double *f, double *g, crom_dftrain_terms *tm)
{
    float *params = R->L->params[0], *grad = R->L->grad[0];
    for (size_t i = 0; i < np; i++)
        params[i] = (float)x[i];
    int rc = loss(R, tm);
    if (rc)
        return rc;
    for (size_t i = 0; i < np; i++)
        g[i] = grad[i];
    *f = tm->objective;
    return 0;
}

/* The direction d of the memory and its slope gᵀd; where it is no descent
 * (or there is no pair yet), steepest descent moving no parameter by more
 * than lr. Returns 0, or 1 where the gradient is zero. */
static int lbfgs_direction(lbfgs_state *S, double lr, double *slope)
{
    size_t np = S->np;
    const double *g = S->g;
    double *d = S->d;
    crom_lbfgs_direction(&S->M, g, d);
    *slope = 0;
    for (size_t i = 0; i < np; i++)
        *slope += g[i] * d[i];
    if (!(*slope < 0) || S->M.k == 0) {
        crom_lbfgs_reset(&S->M);
        double gmax = 0;
        for (size_t i = 0; i < np; i++)
            gmax = fmax(gmax, fabs(g[i]));
        if (!(gmax > 0))
            return 1;
        *slope = 0;
        for (size_t i = 0; i < np; i++) {
            d[i] = -lr * g[i] / gmax;
            *slope += g[i] * d[i];
        }
    }
    return 0;
}

/* Backtracking along d from x (Armijo, halving up to 30 times; a
 * non-finite loss shortens the step): the accepted point in xt, ft, gt,
 * tt. Returns 0 with *ok, or the loss's error. */
static int lbfgs_search(run *R, lbfgs_state *S, double slope, int *ok)
{
    size_t np = S->np;
    double alpha = 1;
    S->ft = NAN;
    *ok = 0;
    for (int ls = 0; ls < 30 && !*ok; ls++, alpha *= 0.5) {
        for (size_t i = 0; i < np; i++)
            S->xt[i] = S->x[i] + alpha * S->d[i];
        int e = lbfgs_eval(R, np, S->xt, &S->ft, S->gt, &S->tt);
        if (e == CROM_EDATA) {
            crom_err_clear();
            continue;
        }
        if (e)
            return e;
        *ok = S->ft <= S->f + 1e-4 * alpha * slope + 1e-6 * fabs(S->f);
        if (*ok)
            break;
    }
    return 0;
}

/* Accept the trial point: keep the pair, step to it. */
static void lbfgs_accept(lbfgs_state *S)
{
    size_t np = S->np;
    double *d = S->d, *xt = S->xt;
    for (size_t i = 0; i < np; i++) { /* the pair, then the step */
        d[i] = xt[i] - S->x[i];
        xt[i] = S->gt[i] - S->g[i];
    }
    crom_lbfgs_push(&S->M, d, xt);
    for (size_t i = 0; i < np; i++)
        S->x[i] += d[i];
    memcpy(S->g, S->gt, sizeof(double) * np);
    S->f = S->ft;
}

/* L-BFGS, L->resample iterations on each batch of samples and tets
 * before a fresh one is drawn; *kout the steps taken. */
#define IDLE_BATCHES 100

static int train_lbfgs(run *R, long *kout)
{
    const crom_dftrain_loop *L = R->L;
    lbfgs_state S;
    int rc = lbfgs_init(&S, L), ready = !rc, stop = 0, idle = 0;
    long k = 0;
    R->tstart = crom_clock_now(); /* the clock starts after the set-up */
    /* A batch on which no step is accepted (a zero gradient, or no decrease
     * along any direction tried) draws the next one; after IDLE_BATCHES such
     * batches in a row the parameters are taken as converged and training
     * ends (an error if it never took a step), rather than drawing batches
     * for ever. */
    while (!rc && !stop && k < L->steps && idle < IDLE_BATCHES) {
        long k0 = k;
        double frac;
        if (!run_next(R, k, &frac))
            break;
        draw(R, frac);
        crom_dftrain_terms tm;
        if ((rc = lbfgs_eval(R, S.np, S.x, &S.f, S.g, &tm))) {
            if (rc == CROM_EDATA)
                crom_err_ctx("training diverged at step %ld", k + 1);
            break;
        }
        for (int it = 0; it < L->resample && k < L->steps; it++) {
            if (it > 0 && !run_next(R, k, &frac)) {
                stop = 1;
                break;
            }
            double slope;
            int ok;
            if (lbfgs_direction(&S, L->lr, &slope))
                break;
            if ((rc = lbfgs_search(R, &S, slope, &ok)))
                break;
            if (!ok) { /* no decrease along d: start the memory afresh on the next batch */
                crom_lbfgs_reset(&S.M);
                break;
            }
            lbfgs_accept(&S);
            run_record(R, k, &S.tt);
            k++;
        }
        idle = k == k0 ? idle + 1 : 0;
    }
    if (!rc && idle >= IDLE_BATCHES && k == 0)
        rc = crom_err(CROM_EDATA, "L-BFGS took no step on %d batches in a row (a zero gradient, or no decrease "
                                  "along the gradient)", IDLE_BATCHES);
    for (size_t i = 0; ready && i < S.np; i++) /* the parameters of the last accepted step */
        L->params[0][i] = (float)S.x[i];
    lbfgs_free(&S);
    *kout = k;
    return rc;
}

/* ============================================================ training */

int crom_dftrain_run(const crom_dftrain_loop *L, crom_dftrain_log *log)
{
    run R;
    long k = 0;
    int rc = run_begin(&R, L, log);
    if (!rc)
        rc = L->lbfgs ? train_lbfgs(&R, &k) : train_adam(&R, &k);
    if (!rc)
        rc = run_end(&R, k);
    run_free(&R);
    if (rc)
        crom_dftrain_log_free(log);
    return rc;
}
