/* fit.h — learning a displacement basis W(X) from point samples (LiCROM §3).
 *
 * Three fits:
 *   - lsq (variable projection, the fast path): every frame's q is the
 *     least-squares fit of the current W to that frame's samples,
 *         q_f = argmin_q sum_i |W(X_i) q - u_fi|^2 + lambda_f |q|^2,
 *     re-solved at every step; lambda_f = tikhonov * tr(G_f) / r with
 *     G_f = sum_i W_i^T W_i. The loss is the resulting minimum, and its
 *     gradient w.r.t. W's parameters is that of the same expression at q_f
 *     held fixed (envelope theorem; the dependence of lambda_f on W is
 *     differentiated exactly).
 *   - pointnet (LiCROM eq. 4): q_f = P(S(X, u)) from a PointNet P that sees a
 *     random subsample of the frame, trained jointly with W.
 *   - pod: the r leading modes of the mass-weighted snapshot matrix of one
 *     mesh (lumped vertex volumes as weights, normalized by the total volume,
 *     so the modes are orthonormal in the volume-mean inner product
 *     <a, b> = sum_v w_v a_v . b_v / V), stored as a piecewise-linear field.
 *
 * Training batches (crom_fit_batch) are groups of frames that share a set of
 * points: W is evaluated once per point and used by every frame of the group,
 * and the per-frame work is matrix products (BLAS) of [3 x points] x [frames]
 * blocks. Samples taken at mesh vertices (crom-sample --mode vertices) are
 * grouped by source mesh: a step evaluates W at a random subset V of one
 * source's vertices and uses, for every frame of the batch, the samples it
 * has at V (a 0/1 mask says which). Interior samples give one group per
 * frame. Displacements in a batch are scaled by the data's RMS displacement
 * s, so losses are relative; the model stores W with q in metres. With
 * shards (crom_fit_opts) a step's frames are cut into shards, each a batch
 * of its own in this sense, which processes may share out (MPI).
 *
 * After training an mlp W is re-expressed, exactly, in a canonical basis of
 * its own span: orthonormal in the mean over the training points
 * (mean_i W_i^T W_i = I, so each field has RMS magnitude 1 and q is in metres
 * of RMS displacement) and ordered by decreasing variance of q over the
 * training frames, like POD modes. The change of basis is folded into the
 * last layer of W (and its inverse into the encoder's head).
 */
#ifndef CROM_FIT_H
#define CROM_FIT_H

#include <stddef.h>
#include <stdint.h>

#include "nn/nn.h"
#include "rom/model.h"
#include "rom/samples.h"

/* ---------------------------------------------------------- the losses */

/* One training batch: ngroups groups of frames, group g with rows[g] points
 * (consecutive rows of X) and frames[g] frames (consecutive in the batch's
 * frame order). */
typedef struct {
    int ngroups, nframes, nrows;
    int *rows;      /* [ngroups] points of each group */
    int *frames;    /* [ngroups] frames of each group */
    int *dense;     /* [ngroups] 1: every frame has a sample at every point (M unused) */
    float *X;       /* [nrows][3] points (m) */
    float *S;       /* [nrows][3] where a field's cut features are taken (crom_fit_side_points), or NULL: at X */
    double *U;      /* per group, concatenated: [rows][3][frames] scaled displacement, 0 where missing */
    double *M;      /* per group, concatenated: [rows][frames] 1 where frame has the point, else 0 */
    int enc_points; /* points per frame the encoder sees */
    float *enc;     /* [nframes][enc_points][6] encoder input (X, scaled u) */
    int *frame_id;  /* [nframes] which training frame each is (bookkeeping only) */
} crom_fit_batch;

/* Scratch and settings of the loss: W (and P for the joint loss), their
 * workspaces, and buffers for batches of up to maxrows points, maxframes
 * frames and maxcells = sum over groups of rows x frames. No allocation
 * happens per call. */
typedef struct {
    int rank;
    double tikhonov;
    const crom_nn_mlp *W;
    const crom_nn_pointnet *P; /* NULL: lsq (variable projection) */
    size_t nW;                 /* P's gradient starts at grad + nW */
    int maxrows, maxframes, maxcells, enc_points;
    crom_nn_ws ws;
    crom_nn_pointnet_ws pws;
    double *Wd, *dW, *R, *K, *G, *Bm, *Q, *qn, *cvec, *lam;
    float *dy, *qf, *dqf;
    const crom_cutfeat *cut; /* the field's cut features (crom_fit_ctx_set_cut), or NULL */
    float *Xin;              /* [maxrows][3 + K] X and its features */
} crom_fit_ctx;

