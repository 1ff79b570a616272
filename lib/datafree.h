/* datafree.h — subspaces learned from the energy alone, with no simulation
 * data (crom-fitfield --objective energy|neuralmodes).
 *
 * Both learn a map of a latent q in R^r to the positions of every vertex of
 * ONE mesh (crom/model basis "energy" or "neuralmodes", lib/map.h):
 *
 * energy (Sharp et al. 2023, "Data-Free Learning of Reduced-Order
 * Kinematics", eq. 4 and §4.1): x(z) = X + N(z), N an ELU MLP r -> 3nv
 * (5 hidden layers), trained on batches of z ~ N(0, I) to minimize
 *
 *   L = 1/B Σ_b E_pot(X + ρ N(z_b)) / (E V)
 *     + λ · mean over the pairs b < c of ( log( D_bc / (σ ‖z_b − z_c‖) ) )²,
 *
 *   D_bc = sqrt( (N(z_b) − N(z_c))ᵀ M (N(z_b) − N(z_c)) / m ),
 *
 * with E_pot the stable neo-Hookean energy plus the potential of gravity
 * −Σ_v m_v g·u_v, M the lumped mass and m the body's mass (so D and σ are
 * RMS displacements in metres: the paper's ‖·‖_M divided by sqrt(m)), E V
 * Young's modulus times the volume (the energy unit that makes L
 * dimensionless), and ρ the seed-state blend of §4.1: the map is
 * ρ N(z) + (1 − ρ) q_seed with the rest state as seed, i.e. X + ρ N(z), and
 * σ is scaled by ρ too, which cancels in the log-ratio (so the isometry term
 * is written with N itself and is defined at ρ = 0). ρ grows linearly from 0
 * to 1 over the first `ramp` fraction of the steps, then stays 1, so the map
 * that is stored (ρ = 1) is the one trained last. Pinned vertices are built
 * in: their outputs are masked in the loss and their rows of the last layer
 * are zero, so the stored map holds them exactly at rest.
 *
 * neuralmodes (Wang et al. 2024, "Neural Modes", eq. 12–13): x(z) = X + W z
 * + y(z) on the r lowest linear modes W (crom-modes, orthonormal in the mass
 * mean: WᵀMW = m I, q in metres), y a GELU MLP r -> 3nv, trained on z
 * uniform in the box [−a, a]^r to minimize
 *
 *   L = 1/B Σ_b [ E(X + W z_b + y(z_b)) / E_ref + w_o ‖Wᵀ M y(z_b) / m‖² / a² ]
 *     + w_0 ‖y(0)‖²_M / (m a²),
 *
 * the elastic energy (no gravity: nonlinear modes are equilibria of the
 * elastic energy in the space M-orthogonal to the linear ones), a penalty
 * keeping y M-orthogonal to the linear span, and one on y at the origin;
 * E_ref = ½ m ω_r² a², the linear energy of the highest mode at the box
 * size (E V if that is zero); the default w_o = w_0 = 1e4 holds the
 * projection of y onto the modes and y(0) to about 1 % of the box. The last layer starts at zero: training
 * starts from the linear modes.
 *
 * Training: Adam, learning rate halved after each quarter of the steps (the
 * paper's schedule, on a shorter run), batch B. The energies of the B
 * samples are computed in parallel over `threads` threads, each sample
 * serially, so results do not depend on the thread count; the network runs
 * single-threaded (float32), the losses in double.
 */
#ifndef CROM_DATAFREE_H
#define CROM_DATAFREE_H

#include <stdint.h>

#include <hdf5.h>

#include "fem.h"
#include "mesh.h"
#include "model.h"
#include "nn.h"
#include "scenario.h"

enum { CROM_DF_ENERGY = 1, CROM_DF_NEURALMODES = 2 };

/* The physical problem (all borrowed). */
typedef struct {
    const crom_mesh *mesh;
    crom_material mat;
    double gravity[3];           /* m/s² (energy objective only) */
    const unsigned char *fixed;  /* [3nv] pinned DOFs, or NULL */
    const double *modes;         /* neuralmodes: W [nv][3][r] */
    const double *freq;          /* neuralmodes: [r] frequencies (Hz), or NULL */
} crom_df_problem;

