/* datafree.c — energy-trained and Neural-Modes subspaces (see datafree.h). */
#ifdef _OPENMP
#include <omp.h>
#endif
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "base/clock.h"
#include "base/err.h"
#include "base/lbfgs.h"
#include "base/rng.h"
#include "datafree/datafree.h"
#include "datafree/dffield.h"
#include "io/io.h"

void crom_datafree_defaults(crom_datafree_opts *o, int objective)
{
    memset(o, 0, sizeof *o);
    int field = objective == CROM_DATAFREE_FIELD, nm = objective == CROM_DATAFREE_NEURALMODES;
    o->objective = objective;
    o->rank = nm ? 0 : 8;
    o->depth = field ? 4 : 6;
    o->width = 64;
    o->act = nm ? CROM_NN_GELU : CROM_NN_ELU;
    /* the one-mesh maps: many small steps at a larger rate (issue 14's
     * measurements, datafree.h); the field: as trained before */
    o->steps = field ? 2000 : 4000;
    o->lr = field ? 1e-3 : 3e-3;
    o->batch = field ? 32 : 8;
    o->lambda = field ? 1 : 0.03;
    o->ramp = 0.5;
    o->ortho_weight = 1e4;
    o->box_scaled = 1;
    o->features = 32;
    o->field_depth = 4;
    o->field_width = 64;
    o->tets = field ? 512 : 0;
    o->optimizer = CROM_DATAFREE_ADAM;
    o->resample = 10;
    o->tangent_weight = field ? 0 : 0.1;
    o->tangent_samples = 8;
    o->tangent_radius = 0.1;
    o->pin_length = 0;
    o->threads = 1;
    o->seed = 1;
}

/* ============================================================ the loss */

void crom_datafree_ctx_free(crom_datafree_ctx *c)
{
    if (!c)
        return;
    crom_fem_free(&c->fem);
    crom_nn_ws_free(&c->ws);
    free(c->mw);
    free(c->MWm);
    free(c->Y);
    free(c->G);
    free(c->dY);
    free(c->E);
    free(c->xb);
    free(c->zf);
    free(c->dyf);
    free(c->bad);
    free(c->cb);
    free(c->half);
    memset(c, 0, sizeof *c);
}

int crom_datafree_ctx_init(crom_datafree_ctx *c, const crom_datafree_problem *p, const crom_datafree_opts *o,
                     const crom_nn_mlp *net, int maxbatch)
{
    memset(c, 0, sizeof *c);
    c->P = *p;
    c->o = *o;
    c->net = net;
    const crom_nn_spec *sp = &net->spec;
    int r = sp->width[0], n = 3 * p->mesh->nv, nm = o->objective == CROM_DATAFREE_NEURALMODES;
    if (sp->width[sp->nlayers] != n)
        return crom_err(CROM_EUSAGE, "the map's network outputs %d values, the mesh has 3nv = %d",
                        sp->width[sp->nlayers], n);
    if (maxbatch < 1)
        return crom_err(CROM_EUSAGE, "batch of %d samples", maxbatch);
    if (nm && !p->modes)
        return crom_err(CROM_EUSAGE, "neuralmodes needs linear modes");
    if (!nm && !(o->sigma > 0))
        return crom_err(CROM_EUSAGE, "sigma must be positive");
    if (nm && !(o->box > 0))
        return crom_err(CROM_EUSAGE, "the latent box must be positive");
    c->r = r;
    c->n = n;
    c->maxbatch = maxbatch;
    c->B0 = !nm && o->tangent_weight > 0 ? o->tangent_samples : 0;
    if (c->B0 < 0)
        return crom_err(CROM_EUSAGE, "%d tangent samples", c->B0);
    c->nthreads = o->threads < 1 ? 1 : o->threads > 256 ? 256 : o->threads;
    size_t rows = (size_t)maxbatch + c->B0 + 1; /* the batch, the tangent samples, the anchor */
    int rc = crom_fem_init(&c->fem, p->mesh, &p->mat);
    if (!rc)
        rc = crom_nn_ws_init(&c->ws, net, (int)rows, 1);
    if (rc) {
        crom_datafree_ctx_free(c);
        return rc;
    }
    c->mw = crom_malloc(sizeof(double) * (size_t)n);
    c->MWm = nm ? crom_malloc(sizeof(double) * (size_t)n * r) : NULL;
    c->Y = crom_malloc(sizeof(double) * rows * n);
    c->G = crom_malloc(sizeof(double) * (size_t)maxbatch * n);
    c->dY = crom_malloc(sizeof(double) * rows * n);
    c->E = crom_malloc(sizeof(double) * (size_t)maxbatch);
    c->xb = crom_malloc(sizeof(double) * (size_t)c->nthreads * n);
    c->zf = crom_malloc(sizeof(float) * rows * r);
    c->dyf = crom_malloc(sizeof(float) * rows * n);
    c->bad = crom_malloc(sizeof(int) * (size_t)maxbatch);
    c->cb = crom_malloc(sizeof(double) * (size_t)(r > c->B0 ? r : c->B0));
    c->half = crom_malloc(sizeof(double) * (size_t)r);
    if (!c->cb || !c->half || !c->mw || (nm && !c->MWm) || !c->Y || !c->G || !c->dY || !c->E || !c->xb || !c->zf || !c->dyf || !c->bad) {
        crom_datafree_ctx_free(c);
        return CROM_EINTERNAL;
    }
    c->mass = c->fem.total_mass;
    for (int i = 0; i < n; i++)
        c->mw[i] = c->fem.mass[i / 3] / c->mass;
    double EV = p->mat.E * c->fem.volume;
    c->Eref = EV;
    if (nm) {
        for (int i = 0; i < n; i++)
            for (int k = 0; k < r; k++)
                c->MWm[(size_t)i * r + k] = c->mw[i] * p->modes[(size_t)i * r + k];
        double fmax = 0, fmin = INFINITY;
        for (int k = 0; p->freq && k < r; k++) {
            fmax = fmax > p->freq[k] ? fmax : p->freq[k];
            if (p->freq[k] > 0)
                fmin = fmin < p->freq[k] ? fmin : p->freq[k];
        }
        /* the box: half-width a for every mode, or a f_1 / f_k for mode k
         * (the same linear energy ½ m ω_k² a_k² at every edge) */
        int scaled = o->box_scaled && isfinite(fmin);
        for (int k = 0; k < r; k++)
            c->half[k] = scaled && p->freq[k] > 0 ? o->box * fmin / p->freq[k] : o->box;
        double w = 2 * M_PI * (scaled ? fmin : fmax);
        c->Eref = 0.5 * c->mass * w * w * o->box * o->box;
        if (!(c->Eref > 0) || !isfinite(c->Eref))
            c->Eref = EV;
    }
    return 0;
}

