/* fit.c — training a displacement basis from point samples (see fit.h). */
#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/err.h"
#include "io/io.h"
#include "mesh/locate.h"
#include "rom/fit.h"

#define KCHUNK 128 /* rows per block when summing masked normal matrices */

/* ============================================================ the losses */

void crom_fit_ctx_free(crom_fit_ctx *c)
{
    if (!c)
        return;
    crom_nn_ws_free(&c->ws);
    crom_nn_pointnet_ws_free(&c->pws);
    free(c->Wd);
    free(c->dW);
    free(c->R);
    free(c->K);
    free(c->G);
    free(c->Bm);
    free(c->Q);
    free(c->qn);
    free(c->cvec);
    free(c->lam);
    free(c->dy);
    free(c->qf);
    free(c->dqf);
    free(c->Xin);
    memset(c, 0, sizeof *c);
}

int crom_fit_ctx_init(crom_fit_ctx *c, const crom_nn_mlp *W, const crom_nn_pointnet *P,
                      int maxrows, int maxframes, int maxcells, int enc_points,
                      double tikhonov, int nthreads)
{
    memset(c, 0, sizeof *c);
    int out = W->spec.width[W->spec.nlayers];
    if (W->spec.width[0] < 3 || out < 3 || out % 3)
        return crom_err(CROM_EUSAGE, "the field must map 3 inputs (and its cut features) to 3r outputs");
    if (maxrows < 1 || maxframes < 1 || maxcells < 1 || (P && enc_points < 1))
        return crom_err(CROM_EUSAGE, "loss buffers of %d rows, %d frames, %d cells are invalid",
                        maxrows, maxframes, maxcells);
    int r = out / 3;
    if (P && P->head.spec.width[P->head.spec.nlayers] != r)
        return crom_err(CROM_EUSAGE, "the encoder outputs %d latents, the field has rank %d",
                        P->head.spec.width[P->head.spec.nlayers], r);
    c->rank = r;
    c->tikhonov = tikhonov;
    c->W = W;
    c->P = P;
    c->nW = W->nparams;
    c->maxrows = maxrows;
    c->maxframes = maxframes;
    c->maxcells = maxcells;
    c->enc_points = enc_points;
    int rc = crom_nn_ws_init(&c->ws, W, maxrows, nthreads);
    if (!rc && P)
        rc = crom_nn_pointnet_ws_init(&c->pws, P, maxframes, enc_points, nthreads);
    if (rc) {
        crom_fit_ctx_free(c);
        return rc;
    }
    size_t rr = (size_t)r * r, m3 = 3 * (size_t)maxrows;
    c->Wd = crom_malloc(sizeof(double) * m3 * r);
    c->dW = crom_malloc(sizeof(double) * m3 * r);
    c->R = crom_malloc(sizeof(double) * 3 * (size_t)maxcells);
    c->K = crom_malloc(sizeof(double) * KCHUNK * rr);
    c->G = crom_malloc(sizeof(double) * (size_t)maxframes * rr);
    c->Bm = crom_malloc(sizeof(double) * (size_t)maxframes * r);
    c->Q = crom_malloc(sizeof(double) * (size_t)maxframes * r);
    c->qn = crom_malloc(sizeof(double) * (size_t)maxframes);
    c->lam = crom_malloc(sizeof(double) * (size_t)maxframes);
    c->cvec = crom_malloc(sizeof(double) * (size_t)maxrows);
    c->dy = crom_malloc(sizeof(float) * m3 * r);
    c->qf = crom_malloc(sizeof(float) * (size_t)maxframes * r);
    c->dqf = crom_malloc(sizeof(float) * (size_t)maxframes * r);
    if (!c->Wd || !c->dW || !c->R || !c->K || !c->G || !c->Bm || !c->Q || !c->qn || !c->lam ||
        !c->cvec || !c->dy || !c->qf || !c->dqf) {
        crom_fit_ctx_free(c);
        return CROM_EINTERNAL;
    }
    return 0;
}

int crom_fit_ctx_set_cut(crom_fit_ctx *c, const crom_cutfeat *cut)
{
    int K = cut ? cut->nseg : 0;
    if (c->W->spec.width[0] != 3 + K)
        return crom_err(CROM_EUSAGE, "the field takes %d inputs, a cut of %d segments needs %d", c->W->spec.width[0],
                        K, 3 + K);
    free(c->Xin);
    c->Xin = NULL;
    c->cut = K ? cut : NULL;
    if (K && !(c->Xin = crom_malloc(sizeof(float) * (size_t)(3 + K) * (size_t)c->maxrows)))
        return CROM_EINTERNAL;
    return 0;
}

/* Solve (A + lam I) x = b in place for nrhs right-hand sides b [nrhs][r]
 * (A symmetric r x r, overwritten). Returns 0, or -1 if A + lam I is not
 * positive definite. */
static int spd_solve(double *A, int r, double lam, double *b, int nrhs)
{
    for (int a = 0; a < r; a++)
        A[a * r + a] += lam;
    if (LAPACKE_dpotrf_work(LAPACK_COL_MAJOR, 'L', r, A, r) != 0)
        return -1;
    if (LAPACKE_dpotrs_work(LAPACK_COL_MAJOR, 'L', r, nrhs, A, r, b, r) != 0)
        return -1;
    return 0;
}

static double trace(const double *A, int r)
{
    double t = 0;
    for (int a = 0; a < r; a++)
        t += A[a * r + a];
    return t;
}

/* q for every frame of one group by regularized least squares: Q [B][r]
 * (input: nothing; output: q), lam [B]. Wd [3P][r], U [3P][B], M [P][B]. */
static void lsq_group(crom_fit_ctx *c, const double *Wd, int Pg, int Bg, const double *U,
                      const double *M, int dense, double *Q, double *lam)
{
    int r = c->rank, m3 = 3 * Pg;
    size_t rr = (size_t)r * r;
    /* right-hand sides: Q = U^T Wd, [B][r] */
    cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, Bg, r, m3, 1.0, U, Bg, Wd, r, 0.0, Q, r);
    if (dense) {
        double *G = c->G;
        cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, m3, 1.0, Wd, r, 0.0, G, r);
        for (int a = 0; a < r; a++)
            for (int b = 0; b < a; b++)
                G[a * r + b] = G[b * r + a];
        double tr = trace(G, r), l = c->tikhonov * tr / r;
        memcpy(c->K, G, sizeof(double) * rr);
        int ok = tr > 0 && spd_solve(G, r, l, Q, Bg) == 0;
        if (!ok && tr > 0) { /* numerically singular: regularize a little more */
            l = fmax(l, 1e-9 * tr / r);
            memcpy(G, c->K, sizeof(double) * rr);
            cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, Bg, r, m3, 1.0, U, Bg, Wd, r, 0.0, Q, r);
            ok = spd_solve(G, r, l, Q, Bg) == 0;
        }
        if (!ok) {
            memset(Q, 0, sizeof(double) * (size_t)Bg * r);
            l = 0;
        }
        for (int j = 0; j < Bg; j++)
            lam[j] = l;
        return;
    }
    /* masked: G_f = sum_i m_fi K_i with K_i = W_i^T W_i, in row blocks */
    double *G = c->G;
    memset(G, 0, sizeof(double) * (size_t)Bg * rr);
    for (int i0 = 0; i0 < Pg; i0 += KCHUNK) {
        int nc = Pg - i0 < KCHUNK ? Pg - i0 : KCHUNK;
        for (int i = 0; i < nc; i++) {
            double *K = c->K + (size_t)i * rr;
            const double *w = Wd + (size_t)(i0 + i) * 3 * r;
            for (int a = 0; a < r; a++)
                for (int b = a; b < r; b++) {
                    double s = w[a] * w[b] + w[r + a] * w[r + b] + w[2 * r + a] * w[2 * r + b];
                    K[a * r + b] = s;
                    K[b * r + a] = s;
                }
        }
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, Bg, (int)rr, nc, 1.0,
                    M + (size_t)i0 * Bg, Bg, c->K, (int)rr, 1.0, G, (int)rr);
    }
    for (int j = 0; j < Bg; j++) {
        double *A = G + (size_t)j * rr, *q = Q + (size_t)j * r;
        double tr = trace(A, r), l = c->tikhonov * tr / r;
        memcpy(c->K, A, sizeof(double) * rr);
        memcpy(c->K + rr, q, sizeof(double) * r);
        int ok = tr > 0 && spd_solve(A, r, l, q, 1) == 0;
        if (!ok && tr > 0) {
            l = fmax(l, 1e-9 * tr / r);
            memcpy(A, c->K, sizeof(double) * rr);
            memcpy(q, c->K + rr, sizeof(double) * r);
            ok = spd_solve(A, r, l, q, 1) == 0;
        }
        if (!ok) {
            memset(q, 0, sizeof(double) * r);
            l = 0;
        }
        lam[j] = l;
    }
}

/* The weight of a batch's samples: every cell of a dense group, the sum
 * of the mask in the others. */
static double batch_weight(const crom_fit_batch *b)
{
    double n = 0;
    size_t cell = 0;
    for (int g = 0; g < b->ngroups; g++) {
        size_t k = (size_t)b->rows[g] * b->frames[g];
        if (b->dense[g])
            n += (double)k;
        else
            for (size_t i = 0; i < k; i++)
                n += b->M[cell + i];
        cell += k;
    }
    return n;
}

/* One group of a batch: Pg points in Bg frames, from row row0, sample
 * cell0 and frame fr0 of the batch on. */
typedef struct {
    int Pg, Bg, dense, fr0;
    size_t row0, cell0;
} loss_group;

/* The group's fields W (from the network output Y) into c->Wd, its
 * latents into c->Q (the lsq fit of W to its samples, or the encoder's;
 * also into qout when given), its masked residual R = W Q^T - U into c->R
 * and |q_f|^2 into c->qn; adds |R|^2 to *mis and the lsq fits' Tikhonov
 * terms to *reg. */