typedef struct {
    int objective;          /* CROM_DF_ENERGY or CROM_DF_NEURALMODES */
    int rank;               /* r */
    int depth, width;       /* dense layers (6: 5 hidden) and hidden width (64) */
    crom_nn_act act;        /* ELU (energy) or GELU (neuralmodes) */
    int steps;              /* training steps (2000) */
    double minutes;         /* wall-time budget (0: none) */
    double lr;              /* base learning rate (1e-3) */
    int batch;              /* samples per step (32) */
    double sigma;           /* energy: isometry scale, RMS metres per unit z */
    double lambda;          /* energy: isometry weight (1) */
    double ramp;            /* energy: fraction of the steps over which ρ grows (0.5) */
    double box;             /* neuralmodes: half-width a of the z box (m) */
    double ortho_weight;    /* neuralmodes: w_o (1e4) */
    double origin_weight;   /* neuralmodes: w_0 (1e4) */
    int threads;            /* energy evaluations in parallel (1) */
    uint64_t seed;
    void (*progress)(void *ctx, long step, double frac, double objective);
    void *progress_ctx;
} crom_df_opts;

/* Defaults of an objective (above); sigma and box are 0: crom_df_train
 * picks 0.05 and 0.1 times the bounding-box diagonal. */
void crom_df_defaults(crom_df_opts *o, int objective);

/* ------------------------------------------------------------- the loss */

/* What one evaluation of the loss gives, besides its value. */
typedef struct {
    double objective; /* L (dimensionless) */
    double energy;    /* mean E_pot (energy) or elastic energy (neuralmodes) of the samples (J) */
    double penalty;   /* energy: mean squared log-ratio; neuralmodes: mean ‖WᵀMy/m‖²/a² */
    double origin;    /* neuralmodes: ‖y(0)‖²_M/(m a²) */
} crom_df_terms;

typedef struct {
    crom_df_problem P;
    crom_df_opts o;
    const crom_nn_mlp *net;  /* r -> 3nv */
    crom_fem fem;            /* rest shapes, volumes, lumped masses */
    crom_nn_ws ws;
    int r, n, maxbatch, nthreads;
    double mass, Eref;
    double *mw;              /* [n] m_i / m per DOF */
    double *MWm;             /* neuralmodes: [n][r] M W / m */
    double *Y, *G, *dY, *E, *xb;
    float *zf, *dyf;
    int *bad;
    double *cb;              /* [r] scratch */
} crom_df_ctx;

/* Set up the loss of options o (objective, sigma, lambda, box, weights,
 * threads) on problem p for network net and batches of up to maxbatch
 * samples. sigma and box must be set (> 0). Returns 0, CROM_EUSAGE (bad
 * sizes), CROM_EDATA (bad mesh), CROM_EINTERNAL (out of memory). */
int crom_df_ctx_init(crom_df_ctx *c, const crom_df_problem *p, const crom_df_opts *o,
                     const crom_nn_mlp *net, int maxbatch);
void crom_df_ctx_free(crom_df_ctx *c);

/* The loss L of B samples z [B][r] at blend rho (energy objective; ignored
 * for neuralmodes, whose origin term is evaluated at an extra z = 0), and
 * if grad != NULL its gradient dL/dparams (overwritten, layout of
 * net->params). Returns 0, or CROM_EDATA for a non-finite energy. */
int crom_df_loss(crom_df_ctx *c, int B, const double *z, double rho, crom_df_terms *t,
                 float *grad);

/* ------------------------------------------------------------- training */

/* The record of a run: per block of steps (about 100 blocks), the mean
 * terms and the wall time at its end; and totals. */
typedef struct {
    int nblocks;
    double *objective, *energy, *penalty, *seconds;
    long steps;
    double seconds_total;
    double sigma, box, Eref; /* as used */
} crom_df_log;

void crom_df_log_free(crom_df_log *l);

/* Train a map on problem p with options o; out gets a model of kind
 * "energy" or "neuralmodes" (mesh copied with its regions; neuralmodes also
 * keeps W and the frequencies) and log the record. Returns 0, CROM_EUSAGE
 * (rank larger than the free degrees of freedom, a free body under gravity,
 * bad options), CROM_EDATA (training diverged) or CROM_EINTERNAL. */
int crom_df_train(const crom_df_problem *p, const crom_df_opts *o, crom_model *out, crom_df_log *log);

/* Write what a data-free model records beyond its basis (after
 * crom_model_write): the options as attributes (sigma, isometry_weight,
 * gravity; latent_box, ortho_weight, origin_weight, modes_id), the body's
 * mass, and the training record (training/objective, /energy, /penalty,
 * /seconds). modes_id may be NULL. Returns 0 or an HDF5 error. */
int crom_df_write_record(hid_t loc, const crom_df_opts *o, const crom_df_problem *p,
                         const crom_df_log *log, double mass, const char *modes_id);

/* Parse flag text ("--youngs 1e6\n--pin clamp\n", as stored in `scenario`
 * attributes) into s with the scenario parser. Unknown flags are skipped.
 * Returns 0 or CROM_EDATA naming the bad flag. */
int crom_df_scenario_parse(const char *text, crom_scenario *s);

#endif