int crom_datafree_loss(crom_datafree_ctx *c, int B, const double *z, double rho, int K, const int *tets, crom_datafree_terms *t,
                 float *grad)
{
    int r = c->r, n = c->n, nm = c->o.objective == CROM_DATAFREE_NEURALMODES, B0 = c->B0, rows = B + B0 + 1;
    const unsigned char *fixed = c->P.fixed;
    const double *X = c->P.mesh->X;
    const crom_fem *fem = &c->fem;
    if (B < 1 || B > c->maxbatch)
        return crom_err(CROM_EUSAGE, "batch of %d samples (at most %d)", B, c->maxbatch);
    for (int k = 0; tets && k < K; k++)
        if (tets[k] < 0 || tets[k] >= fem->nt)
            return crom_err(CROM_EUSAGE, "tet %d out of range", tets[k]);
    if (tets && K < 1)
        return crom_err(CROM_EUSAGE, "a cubature of %d tets", K);
    if (!nm)
        rho = rho < 0 ? 0 : rho > 1 ? 1 : rho;
    else
        rho = 1;
    /* the batch, the tangent samples, then z = 0: the anchor N(0) that
     * every sample is taken relative to (lib/map.h), x = X + W z + ρ (N(z)
     * − N(0)) */
    for (int b = 0; b < B + B0; b++)
        for (int k = 0; k < r; k++)
            c->zf[(size_t)b * r + k] = (float)z[(size_t)b * r + k];
    memset(c->zf + (size_t)(B + B0) * r, 0, sizeof(float) * (size_t)r);
    int rc = crom_nn_mlp_forward(c->net, &c->ws, rows, c->zf, NULL);
    if (rc)
        return rc;
    const float *Yf = crom_nn_ws_output(&c->ws), *Y0 = Yf + (size_t)(B + B0) * n;
    for (int b = 0; b < B + B0; b++) /* Y_b = N(z_b) − N(0) */
        for (int i = 0; i < n; i++)
            c->Y[(size_t)b * n + i] = (double)Yf[(size_t)b * n + i] - (double)Y0[i];
    if (fixed) /* pinned outputs do not exist: the mask is part of the map */
        for (int b = 0; b < B + B0; b++)
            for (int i = 0; i < n; i++)
                if (fixed[i])
                    c->Y[(size_t)b * n + i] = 0;
    /* energies and their gradients, sample by sample */
    const double *g = c->P.gravity;
    const double *Wm = c->P.modes;
    crom_fem_opts fo = {0, 0, fixed, 1};
#pragma omp parallel for num_threads(c->nthreads) schedule(static)
    for (int b = 0; b < B; b++) {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        double *x = c->xb + (size_t)tid * n, *G = c->G + (size_t)b * n;
        const double *Y = c->Y + (size_t)b * n, *zb = z + (size_t)b * r;
        for (int i = 0; i < n; i++) {
            double u = rho * Y[i];
            if (nm)
                for (int k = 0; k < r; k++)
                    u += Wm[(size_t)i * r + k] * zb[k];
            x[i] = X[i] + u;
        }
        double Eb = 0;
        if (!tets) {
            c->bad[b] = crom_fem_assemble(fem, x, &fo, &Eb, G, NULL);
        } else { /* K random tets, each standing for nt/K of them */
            double wK = (double)fem->nt / K;
            memset(G, 0, sizeof(double) * (size_t)n);
            c->bad[b] = 0;
            for (int k = 0; k < K && !c->bad[b]; k++) {
                const int *tv = fem->tets + 4 * (size_t)tets[k];
                double xe[12], ge[12], Ee;
                for (int a = 0; a < 4; a++)
                    memcpy(xe + 3 * a, x + 3 * (size_t)tv[a], sizeof(double) * 3);
                c->bad[b] = crom_fem_tet_eval(&fem->mat, xe, fem->Dminv + 9 * (size_t)tets[k], fem->vol[tets[k]], 0,
                                              &Ee, ge, NULL);
                Eb += wK * Ee;
                for (int a = 0; a < 4; a++)
                    for (int d = 0; d < 3; d++)
                        G[3 * (size_t)tv[a] + d] += wK * ge[3 * a + d];
            }
            for (int i = 0; fixed && i < n; i++)
                if (fixed[i])
                    G[i] = 0;
        }
        if (!nm) /* gravity: -Σ m_v g·u_v */
            for (int i = 0; i < n; i++) {
                if (fixed && fixed[i])
                    continue;
                double mg = c->fem.mass[i / 3] * g[i % 3];
                Eb -= mg * (x[i] - X[i]);
                G[i] -= mg;
            }
        c->E[b] = Eb;
    }
    for (int b = 0; b < B; b++)
        if (c->bad[b] || !isfinite(c->E[b]))
            return crom_err(CROM_EDATA, "sample %d of the batch has a non-finite energy", b);
    double obj = 0, Em = 0, pen = 0, tan = 0;
    double scale = 1.0 / (B * c->Eref);
    for (int b = 0; b < B; b++) {
        Em += c->E[b] / B;
        obj += c->E[b] * scale;
        const double *G = c->G + (size_t)b * n;
        double *dY = c->dY + (size_t)b * n;
        for (int i = 0; i < n; i++)
            dY[i] = rho * scale * G[i];
    }
    if (!nm && B >= 2) {
        /* isometry: λ mean_{b<c} ℓ², ℓ = ½ log D² − log(σ |z_b − z_c|)
         * (the anchor cancels in the differences) */
        double npairs = 0.5 * B * (B - 1), lam = c->o.lambda, ls = log(c->o.sigma);
        for (int b = 0; b < B; b++)
            for (int e = b + 1; e < B; e++) {
                const double *Yb = c->Y + (size_t)b * n, *Ye = c->Y + (size_t)e * n;
                double dz = 0, D2 = 0;
                for (int k = 0; k < r; k++) {
                    double d = z[(size_t)b * r + k] - z[(size_t)e * r + k];
                    dz += d * d;
                }
                for (int i = 0; i < n; i++) {
                    double d = Yb[i] - Ye[i];
                    D2 += c->mw[i] * d * d;
                }
                if (!(D2 > 0) || !(dz > 0))
                    continue;
                double l = 0.5 * log(D2) - 0.5 * log(dz) - ls;
                pen += l * l / npairs;
                obj += lam * l * l / npairs;
                double coef = lam / npairs * 2 * l / D2;
                double *dYb = c->dY + (size_t)b * n, *dYe = c->dY + (size_t)e * n;
                for (int i = 0; i < n; i++) {
                    double v = coef * c->mw[i] * (Yb[i] - Ye[i]);
                    dYb[i] += v;
                    dYe[i] -= v;
                }
            }
    }
    if (B0 > 0) {
        /* the tangent at rest, conformal: λ_0 mean_s (ℓ_s − ℓ̄)², ℓ_s = ½ log
         * D_s² − log |z_s| with D_s the RMS displacement of the small sample
         * z_s from rest and ℓ̄ the mean over the samples: every direction
         * moves the body alike near rest, at a scale the map is free to
         * choose (the gradient of the mean cancels, Σ_s (ℓ_s − ℓ̄) = 0) */
        double lam0 = c->o.tangent_weight, *lsb = c->cb, lbar = 0;
        int ok = 1;
        for (int b = B; b < B + B0; b++) {
            const double *Yb = c->Y + (size_t)b * n;
            double dz = 0, D2 = 0;
            for (int k = 0; k < r; k++)
                dz += z[(size_t)b * r + k] * z[(size_t)b * r + k];
            for (int i = 0; i < n; i++)
                D2 += c->mw[i] * Yb[i] * Yb[i];
            memset(c->dY + (size_t)b * n, 0, sizeof(double) * (size_t)n);
            ok &= D2 > 0 && dz > 0;
            lsb[b - B] = 0.5 * log(D2) - 0.5 * log(dz);
            lbar += lsb[b - B] / B0;
        }
        for (int b = B; ok && b < B + B0; b++) {
            const double *Yb = c->Y + (size_t)b * n;
            double *dYb = c->dY + (size_t)b * n, D2 = 0, l = lsb[b - B] - lbar;
            for (int i = 0; i < n; i++)
                D2 += c->mw[i] * Yb[i] * Yb[i];
            tan += l * l / B0;
            obj += lam0 * l * l / B0;
            double coef = lam0 / B0 * 2 * l / D2;
            for (int i = 0; i < n; i++)
                dYb[i] = coef * c->mw[i] * Yb[i];
        }
    }
    if (nm) {
        /* M-orthogonality of y(z) − y(0) to the modes */
        double a2 = c->o.box * c->o.box, wo = c->o.ortho_weight;
        double *cp = c->cb;
        for (int b = 0; b < B; b++) {
            const double *Yb = c->Y + (size_t)b * n;
            cblas_dgemv(CblasRowMajor, CblasTrans, n, r, 1.0, c->MWm, r, Yb, 1, 0.0, cp, 1);
            double o2 = 0;
            for (int k = 0; k < r; k++)
                o2 += cp[k] * cp[k];
            o2 /= a2;
            pen += o2 / B;
            obj += wo * o2 / B;
            /* d/dY_b of wo/B ‖c‖²/a² = 2 wo/(B a²) M W c / m */
            cblas_dgemv(CblasRowMajor, CblasNoTrans, n, r, 2 * wo / (B * a2), c->MWm, r, cp, 1, 1.0,
                        c->dY + (size_t)b * n, 1);
        }
    }
    if (t) {
        t->objective = obj;
        t->energy = Em;
        t->penalty = pen;
        t->tangent = tan;
    }
    if (!isfinite(obj))
        return crom_err(CROM_EDATA, "the data-free objective is not finite");
    if (grad) {
        /* through the anchor: dL/dN(z_b) = dY_b, dL/dN(0) = −Σ_b dY_b */
        float *d0 = c->dyf + (size_t)(B + B0) * n;
        memset(d0, 0, sizeof(float) * (size_t)n);
        for (int b = 0; b < B + B0; b++)
            for (int i = 0; i < n; i++) {
                double v = fixed && fixed[i] ? 0.0 : c->dY[(size_t)b * n + i];
                c->dyf[(size_t)b * n + i] = (float)v;
                d0[i] -= (float)v;
            }
        memset(grad, 0, sizeof(float) * c->net->nparams);
        rc = crom_nn_mlp_backward(c->net, &c->ws, rows, c->dyf, grad, NULL);
    }
    return rc;
}

