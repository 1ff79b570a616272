/* dftrain.h — what the data-free trainers share (the maps of datafree.h,
 * the field of dffield.h, the skinning weights of dfskin.h): the terms of
 * one evaluation of a loss, the record of a run, and the loop that trains.
 *
 * The loop: each step draws a fresh batch (latent samples, the tangent
 * samples (short secants from rest along the latent axes), the tets of a fresh random cubature), evaluates the
 * trainer's loss and gradient, and moves the parameters: Adam on a fresh
 * batch every step, or L-BFGS with a backtracking line search (Wang et
 * al.'s optimizer, lib/base/lbfgs.h), `resample` iterations on each batch
 * (the objective must stay fixed while the line search compares values;
 * the pairs are kept across batches, and the first step, with no pair
 * yet, moves no parameter by more than lr). The schedule is the fraction
 * of the steps done or of the time budget used, whichever is further
 * along; the learning rate is halved after each quarter of it (Sharp et
 * al.'s schedule on a shorter run), and the seed-state blend ρ of the
 * energy objectives grows from 0 to 1 over its first `ramp` (datafree.h).
 * The record keeps per block of steps (about 100 blocks) the mean terms
 * and the wall time at its end.
 */
#ifndef CROM_DFTRAIN_H
#define CROM_DFTRAIN_H

#include <stddef.h>
#include <stdint.h>

#include <hdf5.h>

#include "base/rng.h"
#include "mesh/mesh.h"
#include "nn/nn.h"

/* ------------------------------------------------------------ set-up */

/* The diagonal of the mesh's bounding box (m). */
double crom_dftrain_diag(const crom_mesh *m);

/* A network in -> width x (depth - 1) -> out of activation act (depth >= 1,
 * at most CROM_NN_MAX_LAYERS, else CROM_EUSAGE). Returns what
 * crom_nn_spec_set returns. */
int crom_dftrain_spec(crom_nn_spec *spec, int in, int width, int depth, int out, crom_nn_act act);

/* Normalize the input of net (3 -> ...) to the bounding box of the mesh.
 * Returns 0 or what crom_nn_norm_fit returns. */
int crom_dftrain_norm_box(crom_nn_mlp *net, const crom_mesh *m);

/* Scale the last layer of net (weights and biases) by f. */
void crom_dftrain_scale_last(crom_nn_mlp *net, float f);

/* The two random streams of a trainer from its seed: init for the
 * networks' initialization, samples for everything drawn after it. */
void crom_dftrain_seed(uint64_t seed, crom_rng *init, crom_rng *samples);

/* The threads of the energy evaluations: n clamped to [1, 256]. */
int crom_dftrain_threads(int n);

/* ------------------------------------------------------------ the loop */

/* What one evaluation of a loss gives, besides its value. */
typedef struct {
    double objective; /* L (dimensionless) */
    double energy;    /* mean energy of the samples (J): potential (energy, field), elastic (neuralmodes, skinning) */
    double penalty;   /* energy, field: mean squared log isometry ratio; neuralmodes: mean ‖WᵀMy/m‖²/a²;
                         skinning: ‖G − I‖² */
    double tangent;   /* energy, field: the collapse floor at rest, Σ_k h(μ_k) (dfloss.h) */
} crom_dftrain_terms;

/* The record of a run: per block of steps, the mean terms and the wall
 * time at its end; and totals. */
typedef struct {
    int nblocks;
    double *objective, *energy, *penalty, *seconds;
    long steps;
    double seconds_total;
    double sigma, box, Eref; /* as used (set by the trainer) */
} crom_dftrain_log;

void crom_dftrain_log_free(crom_dftrain_log *l);

/* Write the per-block record as training/objective, /energy, /penalty and
 * /seconds under loc (nothing if it has no block). Returns 0 or an HDF5
 * error. */
int crom_dftrain_log_write(hid_t loc, const crom_dftrain_log *log);

/* A trainer and its schedule. */
typedef struct {
    /* the loss of a batch: z [batch + tangent][r] the samples, rho the
     * blend, tets [K] the cubature (NULL when K is 0); the gradient goes
     * to grad[] */
    int (*loss)(void *ctx, const double *z, double rho, int K, const int *tets, crom_dftrain_terms *t);
    void *ctx;
    int nblocks;                /* parameter blocks (networks) moved: 1 or 2 (L-BFGS: 1) */
    float *params[2], *grad[2];
    size_t nparams[2];
    /* what a step draws, from rng */
    crom_rng *rng;
    int batch, tangent, r;      /* samples, tangent samples after them, coordinates of each */
    const double *scale;        /* [r]: coordinate k is scale[k] N(0, 1) (NULL: N(0, 1)) */
    int uniform;                /* 1: coordinate k is scale[k] U(−1, 1) instead */
    double tangent_radius;      /* ε: tangent sample k is ε e_(k mod r), a secant from rest */
    int K, nt;                  /* K of the nt tets, every one in order if K = nt (0: none) */
    double ramp;                /* ρ = min(1, frac / ramp) (0: ρ = 1) */
    /* the schedule */
    int steps;
    double minutes;             /* wall-time budget (0: none) */
    double lr;                  /* base learning rate; L-BFGS: the size of its first step */
    int lbfgs, resample;        /* L-BFGS, iterations on each batch */
    const char *hint;           /* after "training diverged at step k" (Adam) */
    void (*progress)(void *ctx, long step, double frac, double objective);
    void *progress_ctx;
} crom_dftrain_loop;

/* Train: run L's schedule, recording in log (allocated here; its sigma,
 * box and Eref are left as they are). Returns 0; the loss's error, CROM_EDATA with
 * "training diverged at step k" for a non-finite loss; CROM_EUSAGE if the
 * time budget ran out before the first step; CROM_EINTERNAL. On failure
 * the record is freed. */
int crom_dftrain_run(const crom_dftrain_loop *L, crom_dftrain_log *log);

#endif