static void group_residual(crom_fit_ctx *c, const crom_fit_batch *b, const loss_group *gr, const float *Y,
                           double *qout, double *mis, double *reg)
{
    int r = c->rank, Pg = gr->Pg, Bg = gr->Bg, m3 = 3 * Pg, dense = gr->dense;
    const double *U = b->U + 3 * gr->cell0, *M = b->M + gr->cell0;
    double *Wd = c->Wd, *Q = c->Q, *R = c->R;
    const float *Yg = Y + gr->row0 * 3 * r;
    for (size_t i = 0; i < (size_t)m3 * r; i++)
        Wd[i] = Yg[i];
    if (!c->P) {
        lsq_group(c, Wd, Pg, Bg, U, M, dense, Q, c->lam);
    } else {
        for (int j = 0; j < Bg; j++)
            for (int k = 0; k < r; k++)
                Q[j * r + k] = c->qf[(size_t)(gr->fr0 + j) * r + k];
    }
    /* residual R = Wd Q^T - U, masked */
    memcpy(R, U, sizeof(double) * (size_t)m3 * Bg);
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasTrans, m3, Bg, r, 1.0, Wd, r, Q, r, -1.0, R, Bg);
    if (!dense)
        for (int i = 0; i < Pg; i++)
            for (int cc = 0; cc < 3; cc++) {
                double *Ri = R + (size_t)(3 * i + cc) * Bg;
                const double *Mi = M + (size_t)i * Bg;
                for (int j = 0; j < Bg; j++)
                    Ri[j] *= Mi[j];
            }
    for (size_t i = 0; i < (size_t)m3 * Bg; i++)
        *mis += R[i] * R[i];
    for (int j = 0; j < Bg; j++) {
        double s = 0;
        for (int k = 0; k < r; k++)
            s += Q[j * r + k] * Q[j * r + k];
        c->qn[j] = s;
        if (!c->P)
            *reg += c->lam[j] * s;
    }
    if (qout)
        memcpy(qout + (size_t)gr->fr0 * r, Q, sizeof(double) * (size_t)Bg * r);
}

/* The group's part of the loss gradient (scale = 2/n), from what
 * group_residual left in c: d/dW at its rows into c->dy (as float), and
 * with an encoder d/dq of its frames into c->dqf. */
static void group_gradient(crom_fit_ctx *c, const crom_fit_batch *b, const loss_group *gr, double scale)
{
    int r = c->rank, Pg = gr->Pg, Bg = gr->Bg, m3 = 3 * Pg;
    const double *M = b->M + gr->cell0, *Wd = c->Wd, *Q = c->Q, *R = c->R;
    double *dW = c->dW;
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, m3, r, Bg, scale, R, Bg, Q, r, 0.0, dW, r);
    if (!c->P && c->tikhonov > 0) {
        /* d/dW_i of sum_f lambda_f |q_f|^2 / n, lambda_f = tik tr(G_f) / r */
        if (gr->dense) {
            double s = 0;
            for (int j = 0; j < Bg; j++)
                s += c->lam[j] > 0 ? c->qn[j] : 0;
            for (int i = 0; i < Pg; i++)
                c->cvec[i] = s;
        } else {
            for (int j = 0; j < Bg; j++)
                if (!(c->lam[j] > 0))
                    c->qn[j] = 0;
            cblas_dgemv(CblasRowMajor, CblasNoTrans, Pg, Bg, 1.0, M, Bg, c->qn, 1, 0.0, c->cvec, 1);
        }
        double coef = scale * c->tikhonov / r;
        for (int i = 0; i < Pg; i++) {
            double ci = coef * c->cvec[i];
            for (int k = 0; k < 3 * r; k++)
                dW[(size_t)i * 3 * r + k] += ci * Wd[(size_t)i * 3 * r + k];
        }
    }
    float *dy = c->dy + gr->row0 * 3 * r;
    for (size_t i = 0; i < (size_t)m3 * r; i++)
        dy[i] = (float)dW[i];
    if (c->P) {
        cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, Bg, r, m3, scale, R, Bg, Wd, r, 0.0, c->Bm, r);
        for (int j = 0; j < Bg; j++)
            for (int k = 0; k < r; k++)
                c->dqf[(size_t)(gr->fr0 + j) * r + k] = (float)c->Bm[j * r + k];
    }
}

int crom_fit_loss(crom_fit_ctx *c, const crom_fit_batch *b, double *objective, double *misfit,
                  float *grad, double *qout)
{
    if (b->nrows > c->maxrows || b->nframes > c->maxframes || b->nrows < 1 || b->nframes < 1)
        return crom_err(CROM_EUSAGE, "batch of %d points and %d frames exceeds the loss buffers",
                        b->nrows, b->nframes);
    size_t cells = 0;
    for (int g = 0; g < b->ngroups; g++)
        cells += (size_t)b->rows[g] * b->frames[g];
    if (cells > (size_t)c->maxcells)
        return crom_err(CROM_EUSAGE, "batch of %zu samples exceeds the loss buffers", cells);
    if (c->W->spec.width[0] != 3 + (c->cut ? c->cut->nseg : 0))
        return crom_err(CROM_EUSAGE, "the field takes %d inputs: set its cut", c->W->spec.width[0]);
    if (c->cut)
        crom_cutfeat_inputs_f(c->cut, (size_t)b->nrows, b->X, b->S, c->Xin);
    int rc = crom_nn_mlp_forward(c->W, &c->ws, b->nrows, c->cut ? c->Xin : b->X, NULL);
    if (rc)
        return rc;
    const float *Y = crom_nn_ws_output(&c->ws);
    if (c->P && (rc = crom_nn_pointnet_forward(c->P, &c->pws, b->nframes, b->enc_points, b->enc,
                                               c->qf)))
        return rc;
    double n = batch_weight(b);
    double mis = 0, reg = 0, scale = n > 0 ? 2.0 / n : 0;
    loss_group gr = {0, 0, 0, 0, 0, 0};
    for (int g = 0; g < b->ngroups; g++) {
        gr.Pg = b->rows[g];
        gr.Bg = b->frames[g];
        gr.dense = b->dense[g];
        group_residual(c, b, &gr, Y, qout, &mis, &reg);
        if (grad && n > 0)
            group_gradient(c, b, &gr, scale);
        gr.row0 += (size_t)gr.Pg;
        gr.cell0 += (size_t)gr.Pg * gr.Bg;
        gr.fr0 += gr.Bg;
    }
    if (objective)
        *objective = n > 0 ? (mis + reg) / n : 0;
    if (misfit)
        *misfit = n > 0 ? mis / n : 0;
    if (grad) {
        memset(grad, 0, sizeof(float) * (c->nW + (c->P ? c->P->nparams : 0)));
        if (n > 0) {
            rc = crom_nn_mlp_backward(c->W, &c->ws, b->nrows, c->dy, grad, NULL);
            if (!rc && c->P)
                rc = crom_nn_pointnet_backward(c->P, &c->pws, b->nframes, b->enc_points, c->dqf,
                                               grad + c->nW, NULL);
        }
    }
    return rc;
}

/* ============================================================ checks */

void crom_fit_defaults(crom_fit_opts *o)
{
    memset(o, 0, sizeof *o);
    o->rank = 20;
    o->encoder = CROM_MODEL_ENC_LSQ;
    o->depth = 5;
    o->width = 60;
    o->act = CROM_NN_ELU;
    o->epochs = 0;
    o->lr = 0;
    o->batch = 16;
    o->points_per_step = 0;
    o->enc_points = 2500;
    o->tikhonov = 1e-6;
    o->threads = 1;
    o->seed = 1;
    o->shards = 1;
    o->nprocs = 1;
}

float *crom_fit_side_points(const crom_samples *S, const crom_cutfeat *cut)
{
    size_t n = (size_t)S->F * S->N;
    float *side = crom_malloc(sizeof(float) * 3 * (n ? n : 1));
    if (!side)
        return NULL;
    memcpy(side, S->X, sizeof(float) * 3 * n);
    for (int k = 0; k < S->nsources; k++) {
        const crom_mesh *m = &S->src[k];
        if (m->nt < 1) /* a shell: no tets, the samples as they are */
            continue;
        crom_locator L;
        if (crom_locate_init(&L, m)) {
            free(side);
            return NULL;
        }
        for (int f = 0; f < S->F; f++) {
            if (S->source[f] != k)
                continue;
            for (int i = 0; i < S->N; i++) {
                size_t j = (size_t)f * S->N + i;
                if (S->vertex[j] >= 0)
                    continue;
                double p[3] = {S->X[3 * j], S->X[3 * j + 1], S->X[3 * j + 2]}, c[3] = {0, 0, 0}, bary[4];
                double fp[CROM_CUTFEAT_MAX], fc[CROM_CUTFEAT_MAX];
                int t;
                crom_locate_point(&L, p, &t, bary, NULL);
                for (int a = 0; a < 4; a++)
                    for (int d = 0; d < 3; d++)
                        c[d] += 0.25 * m->X[3 * m->tets[4 * t + a] + d];
                crom_cutfeat_point(cut, p, fp);
                crom_cutfeat_point(cut, c, fc);
                int across = 0;
                for (int s = 0; s < cut->nseg; s++)
                    across |= fabs(fc[s]) > 0.5 && (fc[s] > 0) != (fp[s] > 0);
                for (int d = 0; across && d < 3; d++)
                    side[3 * j + d] = (float)c[d];
            }
        }
        crom_locate_free(&L);
    }
    return side;
}