/* ============================================================ training */

void crom_datafree_log_free(crom_datafree_log *l)
{
    if (!l)
        return;
    free(l->objective);
    free(l->energy);
    free(l->penalty);
    free(l->seconds);
    memset(l, 0, sizeof *l);
}

int crom_datafree_run_begin(crom_datafree_run *R, crom_datafree_log *log, const crom_datafree_opts *o)
{
    memset(R, 0, sizeof *R);
    R->log = log;
    R->o = o;
    R->block = o->steps >= 100 ? (o->steps + 99) / 100 : 1;
    int maxblocks = o->steps / R->block + 2;
    log->objective = crom_malloc(sizeof(double) * (size_t)maxblocks);
    log->energy = crom_malloc(sizeof(double) * (size_t)maxblocks);
    log->penalty = crom_malloc(sizeof(double) * (size_t)maxblocks);
    log->seconds = crom_malloc(sizeof(double) * (size_t)maxblocks);
    if (!log->objective || !log->energy || !log->penalty || !log->seconds)
        return CROM_EINTERNAL;
    R->budget = o->minutes > 0 ? 60 * o->minutes : 0;
    R->tstart = crom_clock_now();
    return 0;
}

int crom_datafree_run_next(crom_datafree_run *R, long k, double *frac)
{
    double f = (double)k / R->o->steps, el = crom_clock_now() - R->tstart;
    if (R->budget > 0) {
        if (el >= R->budget)
            return 0;
        f = fmax(f, el / R->budget);
    }
    *frac = f;
    return 1;
}

