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
#include "base/rng.h"
#include "datafree/datafree.h"
#include "io/io.h"

void crom_df_defaults(crom_df_opts *o, int objective)
{
    memset(o, 0, sizeof *o);
    o->objective = objective;
    o->rank = objective == CROM_DF_ENERGY ? 8 : 0;
    o->depth = 6;
    o->width = 64;
    o->act = objective == CROM_DF_ENERGY ? CROM_NN_ELU : CROM_NN_GELU;
    o->steps = 2000;
    o->lr = 1e-3;
    o->batch = 32;
    o->lambda = 1;
    o->ramp = 0.5;
    o->ortho_weight = 1e4;
    o->origin_weight = 1e4;
    o->features = 32;
    o->field_depth = 4;
    o->field_width = 64;
    o->tets = 512;
    o->pin_length = 0;
    if (objective == CROM_DF_FIELD) {
        o->rank = 8;
        o->depth = 4;
        o->act = CROM_NN_ELU;
    }
    o->threads = 1;
    o->seed = 1;
}

/* ============================================================ the loss */

void crom_df_ctx_free(crom_df_ctx *c)
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
    memset(c, 0, sizeof *c);
}

int crom_df_ctx_init(crom_df_ctx *c, const crom_df_problem *p, const crom_df_opts *o,
                     const crom_nn_mlp *net, int maxbatch)
{
    memset(c, 0, sizeof *c);
    c->P = *p;
    c->o = *o;
    c->net = net;
    const crom_nn_spec *sp = &net->spec;
    int r = sp->width[0], n = 3 * p->mesh->nv, nm = o->objective == CROM_DF_NEURALMODES;
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
    c->nthreads = o->threads < 1 ? 1 : o->threads > 256 ? 256 : o->threads;
    int rc = crom_fem_init(&c->fem, p->mesh, &p->mat);
    if (!rc)
        rc = crom_nn_ws_init(&c->ws, net, maxbatch + 1, 1);
    if (rc) {
        crom_df_ctx_free(c);
        return rc;
    }
    size_t rows = (size_t)maxbatch + 1;
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
    c->cb = crom_malloc(sizeof(double) * (size_t)r);
    if (!c->cb || !c->mw || (nm && !c->MWm) || !c->Y || !c->G || !c->dY || !c->E || !c->xb || !c->zf || !c->dyf || !c->bad) {
        crom_df_ctx_free(c);
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
        double fmax = 0;
        for (int k = 0; p->freq && k < r; k++)
            fmax = fmax > p->freq[k] ? fmax : p->freq[k];
        double w = 2 * M_PI * fmax;
        c->Eref = 0.5 * c->mass * w * w * o->box * o->box;
        if (!(c->Eref > 0) || !isfinite(c->Eref))
            c->Eref = EV;
    }
    return 0;
}