int crom_fit_check(const crom_samples *S, int rank)
{
    if (S->F == 0)
        return crom_err(CROM_EDATA, "the sample set has no frames: nothing to learn from");
    if (S->F == 1)
        return crom_err(CROM_EDATA, "the sample set has a single frame: a basis needs at least 2 frames");
    if (S->N < 1)
        return crom_err(CROM_EDATA, "the sample set has no points per frame");
    int nz = crom_samples_nonzero_frames(S);
    if (nz == 0)
        return crom_err(CROM_EDATA, "every displacement in the sample set is zero: nothing to learn");
    if (rank > nz)
        return crom_err(CROM_EDATA,
                        "rank %d exceeds the data's rank: only %d of the %d frames have a non-zero "
                        "displacement (use --rank %d or less)", rank, nz, S->F, nz);
    if (3 * (long)S->N < rank)
        return crom_err(CROM_EDATA, "rank %d exceeds the 3 x %d values of a frame", rank, S->N);
    return 0;
}

/* ============================================================ training */

typedef struct {
    const crom_samples *S;
    crom_fit_opts o;
    int r, shared, P, Pe, B;
    double s;            /* displacement scale (m) */
    float *Xsrc;         /* source vertices as float, concatenated */
    float *side;         /* [F][N][3] where the cut features of each sample are taken, or NULL */
    float *Ssrc;         /* shared mode, a field with cut features: each source vertex's field point
                          * (crom_mesh_field_points; its copies on a crack: their own side), as Xsrc */
    size_t *xoff;        /* [nsources] offset of each source in Xsrc (vertices) */
    int *vsz;            /* [nsources] vertices per step of each source (shared mode) */
    int *sv, *si;        /* [F][N] sample vertices sorted, and their sample indices */
    int *perm;           /* per source permutations of 0..nv-1, concatenated (shared) */
    int *permN, *permE;  /* permutations of 0..N-1 (per-frame points, encoder) */
    int *Vbuf;
    int *order;          /* frames in epoch order */
    int *bstart;         /* [nbatches + 1] batch j is order[bstart[j] .. bstart[j+1]) */
    int *border;         /* [nbatches] the order batches are taken in */
    int nbatches, maxbatches;
    int *srcF, *srcFoff; /* frames grouped by source */
    crom_fit_batch b;
    int maxrows, maxcells;
    crom_rng rng;
} trainer;

static void trainer_free(trainer *t)
{
    free(t->Xsrc);
    free(t->side);
    free(t->Ssrc);
    free(t->b.S);
    free(t->xoff);
    free(t->vsz);
    free(t->sv);
    free(t->si);
    free(t->perm);
    free(t->permN);
    free(t->permE);
    free(t->Vbuf);
    free(t->order);
    free(t->bstart);
    free(t->border);
    free(t->srcF);
    free(t->srcFoff);
    free(t->b.rows);
    free(t->b.frames);
    free(t->b.dense);
    free(t->b.X);
    free(t->b.U);
    free(t->b.M);
    free(t->b.enc);
    free(t->b.frame_id);
}

typedef struct {
    int v, i;
} vpair;

static int cmp_vpair(const void *a, const void *b)
{
    const vpair *x = a, *y = b;
    return (x->v > y->v) - (x->v < y->v);
}

static int cmp_int(const void *a, const void *b)
{
    int x = *(const int *)a, y = *(const int *)b;
    return (x > y) - (x < y);
}

/* k distinct random entries of the permutation p [n] moved to its front. */
static void partial_shuffle(crom_rng *rng, int *p, int n, int k)
{
    for (int i = 0; i < k && i < n; i++) {
        int j = i + (int)crom_rng_below(rng, (uint64_t)(n - i));
        int tmp = p[i];
        p[i] = p[j];
        p[j] = tmp;
    }
}

/* The frames of each source: srcF[srcFoff[k] .. srcFoff[k+1]) in frame
 * order. */
static int group_by_source(trainer *t)
{
    const crom_samples *S = t->S;
    int ns = S->nsources;
    t->srcFoff = crom_calloc((size_t)ns + 1, sizeof(int));
    t->srcF = crom_malloc(sizeof(int) * (size_t)S->F);
    int *fill = crom_calloc((size_t)ns, sizeof(int));
    if (!t->srcFoff || !t->srcF || !fill) {
        free(fill);
        return CROM_EINTERNAL;
    }
    for (int f = 0; f < S->F; f++)
        t->srcFoff[S->source[f] + 1]++;
    for (int k = 0; k < ns; k++)
        t->srcFoff[k + 1] += t->srcFoff[k];
    for (int f = 0; f < S->F; f++) {
        int k = S->source[f];
        t->srcF[t->srcFoff[k] + fill[k]++] = f;
    }
    free(fill);
    return 0;
}

/* Shared mode: each source's vertices as float (Xsrc, xoff) and their
 * permutation, the vertices per step vsz of each source (P scaled by
 * nv / N), every frame's sample vertices sorted (sv, si), and the row
 * buffers sized by the largest vsz. */
static int init_shared(trainer *t)
{
    const crom_samples *S = t->S;
    int ns = S->nsources;
    t->xoff = crom_malloc(sizeof(size_t) * (size_t)ns);
    t->vsz = crom_malloc(sizeof(int) * (size_t)ns);
    if (!t->xoff || !t->vsz)
        return CROM_EINTERNAL;
    size_t tot = 0;
    int maxv = 0;
    for (int k = 0; k < ns; k++) {
        t->xoff[k] = tot;
        tot += (size_t)S->src[k].nv;
    }
    t->Xsrc = crom_malloc(sizeof(float) * 3 * (tot ? tot : 1));
    t->perm = crom_malloc(sizeof(int) * (tot ? tot : 1));
    t->sv = crom_malloc(sizeof(int) * (size_t)S->F * S->N);
    t->si = crom_malloc(sizeof(int) * (size_t)S->F * S->N);
    vpair *tmp = crom_malloc(sizeof(vpair) * (size_t)S->N);
    if (!t->Xsrc || !t->perm || !t->sv || !t->si || !tmp) {
        free(tmp);
        return CROM_EINTERNAL;
    }
    for (int k = 0; k < ns; k++) {
        const crom_mesh *m = &S->src[k];
        for (size_t i = 0; i < 3 * (size_t)m->nv; i++)
            t->Xsrc[3 * t->xoff[k] + i] = (float)m->X[i];
        for (int i = 0; i < m->nv; i++)
            t->perm[t->xoff[k] + i] = i;
        double v = ceil((double)t->P * m->nv / S->N);
        t->vsz[k] = v < m->nv ? (int)v : m->nv;
        if (t->srcFoff[k + 1] > t->srcFoff[k] && t->vsz[k] > maxv)
            maxv = t->vsz[k];
    }
    for (int f = 0; f < S->F; f++) {
        const int *vx = S->vertex + (size_t)f * S->N;
        for (int i = 0; i < S->N; i++)
            tmp[i] = (vpair){vx[i], i};
        qsort(tmp, (size_t)S->N, sizeof *tmp, cmp_vpair);
        for (int i = 0; i < S->N; i++) {
            t->sv[(size_t)f * S->N + i] = tmp[i].v;
            t->si[(size_t)f * S->N + i] = tmp[i].i;
        }
    }
    free(tmp);
    t->Vbuf = crom_malloc(sizeof(int) * (size_t)(maxv ? maxv : 1));
    if (!t->Vbuf)
        return CROM_EINTERNAL;
    t->maxrows = maxv;
    t->maxcells = maxv * t->B;
    return 0;
}

/* Shared mode with cut features: the field point of every source vertex
 * (Ssrc) and the batch's side points: a crack's copies take the features
 * of their own side at their own position. */
static int init_shared_sides(trainer *t)
{
    const crom_samples *S = t->S;
    size_t tot = 0;
    for (int k = 0; k < S->nsources; k++)
        tot += (size_t)S->src[k].nv;
    t->Ssrc = crom_malloc(sizeof(float) * 3 * (tot ? tot : 1));
    t->b.S = crom_malloc(sizeof(float) * 3 * (size_t)(t->maxrows ? t->maxrows : 1));
    if (!t->Ssrc || !t->b.S)
        return CROM_EINTERNAL;
    for (int k = 0; k < S->nsources; k++) {
        const crom_mesh *m = &S->src[k];
        double *fp = crom_mesh_field_points(m, CROM_MESH_CRACK_OFFSET, NULL);
        if (!fp)
            return CROM_EINTERNAL;
        for (size_t i = 0; i < 3 * (size_t)m->nv; i++)
            t->Ssrc[3 * t->xoff[k] + i] = (float)fp[i];
        free(fp);
    }
    return 0;
}

/* The batch buffers (pn: with the encoder's points) and the epoch plan. */
static int alloc_batches(trainer *t, int pn)
{
    const crom_samples *S = t->S;
    crom_fit_batch *b = &t->b;
    int B = t->B, maxgroups = t->shared ? 1 : B;
    b->rows = crom_malloc(sizeof(int) * (size_t)maxgroups);
    b->frames = crom_malloc(sizeof(int) * (size_t)maxgroups);
    b->dense = crom_malloc(sizeof(int) * (size_t)maxgroups);
    b->X = crom_malloc(sizeof(float) * 3 * (size_t)t->maxrows);
    b->U = crom_malloc(sizeof(double) * 3 * (size_t)t->maxcells);
    b->M = crom_malloc(sizeof(double) * (size_t)t->maxcells);
    b->frame_id = crom_malloc(sizeof(int) * (size_t)B);
    if (pn)
        b->enc = crom_malloc(sizeof(float) * 6 * (size_t)B * t->Pe);
    b->enc_points = t->Pe;
    t->order = crom_malloc(sizeof(int) * (size_t)S->F);
    t->maxbatches = S->F + S->nsources + 1;
    t->bstart = crom_malloc(sizeof(int) * ((size_t)t->maxbatches + 1));
    t->border = crom_malloc(sizeof(int) * ((size_t)t->maxbatches + 1));
    if (!b->rows || !b->frames || !b->dense || !b->X || !b->U || !b->M || !b->frame_id ||
        (pn && !b->enc) || !t->order || !t->bstart || !t->border)
        return CROM_EINTERNAL;
    return 0;
}