static void close_block(crom_datafree_run *R)
{
    crom_datafree_log *log = R->log;
    int j = log->nblocks++;
    log->objective[j] = R->sobj / R->inblock;
    log->energy[j] = R->sen / R->inblock;
    log->penalty[j] = R->spen / R->inblock;
    log->seconds[j] = crom_clock_wall(crom_clock_now() - R->tstart);
    R->sobj = R->sen = R->spen = 0;
    R->inblock = 0;
}

void crom_datafree_run_record(crom_datafree_run *R, long k, const crom_datafree_terms *t)
{
    const crom_datafree_opts *o = R->o;
    R->sobj += t->objective;
    R->sen += t->energy;
    R->spen += t->penalty;
    if (++R->inblock == R->block || k + 1 == o->steps) {
        close_block(R);
        if (o->progress) {
            double f = (double)(k + 1) / o->steps;
            if (R->budget > 0)
                f = fmax(f, (crom_clock_now() - R->tstart) / R->budget);
            o->progress(o->progress_ctx, k + 1, fmin(f, 1.0), R->log->objective[R->log->nblocks - 1]);
        }
    }
}

int crom_datafree_run_end(crom_datafree_run *R, long k)
{
    if (R->inblock > 0) /* stopped by the clock inside a block */
        close_block(R);
    R->log->steps = k;
    R->log->seconds_total = crom_clock_now() - R->tstart;
    return k > 0 ? 0 : crom_err(CROM_EUSAGE, "no training step fitted in the time budget");
}

