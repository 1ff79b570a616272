/* datafree.h — subspaces learned from the energy alone, with no simulation
 * data (crom-fitfield --objective energy|neuralmodes|field).
 *
 * Every map is ANCHORED at the rest shape (lib/rom/map.h): its network's value
 * at z = 0 is subtracted, N(z) − N(0), so x(0) = X exactly, and the losses
 * below are taken on that same anchored map (the network is also run at
 * z = 0 in every step, and the gradient flows through the anchor: dL/dN(0)
 * = −Σ_b dL/dN(z_b)). A run from rest then starts at z = 0 (lib/rom/nlsim.h).
 *
 * energy and neuralmodes learn a map of a latent q in R^r to the positions
 * of every vertex of ONE mesh (crom/model basis "energy" or "neuralmodes", lib/rom/map.h):
 *
 * Conditional (Sharp et al. §3.5, problem.ncond > 0, energy only): the
 * network takes [z, c], c a few scenario parameters (phys/scenario.h:
 * the modulus ratio of a region, a gravity component); each batch draws
 * one c uniformly from their ranges and the loss is the same at that c (the
 * anchor too: x(0, c) = X for every c). The batch's c is taken from the
 * batch's own latents, u_k = Φ(Σ_b ±z_{b,k mod r} / √B), uniform for z ~
 * N(0, I), so it holds while L-BFGS iterates on a batch.
 *
 * energy (Sharp et al. 2023, "Data-Free Learning of Reduced-Order
 * Kinematics", eq. 4 and §4.1): x(z) = X + N(z) − N(0), N an ELU MLP r ->
 * 3nv (5 hidden layers), trained on batches of z ~ N(0, I) to minimize
 *
 *   L = 1/B Σ_b E_pot(X + ρ Y_b) / (E V)
 *     + λ · mean over the pairs b < c of ( log( D_bc / (σ ‖z_b − z_c‖) ) )²
 *     + λ_0 · Σ_k h(μ_k),
 *
 *   Y_b = N(z_b) − N(0),  D_bc = sqrt( (Y_b − Y_c)ᵀ M (Y_b − Y_c) / m ),
 *   μ_k the eigenvalues of r G / tr G, G_kl = Y_kᵀ M Y_l / m over the secants
 *   Y_k = N(ε e_k) − N(0) along the r latent axes, h(μ) = log²(μ/τ) for μ < τ,
 *
 * with E_pot the stable neo-Hookean energy plus the potential of gravity
 * −Σ_v m_v g·u_v, M the lumped mass and m the body's mass (so D and σ are
 * RMS displacements in metres: the paper's ‖·‖_M divided by sqrt(m)), E V
 * Young's modulus times the volume (the energy unit that makes L
 * dimensionless), and ρ the seed-state blend of §4.1 with the rest state as
 * seed: X + ρ Y, σ scaled by ρ too, which cancels in the log-ratio. ρ grows
 * linearly from 0 to 1 over the first `ramp` fraction of the steps, then
 * stays 1, so the map that is stored (ρ = 1) is the one trained last. The
 * last term is the collapse floor AT REST (Neural Modes §4.4's measure of
 * mode collapse made a loss; ε = 0.1, τ = 0.03, energy not evaluated at the
 * secants): it is zero while every latent direction moves the body at rest
 * by at least a fraction of the mean, and otherwise pushes the smallest
 * normalized eigenvalues up; without it a weak isometry (small λ) lets some
 * latent directions collapse at rest, where every run starts, and the first
 * step of a run from rest misses part of the fall. Pinned vertices are built in: their outputs are masked
 * in the loss and their rows of the last layer are zero, so the stored map
 * holds them exactly at rest.
 *
 * neuralmodes (Wang et al. 2024, "Neural Modes", eq. 12–13): x(z) = X + W z
 * + y(z), y = N(z) − N(0) (so y(0) = 0 exactly, which Wang et al. ask of
 * a penalty), on the r lowest linear modes W (crom-modes, orthonormal in
 * the mass mean: WᵀMW = m I, q in metres), N a GELU MLP r -> 3nv, trained
 * on z uniform in a box to minimize
 *
 *   L = 1/B Σ_b [ E(X + W z_b + y(z_b)) / E_ref + w_o ‖Wᵀ M y(z_b) / m‖² / a² ],
 *
 * the elastic energy (no gravity: nonlinear modes are equilibria of the
 * elastic energy in the space M-orthogonal to the linear ones) and a
 * penalty keeping y M-orthogonal to the linear span. The box: z_k in
 * [−a_k, a_k] with a_k = a f_1 / f_k (box_scaled, the default: the same
 * linear energy ½ m ω_k² a_k² at every edge) or a_k = a (Wang et al.);
 * E_ref = ½ m ω² a² with ω the lowest (scaled) or highest (uniform) mode's
 * (E V if that is zero). The default w_o = 1e4 holds the projection of y
 * onto the modes to about 1 % of the box. With modal derivatives Ψ of the
 * modes (Barbič and James 2005; crom-fitfield --derivatives) the map is
 * seeded with the second-order term, x = X + W z + ½ Σ_{i<=j} Ψ_ij z_i z_j
 * + y(z): the in-plane shortening that keeps bent modes of a shell or a
 * slender body from stretching (locking), which y is slow to learn alone. The last layer starts at zero:
 * training starts from the linear modes.
 *
 * The supervised baseline of Wang et al. (their "L2 supervised" row,
 * Table 2): the same map fitted to constrained equilibria u*_k at modal
 * coordinates z_k (crom-fullsim --equilibria) by the geometric loss
 * 1/B Σ_b |u(z_b) − u*_b|²_M / (m a²) plus the same orthogonality penalty,
 * with z_b drawn from the equilibria (problem.nsup > 0): the energy is
 * then only recorded.
 *
 * Sampling along a run (problem.nvisit > 0, beyond both papers): the box
 * holds the small deformations, but a large one (a soft body sagging far
 * under its load) projects onto the modes outside it, most on the stiffer
 * modes (issue 14: mode 6 at 3.8 times its half-width), where a map
 * trained on the box extrapolates. Given the modal coordinates a reduced
 * run of the map's seed visited (crom-reducedstep --model, no full
 * simulation), every other sample of a batch is one of them, picked
 * uniformly, moved by up to VISIT_JITTER of max(a_k, |z_k|) per
 * coordinate; the loss is the same energy, so the map learns the
 * constrained equilibria where the run goes (still data-free).
 *
 * Refining an energy map along a run (problem.init and nvisit, beyond the
 * paper): training starts from a trained map's network at ρ = 1, and every
 * other sample of a batch is a latent a reduced run of that map visited,
 * picked uniformly, plus VISIT_JITTER times a N(0, I) draw: the map's
 * energy is lowered where the run went (a bistable bar's second
 * equilibrium, which the samples of N(0, I) seldom reach; a soft bar's
 * static sag error from 6-28% to 1.5-7.6% over four seeds). Still
 * data-free: the run is in the subspace. A continuous field (dffield.h) is
 * refined the same way: φ (and W(X) unless the basis is fixed) from the
 * trained field, every other sample near a latent its run visited (a soft
 * bar's static sag error from 18-19% to 4.4-9.3% for the field over
 * skinning eigenmodes).
 *
 * field (beyond both papers): a CONTINUOUS data-free subspace x(X, z) = X
 * + W(X) (φ(z) − φ(0)), W a neural field over the body, trained on the
 * energy loss above integrated by a random cubature of the mesh: dffield.h.
 * The one-mesh maps take the same random cubature on request (`tets`).
 *
 * Training: Adam on a fresh batch every step, learning rate halved after
 * each quarter of the steps (the paper's schedule, on a shorter run); or
 * L-BFGS with a backtracking line search (Wang et al.'s optimizer,
 * lib/base/lbfgs.h), `resample` iterations on each batch (the loop of
 * dftrain.h, shared with the field and the skinning weights). The defaults come from
 * issue 14's measurements on a soft clamped bar sagging under gravity (a
 * third of its length; README, "Benchmarks"): for the one-mesh maps many
 * small steps (batch 8, rate 3e-3) beat fewer large ones at equal time;
 * energy: a weak isometry (λ = 0.03: at λ = 1 the isometry swamps the
 * energy, which is ~1e-3 in units of E V, and the static sag misses by
 * 40-80 %) with the collapse floor at rest (λ_0 = 0.03, τ = 0.03); neuralmodes: the
 * frequency-scaled box, half-width 0.2 × the bounding-box diagonal for
 * the lowest mode (a uniform box spends the loss on the stiff modes:
 * static sag 84 % off against 16 % at 4000 steps). The energies of the B
 * samples are computed in parallel over `threads` threads, each sample
 * serially, so results do not depend on the thread count; the network runs
 * single-threaded (float32), the losses in double.
 */