/* A trainer for S under o: the displacement scale, the frames by source,
 * shared or per-frame points, and the buffers. */
static int trainer_init(trainer *t, const crom_samples *S, const crom_fit_opts *o)
{
    memset(t, 0, sizeof *t);
    t->S = S;
    t->o = *o;
    t->r = o->rank;
    t->B = o->batch < S->F ? o->batch : S->F;
    int pn = o->encoder == CROM_MODEL_ENC_POINTNET;
    int P = o->points_per_step > 0 ? o->points_per_step : pn ? S->N : 128;
    t->P = P < S->N ? P : S->N;
    t->Pe = pn ? (o->enc_points < S->N ? o->enc_points : S->N) : 0;
    crom_rng_seed(&t->rng, o->seed ^ 0x5a3c1e7b9d2f4680ULL);
    /* displacement scale */
    double ss = 0;
    size_t n3 = (size_t)S->F * S->N * 3;
    for (size_t i = 0; i < n3; i++)
        ss += (double)S->U[i] * S->U[i];
    t->s = sqrt(ss / ((double)S->F * S->N));
    if (!(t->s > 0))
        return crom_err(CROM_EDATA, "every displacement in the sample set is zero: nothing to learn");
    int rc = group_by_source(t);
    if (rc)
        return rc;
    /* shared points: vertex samples that cover at least a quarter of each mesh */
    t->shared = 1;
    for (size_t i = 0; i < (size_t)S->F * S->N && t->shared; i++)
        if (S->vertex[i] < 0)
            t->shared = 0;
    for (int k = 0; k < S->nsources && t->shared; k++)
        if (t->srcFoff[k + 1] > t->srcFoff[k] && 4L * S->N < S->src[k].nv)
            t->shared = 0;
    t->permN = crom_malloc(sizeof(int) * (size_t)S->N);
    t->permE = crom_malloc(sizeof(int) * (size_t)S->N);
    if (!t->permN || !t->permE)
        return CROM_EINTERNAL;
    for (int i = 0; i < S->N; i++)
        t->permN[i] = t->permE[i] = i;
    if (t->shared) {
        if ((rc = init_shared(t)))
            return rc;
        if (o->cut && o->cut->nseg && (rc = init_shared_sides(t)))
            return rc;
    } else {
        t->maxrows = t->B * t->P;
        t->maxcells = t->B * t->P;
        if (o->cut && o->cut->nseg) { /* interior samples: their features from their own side */
            t->side = crom_fit_side_points(S, o->cut);
            t->b.S = crom_malloc(sizeof(float) * 3 * (size_t)t->maxrows);
            if (!t->side || !t->b.S)
                return t->side ? CROM_EINTERNAL : crom_errcode();
        }
    }
    return alloc_batches(t, pn);
}

/* The batches of one epoch: frames shuffled (within each source in shared
 * mode, so a batch comes from one mesh), cut into batches of at most B. */
static void plan_epoch(trainer *t)
{
    const crom_samples *S = t->S;
    int B = t->B, nb = 0, pos = 0;
    if (!t->shared) {
        for (int f = 0; f < S->F; f++)
            t->order[f] = f;
        crom_rng_shuffle(&t->rng, t->order, S->F);
        for (int i = 0; i < S->F; i += B)
            t->bstart[nb++] = i;
        t->bstart[nb] = S->F;
        t->nbatches = nb;
        for (int j = 0; j < nb; j++)
            t->border[j] = j;
        return;
    }
    /* per source: shuffle its frames, split into near-equal batches */
    int *starts = t->bstart; /* filled in source order, then shuffled as blocks */
    for (int k = 0; k < S->nsources; k++) {
        int n = t->srcFoff[k + 1] - t->srcFoff[k];
        if (!n)
            continue;
        int *fr = t->order + pos;
        memcpy(fr, t->srcF + t->srcFoff[k], sizeof(int) * (size_t)n);
        crom_rng_shuffle(&t->rng, fr, n);
        int nbk = (n + B - 1) / B;
        for (int j = 0; j < nbk; j++)
            starts[nb++] = pos + (int)((long)n * j / nbk);
        pos += n;
    }
    starts[nb] = pos;
    t->nbatches = nb;
    for (int j = 0; j < nb; j++)
        t->border[j] = j;
    crom_rng_shuffle(&t->rng, t->border, nb);
}

/* Shared mode: t->b from the frames fr[0..nf-1] of source k at its
 * vertices perm[0..v-1] (just drawn). */
static void fill_shared(trainer *t, const int *fr, int nf, int k, const int *perm, int v)
{
    const crom_samples *S = t->S;
    crom_fit_batch *b = &t->b;
    int N = S->N;
    double is = 1.0 / t->s;
    memcpy(t->Vbuf, perm, sizeof(int) * (size_t)v);
    qsort(t->Vbuf, (size_t)v, sizeof(int), cmp_int);
    const float *Xs = t->Xsrc + 3 * t->xoff[k];
    for (int i = 0; i < v; i++)
        memcpy(b->X + 3 * (size_t)i, Xs + 3 * (size_t)t->Vbuf[i], sizeof(float) * 3);
    for (int i = 0; t->Ssrc && i < v; i++)
        memcpy(b->S + 3 * (size_t)i, t->Ssrc + 3 * (t->xoff[k] + (size_t)t->Vbuf[i]), sizeof(float) * 3);
    memset(b->U, 0, sizeof(double) * 3 * (size_t)v * nf);
    memset(b->M, 0, sizeof(double) * (size_t)v * nf);
    size_t present = 0;
    for (int j = 0; j < nf; j++) {
        int f = fr[j];
        const int *sv = t->sv + (size_t)f * N, *si = t->si + (size_t)f * N;
        const float *Uf = S->U + (size_t)f * N * 3;
        int a = 0, c = 0;
        while (a < v && c < N) {
            if (t->Vbuf[a] < sv[c])
                a++;
            else if (t->Vbuf[a] > sv[c])
                c++;
            else {
                const float *u = Uf + 3 * (size_t)si[c];
                for (int d = 0; d < 3; d++)
                    b->U[(size_t)(3 * a + d) * nf + j] = u[d] * is;
                b->M[(size_t)a * nf + j] = 1;
                present++;
                a++;
                c++;
            }
        }
    }
    b->ngroups = 1;
    b->rows[0] = v;
    b->frames[0] = nf;
    b->dense[0] = present == (size_t)v * nf;
    b->nrows = v;
}

/* Draw the points of the frames fr[0..nf-1] (one source in shared mode)
 * and, if fill, fill t->b with them. Without fill only the random draws
 * are made, the same ones in the same order: a process draws the shards
 * it does not evaluate too, so that every process's generator stays in
 * step. */
static void build_batch(trainer *t, const int *fr, int nf, int fill)
{
    const crom_samples *S = t->S;
    crom_fit_batch *b = &t->b;
    int N = S->N;
    double is = 1.0 / t->s;
    if (fill) {
        b->nframes = nf;
        memcpy(b->frame_id, fr, sizeof(int) * (size_t)nf);
    }
    if (t->shared) {
        int k = S->source[fr[0]];
        int nv = S->src[k].nv, v = t->vsz[k];
        int *perm = t->perm + t->xoff[k];
        partial_shuffle(&t->rng, perm, nv, v);
        if (fill)
            fill_shared(t, fr, nf, k, perm, v);
    } else {
        int P = t->P;
        if (fill) {
            b->ngroups = nf;
            b->nrows = nf * P;
        }
        for (int j = 0; j < nf; j++) {
            int f = fr[j];
            partial_shuffle(&t->rng, t->permN, N, P);
            if (!fill)
                continue;
            for (int i = 0; i < P; i++) {
                size_t idx = (size_t)f * N + t->permN[i];
                size_t row = (size_t)j * P + i;
                memcpy(b->X + 3 * row, S->X + 3 * idx, sizeof(float) * 3);
                if (b->S)
                    memcpy(b->S + 3 * row, t->side + 3 * idx, sizeof(float) * 3);
                for (int d = 0; d < 3; d++)
                    b->U[3 * row + d] = S->U[3 * idx + d] * is;
                b->M[row] = 1;
            }
            b->rows[j] = P;
            b->frames[j] = 1;
            b->dense[j] = 1;
        }
    }
    if (b->enc) {
        int Pe = t->Pe;
        for (int j = 0; j < nf; j++) {
            int f = fr[j];
            partial_shuffle(&t->rng, t->permE, N, Pe);
            if (!fill)
                continue;
            float *e = b->enc + (size_t)j * Pe * 6;
            for (int i = 0; i < Pe; i++) {
                size_t idx = (size_t)f * N + t->permE[i];
                for (int d = 0; d < 3; d++) {
                    e[6 * i + d] = S->X[3 * idx + d];
                    e[6 * i + 3 + d] = (float)(S->U[3 * idx + d] * is);
                }
            }
        }
    }
}

/* Fold an r x r map A into the field's last layer: W'(X) = W(X) A. */
static void fold_field(crom_nn_mlp *W, const double *A, int r)
{
    crom_nn_layer *L = &W->layer[W->spec.nlayers - 1];
    int in = L->in;
    double *row = crom_malloc(sizeof(double) * (size_t)r * (in + 1));
    if (!row)
        return;
    for (int c = 0; c < 3; c++) {
        /* rows c*r + k, k < r, hold component c of the fields */
        for (int k = 0; k < r; k++) {
            for (int i = 0; i < in; i++)
                row[(size_t)k * (in + 1) + i] = L->W[(size_t)(c * r + k) * in + i];
            row[(size_t)k * (in + 1) + in] = L->b[c * r + k];
        }
        for (int j = 0; j < r; j++)
            for (int i = 0; i <= in; i++) {
                double s = 0;
                for (int k = 0; k < r; k++)
                    s += row[(size_t)k * (in + 1) + i] * A[k * r + j];
                if (i < in)
                    L->W[(size_t)(c * r + j) * in + i] = (float)s;
                else
                    L->b[c * r + j] = (float)s;
            }
    }
    free(row);
}