double crom_datafree_lr(double base, double frac)
{
    int q = (int)floor(4 * frac);
    if (q > 3)
        q = 3;
    if (q < 0)
        q = 0;
    return base * ldexp(1.0, -q);
}

/* What a training step needs: the loss, the options, the sampler, the
 * parameters and their gradient, the batch z and the random cubature
 * (tets: K of nt, NULL for every tet). */
typedef struct {
    crom_datafree_ctx *ctx;
    const crom_datafree_opts *o;
    crom_rng *rng;
    float *params, *grad;
    double *z;
    int *tets, K, nt, nm;
    double rho;
} tr_ctx;

/* A fresh batch: z ~ N(0, I) (energy) or uniform in the box (neuralmodes),
 * the tets of a fresh random cubature, and ρ at fraction frac. */
static void draw(tr_ctx *T, double frac)
{
    const crom_datafree_opts *o = T->o;
    int r = T->ctx->r;
    T->rho = T->nm ? 1 : o->ramp > 0 ? fmin(1.0, frac / o->ramp) : 1;
    for (int i = 0; i < o->batch * r; i++)
        T->z[i] = T->nm ? T->ctx->half[i % r] * (2 * crom_rng_uniform(T->rng) - 1) : crom_rng_normal(T->rng);
    for (int i = o->batch * r; i < (o->batch + T->ctx->B0) * r; i++) /* small samples: the tangent at rest */
        T->z[i] = o->tangent_radius * crom_rng_normal(T->rng);
    for (int i = 0; T->tets && i < T->K; i++)
        T->tets[i] = (int)crom_rng_below(T->rng, (uint64_t)T->nt);
}

static int loss(tr_ctx *T, crom_datafree_terms *tm, float *grad)
{
    return crom_datafree_loss(T->ctx, T->o->batch, T->z, T->rho, T->K, T->tets, tm, grad);
}

/* Adam on a fresh batch every step, the learning rate halved after each
 * quarter of the schedule. */