#ifndef CROM_DATAFREE_H
#define CROM_DATAFREE_H

#include <stdint.h>

#include <hdf5.h>

#include "datafree/dftrain.h"
#include "mesh/mesh.h"
#include "nn/nn.h"
#include "phys/fem.h"
#include "phys/system.h"
#include "phys/scenario.h"
#include "rom/model.h"

enum { CROM_DATAFREE_ENERGY = 1, CROM_DATAFREE_NEURALMODES = 2, CROM_DATAFREE_FIELD = 3 };
enum { CROM_DATAFREE_ADAM = 0, CROM_DATAFREE_LBFGS = 1 };

/* The physical problem (all borrowed). */
typedef struct {
    const crom_mesh *mesh;
    crom_material mat;
    double gravity[3];           /* m/s² (energy objective only) */
    const unsigned char *fixed;  /* [3nv] pinned DOFs, or NULL */
    const double *modes;         /* neuralmodes: W [nv][3][r] */
    const double *freq;          /* neuralmodes: [r] frequencies (Hz), or NULL */
    const double *deriv;         /* neuralmodes: the modal derivatives Ψ [nv][3][r(r+1)/2] of W
                                  * (lib/phys/mderiv.h, in m⁻¹), or NULL: the map is then
                                  * X + W z + ½ Σ_{i<=j} Ψ_ij z_i z_j + y(z) */
    int nsup;                    /* neuralmodes supervised by nsup constrained equilibria (0: data-free) */
    const double *sup_z;         /* [nsup][r] their modal coordinates (m) */
    const double *sup_u;         /* [nsup][3nv] their displacements (m) */
    long nvisit;                 /* neuralmodes: modal coordinates a reduced run visited (0: none); energy
                                  * and field (with init): latents a reduced run of init visited; */
    const double *visit_z;       /* [nvisit][r]: every other sample of a batch is drawn near one of them */
    const crom_scenario *materials; /* its regions of other materials (--youngs REGION=E), or NULL */
    int ncond;                   /* energy: a conditional map (Sharp et al. §3.5) over ncond scenario
                                  * parameters, cond [ncond] with the ranges they are drawn from;
                                  * a ratio's region must be one of materials' regions */
    const crom_scenario_cond *cond;
    const double *seed;          /* energy: [3nv] the seed state's displacement u_s (Sharp et al. §4.1; a
                                  * low-energy state, e.g. a buckled equilibrium from crom-fullsim, whose
                                  * pinned vertices are where the pins hold them), or NULL: the rest
                                  * shape. The map is anchored there, x(z) = X + u_s + N(z) − N(0), and
                                  * the energy is taken at X + u_s + ρ Y (the seed blend of §4.1) */
    const crom_nn_mlp *init;     /* energy: start from this network (a trained map of the same problem and
                                  * shape: crom-fitfield --init-model) at ρ = 1, no seed blend; field over
                                  * a fixed basis (dffield.h): φ of the same shape to start from; or NULL */
    const crom_nn_mlp *init_field; /* field (with init, its φ): the feature field W(X) to start from, or NULL */
} crom_datafree_problem;