/* Fold an r x r map A into the encoder's output: q' = A q. */
static void fold_head(crom_nn_pointnet *P, const double *A, int r)
{
    crom_nn_layer *L = &P->head.layer[P->head.spec.nlayers - 1];
    int in = L->in;
    double *row = crom_malloc(sizeof(double) * (size_t)r * (in + 1));
    if (!row)
        return;
    for (int k = 0; k < r; k++) {
        for (int i = 0; i < in; i++)
            row[(size_t)k * (in + 1) + i] = L->W[(size_t)k * in + i];
        row[(size_t)k * (in + 1) + in] = L->b[k];
    }
    for (int j = 0; j < r; j++)
        for (int i = 0; i <= in; i++) {
            double s = 0;
            for (int k = 0; k < r; k++)
                s += A[j * r + k] * row[(size_t)k * (in + 1) + i];
            if (i < in)
                L->W[(size_t)j * in + i] = (float)s;
            else
                L->b[j] = (float)s;
        }
    free(row);
}

/* Eigen-decomposition of a symmetric r x r matrix: A is replaced by its
 * eigenvectors (column k of the row-major result = eigenvector k) and ev by
 * the eigenvalues, ascending. */
static int sym_eig(double *A, int r, double *ev)
{
    /* row-major symmetric = column-major symmetric; eigenvectors come back as
     * columns in column-major order, i.e. rows of the row-major array */
    if (LAPACKE_dsyev(LAPACK_COL_MAJOR, 'V', 'L', r, A, r, ev) != 0)
        return crom_err(CROM_EINTERNAL, "symmetric eigen-decomposition failed");
    /* transpose so that column k (row-major) is eigenvector k */
    for (int i = 0; i < r; i++)
        for (int j = i + 1; j < r; j++) {
            double tmp = A[i * r + j];
            A[i * r + j] = A[j * r + i];
            A[j * r + i] = tmp;
        }
    return 0;
}

/* Make the field orthonormal over the training points (mean W^T W = I). */
static int orthonormalize(trainer *t, crom_nn_mlp *W, crom_nn_pointnet *P)
{
    const crom_samples *S = t->S;
    int r = t->r;
    size_t rr = (size_t)r * r;
    /* points: the source vertices (vertex samples) or a strided subset of
     * the sample points */
    size_t npts, total = (size_t)S->F * S->N, stride = 1;
    float *pts;
    if (t->shared) {
        npts = 0;
        for (int k = 0; k < S->nsources; k++)
            npts += (size_t)S->src[k].nv;
        pts = t->Xsrc;
    } else {
        stride = total > 200000 ? (total + 199999) / 200000 : 1;
        npts = (total + stride - 1) / stride;
        pts = crom_malloc(sizeof(float) * 3 * npts);
        if (!pts)
            return CROM_EINTERNAL;
        for (size_t i = 0; i < npts; i++)
            memcpy(pts + 3 * i, S->X + 3 * (i * stride), sizeof(float) * 3);
    }
    float *side = NULL; /* the same points' side points (cut features) */
    const float *sides = t->shared ? t->Ssrc : NULL;
    if (!t->shared && t->side && (side = crom_malloc(sizeof(float) * 3 * npts)))
        for (size_t i = 0; i < npts; i++)
            memcpy(side + 3 * i, t->side + 3 * (i * stride), sizeof(float) * 3);
    if (!t->shared && t->side && !side) {
        free(pts);
        return CROM_EINTERNAL;
    }
    crom_nn_ws ws;
    const crom_cutfeat *cut = t->o.cut && t->o.cut->nseg ? t->o.cut : NULL;
    int chunk = 4096, rc = crom_nn_ws_init(&ws, W, chunk, 1);
    float *in = cut ? crom_malloc(sizeof(float) * (size_t)(3 + cut->nseg) * (size_t)chunk) : NULL;
    if (!rc && cut && !in)
        rc = CROM_EINTERNAL;
    double *G = crom_calloc(rr, sizeof(double)), *Wd = crom_malloc(sizeof(double) * 3 * r * chunk);
    double *A = crom_malloc(sizeof(double) * rr), *Ai = crom_malloc(sizeof(double) * rr);
    double *ev = crom_malloc(sizeof(double) * r);
    if (!rc && (!G || !Wd || !A || !Ai || !ev))
        rc = CROM_EINTERNAL;
    for (size_t s0 = 0; !rc && s0 < npts; s0 += (size_t)chunk) {
        int m = (int)(npts - s0 < (size_t)chunk ? npts - s0 : (size_t)chunk);
        if (cut)
            crom_cutfeat_inputs_f(cut, (size_t)m, pts + 3 * s0,
                                  side ? side + 3 * s0 : sides ? sides + 3 * s0 : NULL, in);
        if ((rc = crom_nn_mlp_forward(W, &ws, m, cut ? in : pts + 3 * s0, NULL)))
            break;
        const float *Y = crom_nn_ws_output(&ws);
        for (size_t i = 0; i < (size_t)m * 3 * r; i++)
            Wd[i] = Y[i];
        cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, 3 * m, 1.0 / (double)npts, Wd, r,
                    1.0, G, r);
    }
    if (!rc) {
        for (int a = 0; a < r; a++)
            for (int b = 0; b < a; b++)
                G[a * r + b] = G[b * r + a];
        rc = sym_eig(G, r, ev);
    }
    if (!rc) {
        double emax = ev[r - 1] > 0 ? ev[r - 1] : 1;
        for (int a = 0; a < r; a++)
            for (int b = 0; b < r; b++) {
                double s = 0, si = 0;
                for (int k = 0; k < r; k++) {
                    double e = fmax(ev[k], 1e-12 * emax);
                    s += G[a * r + k] * G[b * r + k] / sqrt(e);
                    si += G[a * r + k] * G[b * r + k] * sqrt(e);
                }
                A[a * r + b] = s;
                Ai[a * r + b] = si;
            }
        fold_field(W, A, r);
        if (P)
            fold_head(P, Ai, r);
    }
    crom_nn_ws_free(&ws);
    free(in);
    free(side);
    free(G);
    free(Wd);
    free(A);
    free(Ai);
    free(ev);
    if (!t->shared)
        free(pts);
    return rc;
}

/* Order the fields by decreasing variance of q over the frames (q [F][r]),
 * a rotation: W' = W U, q' = U^T q. Signs: largest entry of each column
 * of U positive. */
static int rotate_by_variance(const double *q, int F, int r, crom_nn_mlp *W, crom_nn_pointnet *P)
{
    size_t rr = (size_t)r * r;
    double *C = crom_calloc(rr, sizeof(double)), *U = crom_malloc(sizeof(double) * rr);
    double *Ut = crom_malloc(sizeof(double) * rr), *ev = crom_malloc(sizeof(double) * r);
    int rc = !C || !U || !Ut || !ev ? CROM_EINTERNAL : 0;
    if (!rc) {
        cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, F, 1.0, q, r, 0.0, C, r);
        for (int a = 0; a < r; a++)
            for (int b = 0; b < a; b++)
                C[a * r + b] = C[b * r + a];
        rc = sym_eig(C, r, ev);
    }
    if (!rc) {
        /* descending: column j of U = eigenvector r-1-j */
        for (int j = 0; j < r; j++) {
            int k = r - 1 - j, big = 0;
            for (int a = 0; a < r; a++)
                if (fabs(C[a * r + k]) > fabs(C[big * r + k]))
                    big = a;
            double sg = C[big * r + k] < 0 ? -1 : 1;
            for (int a = 0; a < r; a++)
                U[a * r + j] = sg * C[a * r + k];
        }
        for (int a = 0; a < r; a++)
            for (int b = 0; b < r; b++)
                Ut[a * r + b] = U[b * r + a];
        fold_field(W, U, r);
        if (P)
            fold_head(P, Ut, r);
    }
    free(C);
    free(U);
    free(Ut);
    free(ev);
    return rc;
}

/* One training run of crom_fit_mlp: the options with the encoder's
 * defaults resolved, the batches, the networks and their parameters, the
 * loss and the optimizer, and what the run records. */
typedef struct {
    crom_fit_opts o;
    int pn;               /* a PointNet encoder is trained with the field */
    trainer t;
    crom_nn_mlp W;
    crom_nn_pointnet P;
    size_t nW, nP;        /* parameters of W and of P */
    float *params, *grad; /* [nW + nP] */
    double *acc;          /* [nW + nP + CROM_FIT_EXTRAS] a step's sums: what the allreduce carries */
    crom_fit_ctx ctx;
    crom_nn_adam adam;
    double *loss, *secs;  /* [o.epochs] per epoch: mean misfit (m²), wall time */
    int epochs_done;
    crom_fit_stats st;
} fitrun;

static void fitrun_free(fitrun *R)
{
    free(R->loss);
    free(R->secs);
    crom_nn_adam_free(&R->adam);
    crom_fit_ctx_free(&R->ctx);
    crom_nn_pointnet_free(&R->P);
    crom_nn_mlp_free(&R->W);
    free(R->params);
    free(R->grad);
    free(R->acc);
    trainer_free(&R->t);
}

/* The networks, initialized from o.seed: W: 3 -> width x (depth-1) -> 3r;
 * P: 6 -> 64 -> 128 -> 256, 256 -> 128 -> 64 -> r. */