static int train_adam(tr_ctx *T, crom_datafree_run *R, crom_nn_adam *adam, long *kout)
{
    long k;
    int rc = 0;
    for (k = 0; k < T->o->steps; k++) {
        double frac;
        if (!crom_datafree_run_next(R, k, &frac))
            break;
        draw(T, frac);
        crom_datafree_terms tm;
        if ((rc = loss(T, &tm, T->grad))) {
            if (rc == CROM_EDATA)
                crom_err_ctx("training diverged at step %ld (try a smaller --lr)", k + 1);
            break;
        }
        crom_nn_adam_step(adam, T->params, T->grad, crom_datafree_lr(T->o->lr, frac));
        crom_datafree_run_record(R, k, &tm);
    }
    *kout = k;
    return rc;
}

/* The loss and gradient (double) at parameters x, through the float
 * network. Returns 0, or CROM_EDATA where it is not finite (an inverted
 * element): the line search then shortens the step. */
static int lbfgs_eval(tr_ctx *T, size_t np, const double *x, double *f, double *g, crom_datafree_terms *tm)
{
    for (size_t i = 0; i < np; i++)
        T->params[i] = (float)x[i];
    int rc = loss(T, tm, T->grad);
    if (rc)
        return rc;
    for (size_t i = 0; i < np; i++)
        g[i] = T->grad[i];
    *f = tm->objective;
    return 0;
}

/* L-BFGS with a backtracking line search (the Neural Modes paper's
 * optimizer), o->resample iterations on each batch of samples and tets
 * before a fresh one is drawn (the objective must stay fixed while the
 * line search compares values); the pairs are kept across batches. The
 * first step (no pair yet) moves no parameter by more than o->lr. */
static int train_lbfgs(tr_ctx *T, crom_datafree_run *R, size_t np, long *kout)
{
    const crom_datafree_opts *o = T->o;
    crom_lbfgs L;
    int rc = crom_lbfgs_init(&L, np, 10);
    double *x = crom_malloc(sizeof(double) * np), *g = crom_malloc(sizeof(double) * np);
    double *xt = crom_malloc(sizeof(double) * np), *gt = crom_malloc(sizeof(double) * np);
    double *d = crom_malloc(sizeof(double) * np);
    long k = 0;
    if (!rc && (!x || !g || !xt || !gt || !d))
        rc = CROM_EINTERNAL;
    for (size_t i = 0; !rc && i < np; i++)
        x[i] = T->params[i];
    int stop = 0;
    while (!rc && !stop && k < o->steps) {
        double frac, f;
        if (!crom_datafree_run_next(R, k, &frac))
            break;
        draw(T, frac);
        crom_datafree_terms tm;
        if ((rc = lbfgs_eval(T, np, x, &f, g, &tm))) {
            if (rc == CROM_EDATA)
                crom_err_ctx("training diverged at step %ld", k + 1);
            break;
        }
        for (int it = 0; it < o->resample && k < o->steps; it++) {
            if (it > 0 && !crom_datafree_run_next(R, k, &frac)) {
                stop = 1;
                break;
            }
            crom_lbfgs_direction(&L, g, d);
            double slope = 0, dmax = 0;
            for (size_t i = 0; i < np; i++) {
                slope += g[i] * d[i];
                dmax = fmax(dmax, fabs(d[i]));
            }
            if (!(slope < 0) || L.k == 0) { /* no descent (or no pair yet): steepest descent of size lr */
                crom_lbfgs_reset(&L);
                double gmax = 0;
                for (size_t i = 0; i < np; i++)
                    gmax = fmax(gmax, fabs(g[i]));
                if (!(gmax > 0))
                    break;
                slope = 0;
                for (size_t i = 0; i < np; i++) {
                    d[i] = -o->lr * g[i] / gmax;
                    slope += g[i] * d[i];
                }
            }
            double alpha = 1, ft = NAN;
            crom_datafree_terms tt;
            int ok = 0;
            for (int ls = 0; ls < 30 && !ok; ls++, alpha *= 0.5) {
                for (size_t i = 0; i < np; i++)
                    xt[i] = x[i] + alpha * d[i];
                int e = lbfgs_eval(T, np, xt, &ft, gt, &tt);
                if (e == CROM_EDATA) {
                    crom_err_clear();
                    continue;
                }
                if (e) {
                    rc = e;
                    break;
                }
                ok = ft <= f + 1e-4 * alpha * slope + 1e-6 * fabs(f);
                if (ok)
                    break;
            }
            if (rc)
                break;
            if (!ok) { /* no decrease along d: start the memory afresh on the next batch */
                crom_lbfgs_reset(&L);
                break;
            }
            for (size_t i = 0; i < np; i++) { /* the pair, then the step */
                d[i] = xt[i] - x[i];
                xt[i] = gt[i] - g[i];
            }
            crom_lbfgs_push(&L, d, xt);
            for (size_t i = 0; i < np; i++)
                x[i] += d[i];
            memcpy(g, gt, sizeof(double) * np);
            f = ft;
            crom_datafree_run_record(R, k, &tt);
            k++;
        }
    }
    for (size_t i = 0; x && i < np; i++) /* the parameters of the last accepted step */
        T->params[i] = (float)x[i];
    crom_lbfgs_free(&L);
    free(x);
    free(g);
    free(xt);
    free(gt);
    free(d);
    *kout = k;
    return rc;
}