typedef struct {
    int objective;          /* CROM_DATAFREE_ENERGY or CROM_DATAFREE_NEURALMODES */
    int rank;               /* r */
    int depth, width;       /* dense layers (6: 5 hidden) and hidden width (64) */
    crom_nn_act act;        /* ELU (energy) or GELU (neuralmodes) */
    int steps;              /* training steps (4000; field: 2000); neuralmodes may take 0: y = 0, the map
                             * is its linear part (and, with modal derivatives, the quadratic manifold
                             * X + W z + ½ Σ Ψ_ij z_i z_j of Barbič and James) */
    double minutes;         /* wall-time budget (0: none) */
    double lr;              /* base learning rate (3e-3; field: 1e-3); L-BFGS: the size of its first step */
    int optimizer;          /* CROM_DATAFREE_ADAM or CROM_DATAFREE_LBFGS (energy, neuralmodes) */
    int resample;           /* L-BFGS: iterations on each batch before a fresh one (10) */
    double tangent_weight;  /* energy, field: λ_0, weight of the collapse floor at rest (0.03; field: 0) */
    double tangent_floor;   /* energy, field: its floor τ on the normalized Gram eigenvalues (0.03) */
    double tangent_radius;  /* energy, field: the length ε of its r secants z = ε e_k (0.1) */
    int batch;              /* samples per step (8; field: 32) */
    double sigma;           /* energy: isometry scale, RMS metres per unit z */
    double lambda;          /* energy: isometry weight (0.03; field: 1) */
    double ramp;            /* energy: fraction of the steps over which ρ grows (0.5) */
    double box;             /* neuralmodes: half-width a of the z box (m) */
    int box_scaled;         /* neuralmodes: 1 (default): mode k's half-width is a f_1 / f_k */
    double ortho_weight;    /* neuralmodes: w_o (1e4) */
    int tangent_anchor;     /* neuralmodes: 1: y(z) = N(z) − N(0) − J_N(0) z, so that y = O(z²) and the map's
                             * tangent at rest is the modes' exactly (trained with J_N(0) z as the central
                             * difference (N(ε z) − N(−ε z)) / 2ε, ε = TANGENT_EPS; the model evaluates it
                             * exactly) */
    int features;           /* field: p, the feature fields of W (32) */
    int field_depth, field_width; /* field: dense layers (4) and hidden width (64) of W */
    int tets;               /* tets of the random cubature per step (field: 512; maps: 0, every tet) */
    double pin_length;      /* field: width of the mask at the pins (m; 0: twice the mean edge) */
    int threads;            /* energy evaluations in parallel (1) */
    uint64_t seed;
    void (*progress)(void *ctx, long step, double frac, double objective);
    void *progress_ctx;
} crom_datafree_opts;