/* Set up a loss context for field W (3 -> 3r, or 3 + K -> 3r for a
 * field with cut features: then crom_fit_ctx_set_cut) and optional encoder P (6 ->
 * r, NULL for lsq). nthreads splits the MLP passes (nn.h). Returns 0,
 * CROM_EUSAGE on bad sizes, CROM_EINTERNAL when out of memory. */
int crom_fit_ctx_init(crom_fit_ctx *c, const crom_nn_mlp *W, const crom_nn_pointnet *P,
                      int maxrows, int maxframes, int maxcells, int enc_points,
                      double tikhonov, int nthreads);
void crom_fit_ctx_free(crom_fit_ctx *c);

/* A field that takes the K features of a cut after X (lib/mesh/cutfeat.h;
 * borrowed, keep it alive): W maps 3 + K inputs. The batches still give X
 * [nrows][3]; the loss adds the features. CROM_EUSAGE if W's input width is
 * not 3 + K, CROM_EINTERNAL when out of memory. */
int crom_fit_ctx_set_cut(crom_fit_ctx *c, const crom_cutfeat *cut);

/* The loss of a batch: with n the number of (frame, point) samples present,
 *   objective = (1/n) [ sum_f sum_i m_fi |W(X_i) q_f - u_fi|^2 + sum_f lambda_f |q_f|^2 ]
 * (the lambda term only for lsq) and misfit = the first sum / n. If grad is
 * non-NULL it is overwritten with d objective / d params ([W params | P
 * params]). q (may be NULL) gets the latents [nframes][r] in scaled units.
 * Returns 0, or an error code from the networks. */
int crom_fit_loss(crom_fit_ctx *c, const crom_fit_batch *b, double *objective, double *misfit,
                  float *grad, double *q);

/* ------------------------------------------------------------- training */

typedef struct {
    int rank;               /* r (20) */
    int encoder;            /* CROM_MODEL_ENC_LSQ (default) or CROM_MODEL_ENC_POINTNET */
    int depth, width;       /* field MLP: depth dense layers, hidden width (5, 60) */
    crom_nn_act act;        /* hidden activation (ELU) */
    int epochs;             /* epochs; also the length of the lr schedule (0: default of the encoder) */
    double minutes;         /* wall-time budget (0: none) */
    double lr;              /* base learning rate (0: default of the encoder) */
    int batch;              /* frames per step (16) */
    int points_per_step;    /* samples per frame per step (0: 128 for lsq, all for pointnet) */
    int enc_points;         /* encoder subsample (2500) */
    double tikhonov;        /* relative Tikhonov weight of the lsq fits (1e-6) */
    int threads;            /* threads for the MLP passes (1) */
    uint64_t seed;
    /* Data parallelism (crom-fitfield under MPI). Each step's batch is cut
     * into `shards` shards of about batch/shards frames (consecutive in the
     * batch), each with points of its own; what a step draws does not
     * depend on nprocs. Process `proc` of `nprocs` (an MPI rank) evaluates
     * shards proc, proc + nprocs, ..., sums their gradients weighted by
     * their sample counts, and `allreduce` sums [gradient | loss terms] over
     * the processes in place, once per step (8 (P + CROM_FIT_EXTRAS) bytes,
     * P parameters); then every process takes the same Adam step. A step's
     * objective is the mean over all samples of its shards, so one process
     * with the same shards trains the same model up to round-off. allreduce
     * returns 0 or an error code; it may be NULL when nprocs is 1. The
     * processes return together from a failure before or during training:
     * the next allreduce passes it on (the others get CROM_EINTERNAL and
     * stats->remote_failure 1); after the last step each finishes alone. */
    int shards;             /* shards per step (1; at most the frames of a batch) */
    int proc, nprocs;       /* this process and the number of them (0, 1) */
    int (*allreduce)(void *ctx, double *buf, size_t n);
    void *allreduce_ctx;
    /* a field that can jump across a cut: its K features are inputs after
     * X (lib/mesh/cutfeat.h; NULL or nseg 0: none) */
    const crom_cutfeat *cut;
    /* statistics of the run (may be NULL) */
    struct crom_fit_stats *stats;
    /* progress: called after every epoch (frac = progress in [0,1]) */
    void (*progress)(void *ctx, int epoch, double frac, double loss_m2);
    void *progress_ctx;
} crom_fit_opts;