int crom_datafree_train(const crom_datafree_problem *p, const crom_datafree_opts *o_in, crom_model *out, crom_datafree_log *log)
{
    crom_model_clear(out);
    memset(log, 0, sizeof *log);
    crom_datafree_opts o = *o_in;
    const crom_mesh *mesh = p->mesh;
    int nv = mesh->nv, n = 3 * nv, nm = o.objective == CROM_DATAFREE_NEURALMODES, r = o.rank, rc = 0;
    double t0 = crom_clock_now();
    if (o.objective == CROM_DATAFREE_FIELD)
        return crom_dffield_train(p, o_in, out, log);
    if (o.objective != CROM_DATAFREE_ENERGY && !nm)
        return crom_err(CROM_EUSAGE, "unknown data-free objective %d", o.objective);
    int nfree = 0;
    for (int i = 0; i < n; i++)
        nfree += !(p->fixed && p->fixed[i]);
    if (r < 1)
        return crom_err(CROM_EUSAGE, "--rank %d must be positive", r);
    if (r > nfree)
        return crom_err(CROM_EUSAGE, "--rank %d: a %d-dimensional latent for a body with only %d free degrees of "
                        "freedom (%d vertices, %d pinned DOFs)", r, r, nfree, nv, n - nfree);
    if (nfree == 0)
        return crom_err(CROM_EUSAGE, "every degree of freedom is pinned");
    double gn = fabs(p->gravity[0]) + fabs(p->gravity[1]) + fabs(p->gravity[2]);
    if (!nm && gn > 0 && nfree == n)
        return crom_err(CROM_EUSAGE, "a free body under gravity has no lowest energy (it falls forever): pin a "
                        "region (--pin) or train with --gravity 0,0,0");
    if (o.steps < 1 || o.batch < 1 || o.depth < 2 || o.width < 1)
        return crom_err(CROM_EUSAGE, "steps, batch, depth and width must be positive (depth >= 2)");
    if (!nm && o.batch < 2)
        return crom_err(CROM_EUSAGE, "--batch %d: the isometry term needs pairs (at least 2 samples)", o.batch);
    double lo[3], hi[3];
    crom_mesh_bbox(mesh, lo, hi);
    double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
    if (!(o.sigma > 0))
        o.sigma = 0.05 * diag;
    if (!(o.box > 0))
        o.box = 0.2 * diag;
    if (!isfinite(o.sigma) || !isfinite(o.lambda) || o.lambda < 0 || !isfinite(o.box) ||
        !isfinite(o.ortho_weight) || o.ortho_weight < 0 ||
        !(o.lr > 0) || !isfinite(o.lr) || !(o.ramp >= 0 && o.ramp <= 1))
        return crom_err(CROM_EUSAGE, "non-finite or negative training weight");
    /* the network r -> width x (depth - 1) -> 3nv */
    int widths[CROM_NN_MAX_LAYERS + 1];
    if (o.depth > CROM_NN_MAX_LAYERS)
        return crom_err(CROM_EUSAGE, "--depth %d: at most %d layers", o.depth, CROM_NN_MAX_LAYERS);
    widths[0] = r;
    for (int l = 1; l < o.depth; l++)
        widths[l] = o.width;
    widths[o.depth] = n;
    crom_nn_spec spec;
    if ((rc = crom_nn_spec_set(&spec, o.depth + 1, widths, o.act)))
        return rc;
    size_t np = crom_nn_spec_nparams(&spec);
    float *params = crom_calloc(np, sizeof(float)), *grad = crom_calloc(np, sizeof(float));
    double *z = crom_malloc(sizeof(double) * (size_t)(o.batch + (o.tangent_samples > 0 ? o.tangent_samples : 0)) * r);
    int nt = mesh->nt, K = o.tets > 0 && o.tets < nt ? o.tets : nt; /* every tet, or a random cubature */
    int *tets = K < nt ? crom_malloc(sizeof(int) * (size_t)K) : NULL;
    crom_nn_mlp net;
    memset(&net, 0, sizeof net);
    crom_datafree_ctx ctx;
    memset(&ctx, 0, sizeof ctx);
    crom_nn_adam adam;
    memset(&adam, 0, sizeof adam);
    crom_datafree_run R;
    int rcr = crom_datafree_run_begin(&R, log, &o);
    if (!params || !grad || !z || rcr || (K < nt && !tets)) {
        rc = CROM_EINTERNAL;
        goto done;
    }
    crom_rng irng, srng;
    crom_rng_seed(&irng, o.seed);
    crom_rng_seed(&srng, o.seed ^ 0x5eed5a3b1e5ULL);
    if ((rc = crom_nn_mlp_init(&net, &spec, params, &irng)))
        goto done;
    {
        /* the last layer: pinned outputs stay exactly 0; neuralmodes starts
         * from the linear modes (y = 0) */
        crom_nn_layer *ly = &net.layer[net.spec.nlayers - 1];
        for (int i = 0; i < n; i++)
            if (nm || (p->fixed && p->fixed[i])) {
                memset(ly->W + (size_t)i * ly->in, 0, sizeof(float) * (size_t)ly->in);
                ly->b[i] = 0;
            }
    }
    if ((rc = crom_datafree_ctx_init(&ctx, p, &o, &net, o.batch)))
        goto done;
    if (o.optimizer != CROM_DATAFREE_LBFGS && (rc = crom_nn_adam_init(&adam, np)))
        goto done;
    log->sigma = o.sigma;
    log->box = o.box;
    log->Eref = ctx.Eref;
    tr_ctx T = {&ctx, &o, &srng, params, grad, z, tets, K, nt, nm, 0};
    long k = 0;
    R.tstart = crom_clock_now(); /* the clock starts after the set-up */
    if (o.optimizer == CROM_DATAFREE_LBFGS)
        rc = train_lbfgs(&T, &R, np, &k);
    else
        rc = train_adam(&T, &R, &adam, &k);
    if (rc)
        goto done;
    if ((rc = crom_datafree_run_end(&R, k)))
        goto done;
    if ((rc = crom_model_from_map(out, nm ? "neuralmodes" : "energy", &net, mesh, nm ? p->modes : NULL)))
        goto done;
    if (nm && p->freq) {
        out->frequencies = crom_malloc(sizeof(double) * (size_t)r);
        if (!out->frequencies) {
            crom_model_free(out);
            rc = CROM_EINTERNAL;
            goto done;
        }
        memcpy(out->frequencies, p->freq, sizeof(double) * (size_t)r);
        crom_model_id(out, out->model_id);
    }
    out->training_seconds = crom_clock_wall(crom_clock_now() - t0);
done:
    crom_nn_adam_free(&adam);
    crom_datafree_ctx_free(&ctx);
    crom_nn_mlp_free(&net);
    free(params);
    free(grad);
    free(z);
    free(tets);
    if (rc)
        crom_datafree_log_free(log);
    return rc;
}