int crom_df_loss(crom_df_ctx *c, int B, const double *z, double rho, crom_df_terms *t, float *grad)
{
    int r = c->r, n = c->n, nm = c->o.objective == CROM_DF_NEURALMODES, rows = B + nm;
    const unsigned char *fixed = c->P.fixed;
    const double *X = c->P.mesh->X;
    if (B < 1 || B > c->maxbatch)
        return crom_err(CROM_EUSAGE, "batch of %d samples (at most %d)", B, c->maxbatch);
    if (!nm)
        rho = rho < 0 ? 0 : rho > 1 ? 1 : rho;
    else
        rho = 1;
    for (int b = 0; b < B; b++)
        for (int k = 0; k < r; k++)
            c->zf[(size_t)b * r + k] = (float)z[(size_t)b * r + k];
    if (nm)
        memset(c->zf + (size_t)B * r, 0, sizeof(float) * (size_t)r);
    int rc = crom_nn_mlp_forward(c->net, &c->ws, rows, c->zf, NULL);
    if (rc)
        return rc;
    const float *Yf = crom_nn_ws_output(&c->ws);
    for (size_t i = 0; i < (size_t)rows * n; i++)
        c->Y[i] = Yf[i];
    if (fixed) /* pinned outputs do not exist: the mask is part of the map */
        for (int b = 0; b < rows; b++)
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
        c->bad[b] = crom_fem_assemble(&c->fem, x, &fo, &Eb, G, NULL);
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
    double obj = 0, Em = 0, pen = 0, org = 0;
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
        /* isometry: λ mean_{b<c} ℓ², ℓ = ½ log D² − log(σ |z_b − z_c|) */
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
    if (nm) {
        /* M-orthogonality of y to the modes, and y(0) = 0 */
        double a2 = c->o.box * c->o.box, wo = c->o.ortho_weight, w0 = c->o.origin_weight;
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
        const double *Y0 = c->Y + (size_t)B * n;
        double *dY0 = c->dY + (size_t)B * n;
        for (int i = 0; i < n; i++) {
            org += c->mw[i] * Y0[i] * Y0[i] / a2;
            dY0[i] = 2 * w0 * c->mw[i] * Y0[i] / a2;
        }
        obj += w0 * org;
    }
    if (t) {
        t->objective = obj;
        t->energy = Em;
        t->penalty = pen;
        t->origin = org;
    }
    if (!isfinite(obj))
        return crom_err(CROM_EDATA, "the data-free objective is not finite");
    if (grad) {
        for (size_t i = 0; i < (size_t)rows * n; i++)
            c->dyf[i] = fixed && fixed[i % n] ? 0.0f : (float)c->dY[i];
        memset(grad, 0, sizeof(float) * c->net->nparams);
        rc = crom_nn_mlp_backward(c->net, &c->ws, rows, c->dyf, grad, NULL);
    }
    return rc;
}

/* ============================================================ training */

void crom_df_log_free(crom_df_log *l)
{
    if (!l)
        return;
    free(l->objective);
    free(l->energy);
    free(l->penalty);
    free(l->seconds);
    memset(l, 0, sizeof *l);
}

int crom_df_run_begin(crom_df_run *R, crom_df_log *log, const crom_df_opts *o)
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
    R->tstart = crom_now();
    return 0;
}

int crom_df_run_next(crom_df_run *R, long k, double *frac)
{
    double f = (double)k / R->o->steps, el = crom_now() - R->tstart;
    if (R->budget > 0) {
        if (el >= R->budget)
            return 0;
        f = fmax(f, el / R->budget);
    }
    *frac = f;
    return 1;
}

static void close_block(crom_df_run *R)
{
    crom_df_log *log = R->log;
    int j = log->nblocks++;
    log->objective[j] = R->sobj / R->inblock;
    log->energy[j] = R->sen / R->inblock;
    log->penalty[j] = R->spen / R->inblock;
    log->seconds[j] = crom_wall(crom_now() - R->tstart);
    R->sobj = R->sen = R->spen = 0;
    R->inblock = 0;
}

void crom_df_run_record(crom_df_run *R, long k, const crom_df_terms *t)
{
    const crom_df_opts *o = R->o;
    R->sobj += t->objective;
    R->sen += t->energy;
    R->spen += t->penalty;
    if (++R->inblock == R->block || k + 1 == o->steps) {
        close_block(R);
        if (o->progress) {
            double f = (double)(k + 1) / o->steps;
            if (R->budget > 0)
                f = fmax(f, (crom_now() - R->tstart) / R->budget);
            o->progress(o->progress_ctx, k + 1, fmin(f, 1.0), R->log->objective[R->log->nblocks - 1]);
        }
    }
}

int crom_df_run_end(crom_df_run *R, long k)
{
    if (R->inblock > 0) /* stopped by the clock inside a block */
        close_block(R);
    R->log->steps = k;
    R->log->seconds_total = crom_now() - R->tstart;
    return k > 0 ? 0 : crom_err(CROM_EUSAGE, "no training step fitted in the time budget");
}

double crom_df_lr(double base, double frac)
{
    int q = (int)floor(4 * frac);
    if (q > 3)
        q = 3;
    if (q < 0)
        q = 0;
    return base * ldexp(1.0, -q);
}