static int make_networks(fitrun *R)
{
    const crom_fit_opts *o = &R->o;
    crom_nn_spec ws_, ps, hs;
    int widths[CROM_NN_MAX_LAYERS + 1], rc;
    widths[0] = 3 + (o->cut ? o->cut->nseg : 0);
    for (int l = 1; l < o->depth; l++)
        widths[l] = o->width;
    widths[o->depth] = 3 * o->rank;
    if ((rc = crom_nn_spec_set(&ws_, o->depth + 1, widths, o->act)))
        return rc;
    static const int pw[] = {6, 64, 128, 256};
    int hw[] = {256, 128, 64, o->rank};
    R->nW = crom_nn_spec_nparams(&ws_);
    R->nP = 0;
    if (R->pn) {
        if ((rc = crom_nn_pointnet_spec(&ps, &hs, 4, pw, 4, hw)))
            return rc;
        R->nP = crom_nn_pointnet_nparams(&ps, &hs);
    }
    R->params = crom_calloc(R->nW + R->nP, sizeof(float));
    R->grad = crom_calloc(R->nW + R->nP, sizeof(float));
    if (!R->params || !R->grad)
        return CROM_EINTERNAL;
    crom_rng irng;
    crom_rng_seed(&irng, o->seed);
    if ((rc = crom_nn_mlp_init(&R->W, &ws_, R->params, &irng)))
        return rc;
    if (R->pn && (rc = crom_nn_pointnet_init(&R->P, &ps, &hs, R->params + R->nW, &irng)))
        return rc;
    return 0;
}

/* Input normalization: the bounding box of every sample point (and of
 * the scaled u for P), given to crom_nn_norm_fit as its two corners. */
static int set_input_norm(fitrun *R, const crom_samples *S)
{
    size_t n = (size_t)S->F * S->N;
    double box[12];
    for (int d = 0; d < 6; d++) {
        box[d] = INFINITY;
        box[6 + d] = -INFINITY;
    }
    for (size_t i = 0; i < n; i++)
        for (int d = 0; d < 3; d++) {
            double x = S->X[3 * i + d], u = S->U[3 * i + d] / R->t.s;
            box[d] = fmin(box[d], x);
            box[6 + d] = fmax(box[6 + d], x);
            box[3 + d] = fmin(box[3 + d], u);
            box[9 + d] = fmax(box[9 + d], u);
        }
    float sh[3 + CROM_CUTFEAT_MAX], sc[3 + CROM_CUTFEAT_MAX];
    double xb[6] = {box[0], box[1], box[2], box[6], box[7], box[8]};
    int rc = crom_nn_norm_fit(xb, 2, 3, sh, sc);
    for (int k = 0; R->o.cut && k < R->o.cut->nseg; k++) { /* the cut features lie in [-1, 1] already */
        sh[3 + k] = 0;
        sc[3 + k] = 1;
    }
    if (!rc)
        rc = crom_nn_mlp_set_norm(&R->W, sh, sc);
    if (!rc && R->pn) {
        rc = crom_nn_norm_fit(box, 2, 6, sh, sc);
        if (!rc)
            rc = crom_nn_mlp_set_norm(&R->P.point, sh, sc);
    }
    return rc;
}

/* The loss, the optimizer and the per-epoch log. */
static int make_optimizer(fitrun *R)
{
    const crom_fit_opts *o = &R->o;
    int rc = crom_fit_ctx_init(&R->ctx, &R->W, R->pn ? &R->P : NULL, R->t.maxrows, R->t.B, R->t.maxcells,
                               R->pn ? R->t.Pe : 1, o->tikhonov, o->threads);
    if (!rc)
        rc = crom_fit_ctx_set_cut(&R->ctx, o->cut);
    if (rc || (rc = crom_nn_adam_init(&R->adam, R->nW + R->nP)))
        return rc;
    R->loss = crom_malloc(sizeof(double) * (size_t)o->epochs);
    R->secs = crom_malloc(sizeof(double) * (size_t)o->epochs);
    R->acc = crom_malloc(sizeof(double) * (R->nW + R->nP + CROM_FIT_EXTRAS));
    return R->loss && R->secs && R->acc ? 0 : CROM_EINTERNAL;
}

/* The doubles after the gradient in a step's sums (CROM_FIT_EXTRAS of
 * them): the samples n, sum n_s misfit_s, sum n_s objective_s, MLP rows,
 * shards evaluated, the misfit and objective of a lone shard as computed
 * (so that a step of one shard is bit for bit the step of one batch),
 * process 0's clock (s since the start) and the processes that failed. */
enum { X_N, X_MIS, X_OBJ, X_ROWS, X_SHARDS, X_MIS1, X_OBJ1, X_CLOCK, X_FAILED, X_COUNT };
_Static_assert(X_COUNT == CROM_FIT_EXTRAS, "CROM_FIT_EXTRAS counts the extras of a step");

/* FNV-1a over n bytes, continuing from h. */
static uint64_t fnv1a(uint64_t h, const void *p, size_t n)
{
    const unsigned char *c = p;
    for (size_t i = 0; i < n; i++)
        h = (h ^ c[i]) * 0x100000001b3ULL;
    return h;
}

/* A 20-bit fingerprint of what decides the sequence of steps and their
 * allreduces: the samples, and the options but threads, proc and the
 * callbacks. */
static double fingerprint(const crom_samples *S, const crom_fit_opts *o)
{
    size_t n = (size_t)S->F * S->N * 3;
    int v[] = {S->F, S->N, S->nsources, o->rank, o->encoder, o->depth, o->width, (int)o->act, o->epochs, o->batch,
               o->points_per_step, o->enc_points, o->shards, o->nprocs};
    double d[] = {o->lr, o->tikhonov, o->minutes};
    uint64_t h = fnv1a(0xcbf29ce484222325ULL, v, sizeof v);
    h = fnv1a(h, d, sizeof d);
    h = fnv1a(h, &o->seed, sizeof o->seed);
    h = fnv1a(h, S->X, sizeof(float) * n);
    h = fnv1a(h, S->U, sizeof(float) * n);
    h = fnv1a(h, S->vertex, sizeof(int) * (size_t)S->F * S->N);
    h = fnv1a(h, S->source, sizeof(int) * (size_t)S->F);
    return (double)((h ^ h >> 20 ^ h >> 40) & 0xfffff);
}

/* Whether every process is ready to train on the same thing: one
 * allreduce of [failures, f, f^2] with f the fingerprint above, so that a
 * process that could not set up (out of memory) or was given other samples
 * or options (a stale copy of the file on another node) does not leave
 * the others waiting in a step it never takes. Every process sees the sum
 * of f equal nprocs f and that of f^2 equal nprocs f^2 (exact integers in
 * double) only if every f is its own. rc is this process's result. */
static int agree_ready(fitrun *R, const crom_samples *S, int rc)
{
    const crom_fit_opts *o = &R->o;
    if (!o->allreduce)
        return rc;
    double f = fingerprint(S, o), x[3] = {rc != 0, f, f * f};
    int arc = o->allreduce(o->allreduce_ctx, x, 3);
    if (rc || arc)
        return rc ? rc : arc;
    if (x[0] > 0) {
        R->st.remote_failure = 1;
        return crom_err(CROM_EINTERNAL, "training stopped: another process could not set up");
    }
    if (x[1] != o->nprocs * f || x[2] != o->nprocs * (f * f))
        return crom_err(CROM_EUSAGE, "the %d processes were given different samples or training options: each "
                        "must train on the same", o->nprocs);
    return 0;
}

/* One step on batch bj of the epoch's plan (epoch e). Its frames are cut
 * into o.shards shards of consecutive frames, each drawn with its own
 * points; this process evaluates shards proc, proc + nprocs, ... and
 * sums n_s grad_s (n_s: the shard's samples) into R->acc, which the
 * allreduce sums over the processes. The step's gradient is
 * sum n_s grad_s / sum n_s, that of the mean over all its samples, alike
 * on every process, and so is the Adam step, at the learning rate of the
 * fraction frac of the run done or of the budget used, *el seconds (read
 * by the caller; with an allreduce, process 0's clock as it passes it on).
 * *mis gets the step's misfit. With one shard and one process this is,
 * bit for bit, one step on the whole batch: n g / n == g exactly for a
 * float g. The processes return together: a failure is counted in the
 * sums. */
static int train_step(fitrun *R, int bj, int e, double frac, double budget, double tstart, double *el,
                      double *mis)
{
    trainer *t = &R->t;
    const crom_fit_opts *o = &R->o;
    const int *fr = t->order + t->bstart[bj];
    int nf = t->bstart[bj + 1] - t->bstart[bj], S = o->shards, rc = 0;
    size_t np = R->nW + R->nP, nx = np + CROM_FIT_EXTRAS;
    double *acc = R->acc, *x = R->acc + np;
    memset(acc, 0, sizeof(double) * nx);
    for (int s = 0; s < S && !rc; s++) {
        int f0 = (int)((long)nf * s / S), f1 = (int)((long)nf * (s + 1) / S), mine = s % o->nprocs == o->proc;
        if (f1 == f0)
            continue; /* a batch of fewer frames than shards */
        build_batch(t, fr + f0, f1 - f0, mine);
        if (!mine)
            continue;
        double obj, m, n = batch_weight(&t->b);
        if ((rc = crom_fit_loss(&R->ctx, &t->b, &obj, &m, R->grad, NULL)))
            break;
        for (size_t i = 0; i < np; i++)
            acc[i] += n * R->grad[i];
        x[X_N] += n;
        x[X_MIS] += n * m;
        x[X_OBJ] += n * obj;
        x[X_ROWS] += t->b.nrows;
        x[X_SHARDS] += 1;
        x[X_MIS1] = m;
        x[X_OBJ1] = obj;
    }
    if (rc) {
        memset(acc, 0, sizeof(double) * nx);
        x[X_FAILED] = 1;
    }
    if (o->allreduce) {
        /* under MPI this is MPI_Allreduce, which gives every rank the same
         * sums ("MPI requires that all processes participating in these
         * operations receive identical results", MPI 1.1 §4.9.5), so that
         * the processes' parameters stay equal */
        x[X_CLOCK] = o->proc == 0 ? crom_clock_now() - tstart : 0;
        int arc = o->allreduce(o->allreduce_ctx, acc, nx);
        if (rc || arc)
            return rc ? rc : arc;
        R->st.allreduce_doubles = nx;
        *el = x[X_CLOCK];
    }
    if (rc)
        return rc;
    if (x[X_FAILED] > 0) {
        R->st.remote_failure = 1;
        return crom_err(CROM_EINTERNAL, "training stopped at epoch %d: a step failed in another process", e + 1);
    }
    double N = x[X_N];
    int one = x[X_SHARDS] == 1;
    double obj = one ? x[X_OBJ1] : N > 0 ? x[X_OBJ] / N : 0;
    *mis = one ? x[X_MIS1] : N > 0 ? x[X_MIS] / N : 0;
    if (!isfinite(obj))
        return crom_err(CROM_EDATA, "training diverged (loss %g at epoch %d): try a smaller --lr", obj, e + 1);
    for (size_t i = 0; i < np; i++)
        R->grad[i] = N > 0 ? (float)(acc[i] / N) : 0.0f;
    if (budget > 0)
        frac = fmax(frac, *el / budget);
    int ev = (int)floor(frac * o->epochs);
    double lr = crom_nn_lr_schedule(o->lr, ev < o->epochs ? ev : o->epochs - 1, o->epochs);
    crom_nn_adam_step(&R->adam, R->params, R->grad, lr);
    R->st.steps++;
    R->st.rows += x[X_ROWS];
    R->st.samples += N;
    return 0;
}