/* ============================================================ record */

int crom_datafree_write_record(hid_t loc, const crom_datafree_opts *o, const crom_datafree_problem *p,
                         const crom_datafree_log *log, double mass, const char *modes_id)
{
    int rc = crom_h5_set_f64(loc, ".", "mass", &mass, 1);
    long long steps = log->steps;
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "training_steps", steps);
    if (o->objective == CROM_DATAFREE_ENERGY || o->objective == CROM_DATAFREE_FIELD) {
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "sigma", &log->sigma, 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "isometry_weight", &o->lambda, 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "gravity", p->gravity, 3);
        if (!rc && o->objective == CROM_DATAFREE_FIELD) {
            long long k = o->tets;
            rc = crom_h5_set_i64(loc, ".", "cubature_tets", k);

        }
    } else {
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "latent_box", &log->box, 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "ortho_weight", &o->ortho_weight, 1);
        if (!rc && modes_id)
            rc = crom_h5_set_str(loc, ".", "modes_id", modes_id);
    }
    hsize_t d = (hsize_t)log->nblocks;
    if (!rc && d > 0) {
        rc = crom_h5_put_f64(loc, "training/objective", 1, &d, log->objective);
        if (!rc)
            rc = crom_h5_put_f64(loc, "training/energy", 1, &d, log->energy);
        if (!rc)
            rc = crom_h5_put_f64(loc, "training/penalty", 1, &d, log->penalty);
        if (!rc)
            rc = crom_h5_put_f64(loc, "training/seconds", 1, &d, log->seconds);
    }
    return rc;
}