int crom_df_train(const crom_df_problem *p, const crom_df_opts *o_in, crom_model *out, crom_df_log *log)
{
    crom_model_clear(out);
    memset(log, 0, sizeof *log);
    crom_df_opts o = *o_in;
    const crom_mesh *mesh = p->mesh;
    int nv = mesh->nv, n = 3 * nv, nm = o.objective == CROM_DF_NEURALMODES, r = o.rank, rc = 0;
    double t0 = crom_now();
    if (o.objective == CROM_DF_FIELD)
        return crom_df_train_field(p, o_in, out, log);
    if (o.objective != CROM_DF_ENERGY && !nm)
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
        o.box = 0.1 * diag;
    if (!isfinite(o.sigma) || !isfinite(o.lambda) || o.lambda < 0 || !isfinite(o.box) ||
        !isfinite(o.ortho_weight) || o.ortho_weight < 0 || !isfinite(o.origin_weight) || o.origin_weight < 0 ||
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
    double *z = crom_malloc(sizeof(double) * (size_t)o.batch * r);
    crom_nn_mlp net;
    memset(&net, 0, sizeof net);
    crom_df_ctx ctx;
    memset(&ctx, 0, sizeof ctx);
    crom_nn_adam adam;
    memset(&adam, 0, sizeof adam);
    crom_df_run R;
    int rcr = crom_df_run_begin(&R, log, &o);
    if (!params || !grad || !z || rcr) {
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
    if ((rc = crom_df_ctx_init(&ctx, p, &o, &net, o.batch)))
        goto done;
    if ((rc = crom_nn_adam_init(&adam, np)))
        goto done;
    log->sigma = o.sigma;
    log->box = o.box;
    log->Eref = ctx.Eref;
    long k;
    R.tstart = crom_now(); /* the clock starts after the set-up */
    for (k = 0; k < o.steps; k++) {
        double frac;
        if (!crom_df_run_next(&R, k, &frac))
            break;
        double rho = nm ? 1 : o.ramp > 0 ? fmin(1.0, frac / o.ramp) : 1;
        for (int i = 0; i < o.batch * r; i++)
            z[i] = nm ? o.box * (2 * crom_rng_uniform(&srng) - 1) : crom_rng_normal(&srng);
        crom_df_terms tm;
        if ((rc = crom_df_loss(&ctx, o.batch, z, rho, &tm, grad))) {
            if (rc == CROM_EDATA)
                crom_err_ctx("training diverged at step %ld (try a smaller --lr)", k + 1);
            goto done;
        }
        crom_nn_adam_step(&adam, params, grad, crom_df_lr(o.lr, frac));
        crom_df_run_record(&R, k, &tm);
    }
    if ((rc = crom_df_run_end(&R, k)))
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
    out->training_seconds = crom_wall(crom_now() - t0);
done:
    crom_nn_adam_free(&adam);
    crom_df_ctx_free(&ctx);
    crom_nn_mlp_free(&net);
    free(params);
    free(grad);
    free(z);
    if (rc)
        crom_df_log_free(log);
    return rc;
}

/* ============================================================ record */

int crom_df_write_record(hid_t loc, const crom_df_opts *o, const crom_df_problem *p,
                         const crom_df_log *log, double mass, const char *modes_id)
{
    int rc = crom_h5_set_f64(loc, ".", "mass", &mass, 1);
    long long steps = log->steps;
    if (!rc)
        rc = crom_h5_set_i64(loc, ".", "training_steps", steps);
    if (o->objective == CROM_DF_ENERGY || o->objective == CROM_DF_FIELD) {
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "sigma", &log->sigma, 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "isometry_weight", &o->lambda, 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "gravity", p->gravity, 3);
        if (!rc && o->objective == CROM_DF_FIELD) {
            long long k = o->tets;
            rc = crom_h5_set_i64(loc, ".", "cubature_tets", k);

        }
    } else {
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "latent_box", &log->box, 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "ortho_weight", &o->ortho_weight, 1);
        if (!rc)
            rc = crom_h5_set_f64(loc, ".", "origin_weight", &o->origin_weight, 1);
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