/* Defaults of an objective (above); sigma and box are 0: crom_datafree_train
 * picks 0.05 and 0.1 times the bounding-box diagonal. */
void crom_datafree_defaults(crom_datafree_opts *o, int objective);

/* ------------------------------------------------------------- the loss */

typedef struct {
    crom_datafree_problem P;
    crom_datafree_opts o;
    const crom_nn_mlp *net;  /* r -> 3nv */
    crom_system sys;         /* the mesh's system (a solid or a shell): elements, lumped masses */
    crom_nn_ws ws;
    int r, n, maxbatch, nthreads;
    int B0;                  /* tangent samples after the batch (0: none) */
    double mass, Eref;
    double *mw;              /* [n] m_i / m per DOF */
    double *MWm;             /* neuralmodes: [n][r] M W / m */
    double *Y, *G, *dY, *E, *xb;
    float *zf, *dyf;
    int *bad;
    double *cb;              /* [r] scratch */
    double *half;            /* neuralmodes: [r] half-widths of the box per mode */
    double *tg;              /* [3 r r + r] the collapse floor's Gram matrix, gradient, scratch */
    const int *sup;          /* supervised: the equilibrium of each batch sample (set by the caller per batch) */
    /* a conditional map: the network takes [z, c] (in = r + ncond inputs); the
     * batch's c (crom_datafree_set_condition) sets the materials and the
     * gravity the energy is taken with */
    int in;
    double *cond;            /* [ncond] c of the batch */
    int *cond_mat;           /* [ncond] a ratio's material in sys.mats (−1: gravity) */
    double grav[3];          /* the gravity of the batch */
    double *Ec;              /* [maxbatch][ncond] ∂E_b/∂c_k, explicit */
    float *dxf;              /* [rows][in] dL/d(network input) */
    double *dcond;           /* [ncond] dL/dc of the last loss with a gradient */
    double *lift;            /* [ncond][3nv] a pin condition's static lift (phys/mderiv.h; 0 for the others) */
    double *pinoff;          /* [3nv] Σ_k c_k lift_k: the pins moved and the body's lift at the batch's c
                              * (NULL: no pin condition) */
} crom_datafree_ctx;