/* Epochs until o.epochs or the wall-time budget; the learning rate
 * follows the LiCROM step schedule over the fraction of the run done,
 * max(epoch / epochs, elapsed / budget). Each epoch's mean misfit goes to
 * the log and to o.progress. With an allreduce the clock is process 0's,
 * from the last step's allreduce, so that every process stops at the same
 * step. */
static int train(fitrun *R)
{
    const crom_fit_opts *o = &R->o;
    trainer *t = &R->t;
    double budget = o->minutes > 0 ? 60 * o->minutes : 0, tstart = crom_clock_now(), el = 0;
    int stop = 0, rc;
    for (int e = 0; e < o->epochs && !stop; e++) {
        plan_epoch(t);
        double sum = 0;
        int nsum = 0;
        for (int k = 0; k < t->nbatches; k++) {
            double frac = (e + (double)k / t->nbatches) / o->epochs;
            if (!o->allreduce)
                el = crom_clock_now() - tstart;
            if (budget > 0 && el >= budget) {
                stop = 1;
                break;
            }
            double mis = 0;
            if ((rc = train_step(R, t->border[k], e, frac, budget, tstart, &el, &mis)))
                return rc;
            sum += mis;
            nsum++;
        }
        if (nsum == 0)
            break;
        R->loss[R->epochs_done] = sum / nsum * t->s * t->s;
        R->secs[R->epochs_done] = crom_clock_wall(crom_clock_now() - tstart);
        R->epochs_done++;
        if (o->progress) {
            double frac = (double)(e + 1) / o->epochs;
            if (budget > 0)
                frac = fmax(frac, (crom_clock_now() - tstart) / budget);
            o->progress(o->progress_ctx, e + 1, fmin(frac, 1.0), R->loss[R->epochs_done - 1]);
        }
    }
    R->st.seconds = crom_clock_now() - tstart;
    return 0;
}

/* q in metres: the encoder's output and u input carry the scale s. */
static int unscale_encoder(fitrun *R)
{
    int r = R->o.rank;
    double s = R->t.s;
    double *A = crom_calloc((size_t)r * r, sizeof(double));
    if (!A)
        return CROM_EINTERNAL;
    for (int k = 0; k < r; k++)
        A[k * r + k] = s;
    fold_head(&R->P, A, r);
    free(A);
    float sh[6], sc[6];
    for (int d = 0; d < 6; d++) {
        sh[d] = R->P.point.shift[d] * (float)(d >= 3 ? s : 1);
        sc[d] = R->P.point.scale[d] * (float)(d >= 3 ? s : 1);
    }
    crom_nn_mlp_set_norm(&R->P.point, sh, sc);
    return 0;
}

/* Canonical basis: orthonormal over the points, then rotated to the
 * principal axes of the frames' latents, ordered by variance. */
static int canonicalize(fitrun *R, const crom_samples *S)
{
    int rc = orthonormalize(&R->t, &R->W, R->pn ? &R->P : NULL);
    if (rc)
        return rc;
    double *Qall = crom_malloc(sizeof(double) * (size_t)S->F * R->o.rank);
    if (!Qall)
        return CROM_EINTERNAL;
    crom_model tmp;
    double err;
    if ((rc = crom_model_from_mlp(&tmp, &R->W, R->o.cut, R->pn ? &R->P : NULL))) {
        free(Qall);
        return rc;
    }
    rc = crom_fit_error(&tmp, S, R->o.tikhonov, R->pn, R->t.Pe ? R->t.Pe : 1, &err, NULL, Qall);
    crom_model_free(&tmp);
    if (!rc)
        rc = rotate_by_variance(Qall, S->F, R->o.rank, &R->W, R->pn ? &R->P : NULL);
    free(Qall);
    return rc;
}

/* The trained model into out, with its reconstruction error over S and
 * the training log (taken from R); t0 is when the run started. */
static int make_model(fitrun *R, const crom_samples *S, double t0, crom_model *out)
{
    double err;
    int rc = crom_model_from_mlp(out, &R->W, R->o.cut, R->pn ? &R->P : NULL);
    if (rc)
        return rc;
    if ((rc = crom_fit_error(out, S, R->o.tikhonov, R->pn, R->t.Pe ? R->t.Pe : 1, &err, NULL, NULL))) {
        crom_model_free(out);
        return rc;
    }
    out->reconstruction_error = err;
    out->nepochs = R->epochs_done;
    out->loss = R->loss;
    out->seconds = R->secs;
    R->loss = R->secs = NULL;
    out->training_seconds = crom_clock_wall(crom_clock_now() - t0);
    return 0;
}

/* Whether the options (epochs and lr resolved) and the data are fit for
 * training: 0, CROM_EUSAGE or CROM_EDATA. */
static int check_run(const crom_samples *S, const crom_fit_opts *o)
{
    if (o->rank < 1 || o->depth < 2 || o->depth > CROM_NN_MAX_LAYERS || o->width < 1 || o->batch < 1 ||
        !(o->lr > 0) || o->enc_points < 1 || o->threads < 1 || !(o->tikhonov >= 0) || o->shards < 1 ||
        o->nprocs < 1 || o->proc < 0 || o->proc >= o->nprocs || (o->nprocs > 1 && !o->allreduce))
        return crom_err(CROM_EUSAGE, "invalid training options");
    int rc = crom_fit_check(S, o->rank);
    if (rc)
        return rc;
    int B = o->batch < S->F ? o->batch : S->F; /* frames of a batch (trainer_init) */
    if (o->shards > B)
        return crom_err(CROM_EUSAGE, "--shards %d exceeds the %d frames of a batch (--batch %d, %d frames in the "
                        "samples): each shard needs a frame", o->shards, B, o->batch, S->F);
    return 0;
}

int crom_fit_mlp(const crom_samples *S, const crom_fit_opts *opts, crom_model *out)
{
    crom_model_clear(out);
    fitrun R;
    memset(&R, 0, sizeof R);
    crom_fit_opts *o = &R.o;
    *o = *opts;
    R.pn = o->encoder == CROM_MODEL_ENC_POINTNET;
    if (o->epochs <= 0)
        o->epochs = R.pn ? CROM_FIT_EPOCHS_POINTNET : CROM_FIT_EPOCHS_LSQ;
    if (o->lr <= 0)
        o->lr = R.pn ? CROM_FIT_LR_POINTNET : CROM_FIT_LR_LSQ;
    double t0 = crom_clock_now();
    /* threaded MLP passes call sgemm per thread: OpenBLAS single-threaded
     * meanwhile (nn.h), the caller's setting restored on return */
    int blas_threads = openblas_get_num_threads(), threaded = o->threads > 1;
    if (threaded)
        openblas_set_num_threads(1);
    int rc = check_run(S, o);
    if (!rc && !(rc = trainer_init(&R.t, S, o)) && !(rc = make_networks(&R)) && !(rc = set_input_norm(&R, S)))
        rc = make_optimizer(&R);
    /* with an allreduce, every process makes this one call whatever its
     * checks found, then (all ready) the same steps */
    if (!(rc = agree_ready(&R, S, rc)))
        rc = train(&R);
    if (o->stats)
        *o->stats = R.st;
    /* after the last step every process goes on alone, alike */
    if (!rc && !(rc = R.pn ? unscale_encoder(&R) : 0) && !(rc = canonicalize(&R, S)))
        rc = make_model(&R, S, t0, out);
    fitrun_free(&R);
    if (threaded)
        openblas_set_num_threads(blas_threads);
    return rc;
}

/* ============================================================ POD */

/* The frames of S (every vertex once in each: CROM_EDATA otherwise) as
 * snapshots in vertex order: U [F][3nv] the displacements, Y the same
 * weighted by sqrt(w_v / vol), w the vertex volumes; seen [nv] scratch. */
static int pod_snapshots(const crom_samples *S, const double *w, double vol, unsigned char *seen, double *U,
                         double *Y)
{
    int nv = S->N;
    size_t n3 = 3 * (size_t)nv;
    for (int f = 0; f < S->F; f++) {
        memset(seen, 0, (size_t)nv);
        for (int i = 0; i < nv; i++) {
            int v = S->vertex[(size_t)f * nv + i];
            if (v < 0 || seen[v])
                return crom_err(CROM_EDATA, "--basis pod needs every vertex in every frame "
                                            "(crom-sample --points all); frame %d lacks some", f);
            seen[v] = 1;
            for (int d = 0; d < 3; d++) {
                double u = S->U[((size_t)f * nv + i) * 3 + d];
                U[(size_t)f * n3 + 3 * (size_t)v + d] = u;
                Y[(size_t)f * n3 + 3 * (size_t)v + d] = u * sqrt(w[v] / vol);
            }
        }
    }
    return 0;
}