/* The doubles a step's allreduce carries besides the gradient: sample
 * count, weighted misfit and objective, rows, shards, the misfit and
 * objective of a lone shard, process 0's clock, failures. */
#define CROM_FIT_EXTRAS 9

/* What a training run did: steps, MLP rows through forward + backward (W
 * evaluated once per point of a group), samples (frame, point) in the losses
 * (over every process), the wall time of the steps, the doubles summed by
 * each step's allreduce (0 without one), and whether training stopped
 * because another process failed. */
typedef struct crom_fit_stats {
    long steps;
    double rows, samples, seconds;
    size_t allreduce_doubles;
    int remote_failure;
} crom_fit_stats;

#define CROM_FIT_EPOCHS_LSQ 400
#define CROM_FIT_EPOCHS_POINTNET 3750 /* LiCROM §3.1 */
#define CROM_FIT_LR_LSQ 5e-3          /* measured: 2x lower error per minute than 1e-3 */
#define CROM_FIT_LR_POINTNET 1e-3     /* LiCROM §3.1 */

/* The paper's defaults (r 20, 5 layers of width 60, ELU, 16 frames per
 * batch, encoder subsample 2500), encoder lsq; epochs and learning rate
 * resolved per encoder (above) when left 0. */
void crom_fit_defaults(crom_fit_opts *o);

/* Where the cut features of each sample of S are taken, [F][N][3]
 * (malloc'ed): at the sample, except for an interior sample whose tet (in
 * its source mesh) has its centroid on the other side of a segment of cut
 * (|feature| > 1/2 there): then at that centroid. A cut follows element
 * faces (crom-remesh cut), so such a tet lies across the segment's line but
 * moves with the side of its centroid; vertices on a crack take their
 * features from their own tets' centroid likewise (crom_model_eval_mesh).
 * NULL when out of memory or a source mesh has a degenerate tet (error
 * recorded). */
float *crom_fit_side_points(const crom_samples *S, const crom_cutfeat *cut);

/* Check a sample set can give a rank-r basis: at least 2 frames, r no more
 * than the frames with non-zero displacement. CROM_EDATA with a message
 * otherwise. */
int crom_fit_check(const crom_samples *S, int rank);

/* Train a neural field (and a PointNet when o->encoder is pointnet) on S.
 * out gets the model with its training log, reconstruction error and wall
 * time. Stops after o->epochs epochs or o->minutes of wall time; the
 * learning rate follows the LiCROM step schedule over the fraction of the
 * run done, max(epoch / epochs, elapsed / budget) (with an allreduce:
 * process 0's clock, passed on by it). With o->allreduce every process must
 * call this with the same S and options but o->proc (and threads): they
 * check that in one allreduce before training, with what each found wrong
 * with the options and data, and fail together. Returns 0, CROM_EDATA
 * (data unusable: see crom_fit_check), CROM_EUSAGE (bad options, shards
 * more than the frames of a batch) or CROM_EINTERNAL. */
int crom_fit_mlp(const crom_samples *S, const crom_fit_opts *o, crom_model *out);

/* Mass-weighted POD of samples of one mesh with every vertex in every frame
 * (crom-sample --points all): out gets a "pod" model of rank r on that mesh.
 * *captured (may be NULL) gets the fraction of the snapshot energy the r
 * modes hold. CROM_EDATA if the samples are not of that form or r exceeds
 * the numerical rank of the data. */
int crom_fit_pod(const crom_samples *S, int rank, crom_model *out, double *captured);

/* Relative reconstruction error sqrt(sum |W q_f - u_f|^2 / sum |u_f|^2) of
 * model m over every sample of every frame of S, with q_f the lsq fit of W to
 * the frame's samples (relative Tikhonov weight tik) or, if use_encoder and
 * the model has a PointNet, the encoding of a random subsample of at most
 * enc_points samples. frame_err [F] and q [F][r] (may be NULL) get the
 * per-frame errors and latents (m). Returns 0 or an error code. */
int crom_fit_error(const crom_model *m, const crom_samples *S, double tik, int use_encoder,
                   int enc_points, double *err, double *frame_err, double *q);

#endif