/* Set the batch's condition c [ncond] (energy objective, conditional):
 * ratio k gives its region's tets the modulus c_k E (the region's own
 * Poisson ratio), gravity sets its component, a pin moves its (pinned)
 * region by c_k along its axis and the body with it by c_k times its static
 * lift (the small-displacement equilibrium of a unit move; the energy's
 * ∂E/∂c_k is then its gradient along the lift, the pins' DOFs included). Returns 0 or CROM_EDATA for
 * a ratio not positive or a value not finite. */
int crom_datafree_set_condition(crom_datafree_ctx *c, const double *cond);

/* Set up the loss of options o (objective, sigma, lambda, box, weights,
 * threads) on problem p for network net and batches of up to maxbatch
 * samples. sigma and box must be set (> 0). Returns 0, CROM_EUSAGE (bad
 * sizes), CROM_EDATA (bad mesh), CROM_EINTERNAL (out of memory). */
int crom_datafree_ctx_init(crom_datafree_ctx *c, const crom_datafree_problem *p, const crom_datafree_opts *o,
                     const crom_nn_mlp *net, int maxbatch);
void crom_datafree_ctx_free(crom_datafree_ctx *c);

/* The loss L of B samples at blend rho (energy objective; ignored for
 * neuralmodes): z holds [B + c->B0][r], the batch then the tangent
 * samples. The energy is integrated over every tet (tets NULL) or over the
 * K tets tets [K] (repeats allowed), each weighted nt/K. If grad != NULL,
 * its gradient dL/dparams (overwritten, layout of net->params). Returns 0,
 * CROM_EUSAGE (sizes, a tet out of range), or CROM_EDATA for a non-finite
 * energy. */
int crom_datafree_loss(crom_datafree_ctx *c, int B, const double *z, double rho, int K, const int *tets, crom_dftrain_terms *t,
                 float *grad);

/* ------------------------------------------------------------- training */

/* Train a map on problem p with options o; out gets a model of kind
 * "energy" or "neuralmodes" (mesh copied with its regions; neuralmodes also
 * keeps W and the frequencies) and log the record. Returns 0, CROM_EUSAGE
 * (rank larger than the free degrees of freedom, a free body under gravity,
 * bad options), CROM_EDATA (training diverged) or CROM_EINTERNAL. */
int crom_datafree_train(const crom_datafree_problem *p, const crom_datafree_opts *o, crom_model *out, crom_dftrain_log *log);

/* Write what a data-free model records beyond its basis (after
 * crom_model_write): the options as attributes (sigma, isometry_weight,
 * gravity; latent_box, ortho_weight, origin_weight, modes_id), the body's
 * mass, and the training record (training/objective, /energy, /penalty,
 * /seconds). modes_id may be NULL. Returns 0 or an HDF5 error. */
int crom_datafree_write_record(hid_t loc, const crom_datafree_opts *o, const crom_datafree_problem *p,
                         const crom_dftrain_log *log, double mass, const char *modes_id);


/* A batch drawn along a run (datafree.h: sampling along a run, refining):
 * z [B + B0][r] the loop's draws (normal != 0: N(0, I), else uniform in
 * the box of half-widths half [r]); out gets them with every odd sample of
 * the batch moved to a point of visit_z [nvisit][r] (picked by the draw's
 * first coordinate) plus VISIT_JITTER times the rest of the draw (times
 * max(half_k, |z_k|) for a box), and the B0 samples after the batch as they
 * are. */
void crom_datafree_visit_draw(int normal, int B, int B0, int r, const double *z, const double *half, long nvisit,
                              const double *visit_z, double *out);

#endif