/* Each column of A [n][r] signed so that its largest entry is positive. */
static void sign_columns(double *A, size_t n, int r)
{
    for (int j = 0; j < r; j++) {
        size_t big = 0;
        for (size_t i = 0; i < n; i++)
            if (fabs(A[i * r + j]) > fabs(A[big * r + j]))
                big = i;
        if (A[big * r + j] < 0)
            for (size_t i = 0; i < n; i++)
                A[i * r + j] = -A[i * r + j];
    }
}

int crom_fit_pod(const crom_samples *S, int rank, crom_model *out, double *captured)
{
    crom_model_clear(out);
    int rc = crom_fit_check(S, rank);
    if (rc)
        return rc;
    double t0 = crom_clock_now();
    if (S->nsources != 1)
        return crom_err(CROM_EDATA,
                        "--basis pod needs samples of one mesh, and this sample set has %d source meshes "
                        "(a neural field, --basis mlp, learns from several)", S->nsources);
    const crom_mesh *m = &S->src[0];
    int nv = m->nv, F = S->F;
    if (strcmp(S->mode, "vertices") || S->N != nv)
        return crom_err(CROM_EDATA,
                        "--basis pod needs every vertex in every frame (crom-sample --points all); "
                        "these samples have %d %s points per frame of a %d-vertex mesh",
                        S->N, S->mode, nv);
    size_t n3 = 3 * (size_t)nv;
    double *w = crom_malloc(sizeof(double) * (size_t)nv);
    double *U = crom_malloc(sizeof(double) * (size_t)F * n3);
    double *Y = crom_malloc(sizeof(double) * (size_t)F * n3);
    double *K = crom_malloc(sizeof(double) * (size_t)F * F);
    double *ev = crom_malloc(sizeof(double) * (size_t)F);
    double *Vr = crom_malloc(sizeof(double) * (size_t)F * rank);
    double *Phi = crom_malloc(sizeof(double) * n3 * rank);
    unsigned char *seen = crom_malloc((size_t)nv);
    if (!w || !U || !Y || !K || !ev || !Vr || !Phi || !seen) {
        rc = CROM_EINTERNAL;
        goto done;
    }
    double vol = crom_mesh_vertex_volumes(m, w);
    if ((rc = pod_snapshots(S, w, vol, seen, U, Y)))
        goto done;
    /* Gram matrix of the weighted snapshots and its eigenvectors */
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasNoTrans, F, (int)n3, 1.0, Y, (int)n3, 0.0, K, F);
    /* row-major upper = column-major lower */
    if (LAPACKE_dsyevd(LAPACK_COL_MAJOR, 'V', 'L', F, K, F, ev) != 0) {
        rc = crom_err(CROM_EINTERNAL, "POD eigen-decomposition failed");
        goto done;
    }
    double lmax = ev[F - 1], sum = 0, top = 0;
    int nrank = 0;
    for (int k = 0; k < F; k++) {
        sum += fmax(ev[k], 0);
        if (ev[k] > 1e-10 * lmax)
            nrank++;
    }
    if (!(lmax > 0) || rank > nrank) {
        rc = crom_err(CROM_EDATA,
                      "rank %d exceeds the numerical rank %d of the data (%d frames): use --rank %d or less",
                      rank, nrank, F, nrank);
        goto done;
    }
    /* eigenvector k is column k of K (column-major): K[k*F + f] */
    for (int j = 0; j < rank; j++) {
        int k = F - 1 - j;
        top += ev[k];
        double is = 1.0 / sqrt(ev[k]);
        for (int f = 0; f < F; f++)
            Vr[(size_t)f * rank + j] = K[(size_t)k * F + f] * is;
    }
    /* Phi = U^T V Lambda^{-1/2}: M-orthonormal modes, [3nv][r] */
    cblas_dgemm(CblasRowMajor, CblasTrans, CblasNoTrans, (int)n3, rank, F, 1.0, U, (int)n3, Vr,
                rank, 0.0, Phi, rank);
    sign_columns(Phi, n3, rank);
    if ((rc = crom_model_from_mesh(out, "pod", m, Phi, rank)))
        goto done;
    double err;
    if ((rc = crom_fit_error(out, S, 0, 0, 1, &err, NULL, NULL))) {
        crom_model_free(out);
        goto done;
    }
    out->reconstruction_error = err;
    out->training_seconds = crom_clock_wall(crom_clock_now() - t0);
    if (captured)
        *captured = sum > 0 ? top / sum : 1;
done:
    free(w);
    free(U);
    free(Y);
    free(K);
    free(ev);
    free(Vr);
    free(Phi);
    free(seen);
    return rc;
}

/* ============================================================ errors */

int crom_fit_error(const crom_model *m, const crom_samples *S, double tik, int use_encoder,
                   int enc_points, double *err, double *frame_err, double *qout)
{
    int r = m->rank, N = S->N, rc = 0;
    size_t rr = (size_t)r * r;
    int enc = use_encoder && m->encoder == CROM_MODEL_ENC_POINTNET;
    double **cache = crom_calloc((size_t)(S->nsources ? S->nsources : 1), sizeof(double *));
    double *Wf = crom_malloc(sizeof(double) * (size_t)N * 3 * r);
    double *Xd = crom_malloc(sizeof(double) * (size_t)N * 3);
    double *u = crom_malloc(sizeof(double) * (size_t)N * 3);
    double *G = crom_malloc(sizeof(double) * rr), *q = crom_malloc(sizeof(double) * r);
    double *pts = enc ? crom_malloc(sizeof(double) * 6 * (size_t)N) : NULL;
    int *perm = enc ? crom_malloc(sizeof(int) * (size_t)N) : NULL;
    /* a field with cut features: each sample's features from its side (as in training) */
    float *side = m->field == CROM_MODEL_FIELD_MLP && m->cut.nseg ? crom_fit_side_points(S, &m->cut) : NULL;
    double *Sd = side ? crom_malloc(sizeof(double) * (size_t)N * 3) : NULL;
    if (m->field == CROM_MODEL_FIELD_MLP && m->cut.nseg && !side) {
        rc = crom_errcode();
        goto done;
    }
    if (!cache || !Wf || !Xd || !u || !G || !q || (enc && (!pts || !perm)) || (side && !Sd)) {
        rc = CROM_EINTERNAL;
        goto done;
    }
    crom_rng rng;
    crom_rng_seed(&rng, 0x6f1c2e5a);
    double e2 = 0, u2 = 0;
    for (int f = 0; f < S->F; f++) {
        const int *vx = S->vertex + (size_t)f * N;
        int k = S->source[f], gather = 1;
        for (int i = 0; i < N && gather; i++)
            gather = vx[i] >= 0;
        if (gather && !cache[k]) {
            const crom_mesh *sm = &S->src[k];
            cache[k] = crom_malloc(sizeof(double) * (size_t)sm->nv * 3 * r);
            if (!cache[k]) {
                rc = CROM_EINTERNAL;
                goto done;
            }
            if ((rc = crom_model_eval_mesh(m, sm, CROM_MESH_CRACK_OFFSET, cache[k], NULL, NULL)))
                goto done;
        }
        for (size_t i = 0; i < 3 * (size_t)N; i++) {
            Xd[i] = S->X[(size_t)f * N * 3 + i];
            u[i] = S->U[(size_t)f * N * 3 + i];
            if (Sd)
                Sd[i] = side[(size_t)f * N * 3 + i];
        }
        if (gather) {
            for (int i = 0; i < N; i++)
                memcpy(Wf + (size_t)i * 3 * r, cache[k] + (size_t)vx[i] * 3 * r, sizeof(double) * 3 * r);
        } else if ((rc = crom_model_eval_sided(m, (size_t)N, Xd, Sd, Wf, NULL))) {
            goto done;
        }
        if (enc) {
            int Pe = enc_points < N ? enc_points : N;
            for (int i = 0; i < N; i++)
                perm[i] = i;
            partial_shuffle(&rng, perm, N, Pe);
            for (int i = 0; i < Pe; i++)
                for (int d = 0; d < 3; d++) {
                    pts[6 * i + d] = Xd[3 * perm[i] + d];
                    pts[6 * i + 3 + d] = u[3 * perm[i] + d];
                }
            if ((rc = crom_model_encode_pointnet(m, (size_t)Pe, pts, q)))
                goto done;
        } else {
            cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, r, 3 * N, 1.0, Wf, r, 0.0, G, r);
            for (int a = 0; a < r; a++)
                for (int b = 0; b < a; b++)
                    G[a * r + b] = G[b * r + a];
            cblas_dgemv(CblasRowMajor, CblasTrans, 3 * N, r, 1.0, Wf, r, u, 1, 0.0, q, 1);
            double tr = trace(G, r), l = tik * tr / r;
            if (!(tr > 0) || spd_solve(G, r, fmax(l, 1e-14 * tr / r), q, 1) != 0)
                memset(q, 0, sizeof(double) * r);
        }
        double fe = 0, fu = 0;
        for (int i = 0; i < 3 * N; i++) {
            double s = -u[i];
            const double *w = Wf + (size_t)i * r;
            for (int j = 0; j < r; j++)
                s += w[j] * q[j];
            fe += s * s;
            fu += u[i] * u[i];
        }
        e2 += fe;
        u2 += fu;
        if (frame_err)
            frame_err[f] = fu > 0 ? sqrt(fe / fu) : sqrt(fe);
        if (qout)
            memcpy(qout + (size_t)f * r, q, sizeof(double) * r);
    }
    *err = u2 > 0 ? sqrt(e2 / u2) : 0;
done:
    for (int k = 0; cache && k < S->nsources; k++)
        free(cache[k]);
    free(cache);
    free(Wf);
    free(Xd);
    free(u);
    free(G);
    free(q);
    free(pts);
    free(perm);
    free(side);
    free(Sd);
    return rc;
}
