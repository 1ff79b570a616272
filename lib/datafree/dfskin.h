/* dfskin.h — the weights of a skinning-handle subspace (lib/rom/skin.h), with
 * no simulation data (crom-fitfield --objective skinning).
 *
 * trained (Simplicits, Modi et al. 2024): an ELU MLP 3 -> H' (H' = H − 1
 * after the constant handle of a free body, else H; input normalized to the
 * bounding box) gives w̃(X); the weights are w = s(d(X)/ℓ) w̃ (the pin
 * mask of skin.h; 1 for a free body) with w_0 = 1 on a free body. Each step
 * draws a random cubature of K tets of the training geometry, each standing
 * for nt/K of them (an unbiased estimate of the integral over the body, and
 * lumped masses m̂_v of the drawn tets), whitens the weights over it (ŵ_v =
 * L⁻¹ w_v with G = L Lᵀ below: the energy then depends on their span only,
 * as a Rayleigh–Ritz trace does), draws B random handle poses q_b in handle
 * coordinates (Gaussian; the translations Q_h[c][3] with 90 % of the
 * variance, see dfskin.c; RMS displacement about σ over the body), and
 * minimizes
 *
 *   L = 1/B Σ_b Ê(u_b) / (E_ref d̂²(u_b)) + λ_o ‖G − I‖²_F,
 *   u_b = Ŵ(X) q_b,   d̂²(u) = Σ_v m̂_v |u_v|² / m̂,
 *   G = Σ_v m̂_v w(X_v) w(X_v)ᵀ / m̂,   E_ref = E V / D²,
 *
 * Ê the stable neo-Hookean energy of the drawn tets (no gravity: the
 * weights span deformations, the load comes at run time), V the volume, D
 * the bounding-box diagonal, and the second term Simplicits' orthogonality
 * loss over the sample points, mass-weighted: it keeps the weights
 * orthonormal in the mass mean (so no two handles do the same thing and none
 * vanishes; with the whitening it only keeps G well conditioned) while the
 * energy makes them smooth. Ŵ is W with the whitened weights. Each pose's
 * energy is divided by its mean squared displacement (a Rayleigh quotient,
 * as the eigenproblem below minimizes): Simplicits' plain energy is
 * smallest for vanishing weights and fights the orthogonality term over
 * their scale (measured: with λ_o = 10 the weights shrank to |G − I|² = 14
 * and the subspace did not sag; with λ_o = 1000 they stayed rough), while
 * quotient and whitening leave the energy nothing to gain from the scale.
 * With Adam (lib/nn/nn.h) and the data-free objectives' schedule (the rate
 * halved after each quarter).
 *
 * The training geometry is any crom_mesh: a tet mesh of the body, or the
 * disjoint virtual tets of a point sampling of it (lib/mesh/cloud.h), each a
 * finite-difference stencil of the deformation gradient at its point.
 *
 * eigen (skinning eigenmodes, Benchekroun et al. 2023): no training. The
 * weights are the lowest eigenvectors of K_s w = λ M w on the mesh, K_s the
 * per-vertex scalar matrix of the linear-elasticity Hessian at rest summed
 * over the three components, (K_s)_ij = Σ_c K_(3i+c)(3j+c), and M the lumped
 * mass, pinned vertices eliminated (their weights are 0); ARPACK on a
 * CHOLMOD factor through crom_modes_lowest (lib/phys/modes.h). A free body's
 * constant (the null space of K_s) is built, not searched for, and is
 * handle 0. Weights are scaled to unit RMS over the body (Σ m w² = m) with
 * their largest entry positive.
 */
#ifndef CROM_DFSKIN_H
#define CROM_DFSKIN_H

#include <stdint.h>

#include <hdf5.h>

#include "datafree/dfloss.h"
#include "datafree/dftrain.h"
#include "mesh/mesh.h"
#include "nn/nn.h"
#include "phys/fem.h"
#include "rom/model.h"

/* Trained weights: at most this many handles. */
#define CROM_DFSKIN_MAXH 256

/* The training problem (all borrowed). */
typedef struct {
    const crom_mesh *mesh;        /* training geometry (tets, or virtual tets) */
    crom_material mat;
    const unsigned char *fixed;   /* [3nv] pinned DOFs, or NULL */
    int virtual_tets;             /* 1: mesh is disjoint stencils (lib/mesh/cloud.h):
                                     the mask is only what the next fields
                                     give, not the mesh's pinned part */
    int npin;                     /* pinned points for the mask, [npin][3] */
    const double *pinX;
    int ntri;                     /* pinned triangles for the mask (a sampled */
    const double *triX;           /* surface's), [ntri][3][3] */
    const crom_scenario *materials; /* regions of other materials (--youngs REGION=E), or NULL */
} crom_dfskin_problem;

typedef struct {
    int handles;          /* H */
    int depth, width;     /* weight MLP: dense layers (4) and hidden width (64) */
    crom_nn_act act;      /* ELU */
    int steps;            /* training steps (2000) */
    double minutes;       /* wall-time budget (0: none) */
    double lr;            /* base learning rate (1e-3) */
    int batch;            /* handle poses per step (16) */
    double sigma;         /* RMS displacement of the poses (m; 0: 0.01 D) */
    double ortho_weight;  /* λ_o (1) */
    int tets;             /* cubature tets per step (512) */
    double pin_length;    /* ℓ (m; 0: 0.05 D) */
    int threads;          /* energy evaluations in parallel (1) */
    uint64_t seed;
    void (*progress)(void *ctx, long step, double frac, double objective);
    void *progress_ctx;
} crom_dfskin_opts;

void crom_dfskin_defaults(crom_dfskin_opts *o);

/* Checks shared by both kinds: H >= 1 and 12H <= the free degrees of
 * freedom of the geometry (3 per free vertex). CROM_EUSAGE naming the count. */
int crom_dfskin_check_handles(const crom_mesh *mesh, const unsigned char *fixed, int H);

/* ------------------------------------------------------------- the loss */

typedef struct {
    crom_dfskin_problem P;
    crom_dfskin_opts o;
    const crom_nn_mlp *net;   /* 3 -> H' */
    crom_fem fem;
    crom_material *mats;      /* the problem's regions of other materials (dfloss.h), lent to fem */
    int *tmat;
    crom_nn_ws ws;
    int H, Ht, constant, maxbatch, maxtets, maxrows, nthreads;
    double F[12];             /* body frame */
    double mass, Eref, pin_length;
    int npins, ntri;
    double *pinX, *triX;      /* the pin mask: pinned points, triangles */
    double *mask;             /* [nv] s(d(X_v)/ℓ) */
    crom_dfloss_cub cub;      /* the drawn tets */
    int *bad;
    float *xf, *dwf;
    double *w, *wh, *xh, *L, *U, *gu, *dw, *E, *R, *G, *xb;
} crom_dfskin_ctx;

/* Set up the trained loss (o: handles, sigma, ortho_weight, pin_length,
 * threads) on problem p for network net (3 -> H'), batches of up to maxbatch
 * poses over up to maxtets tets. sigma and pin_length must be set (> 0).
 * Returns 0, CROM_EUSAGE, CROM_EDATA (bad mesh), CROM_EINTERNAL. */
int crom_dfskin_ctx_init(crom_dfskin_ctx *c, const crom_dfskin_problem *p, const crom_dfskin_opts *o, const crom_nn_mlp *net,
                      int maxbatch, int maxtets);
void crom_dfskin_ctx_free(crom_dfskin_ctx *c);

/* The loss L of B poses q [B][12H] (handle coordinates) over the K tets
 * tets [K] (repeats allowed); grad (may be NULL) gets dL/dparams
 * (overwritten, layout of net->params). t->energy is the mean energy of the
 * poses (J), t->penalty ‖G − I‖²_F. Returns 0, CROM_EUSAGE (sizes),
 * CROM_EDATA (a non-finite energy, or a pose that does not move the
 * drawn tets). */
int crom_dfskin_loss(crom_dfskin_ctx *c, int B, const double *q, int K, const int *tets, crom_dftrain_terms *t, float *grad);

/* ------------------------------------------------------------- building */

/* Train the weights on problem p; out gets a trained "skinning" model and
 * log the record (crom_dftrain_log of dftrain.h). CROM_EUSAGE (bad options or
 * handle count), CROM_EDATA (training diverged), CROM_EINTERNAL. */
int crom_dfskin_train(const crom_dfskin_problem *p, const crom_dfskin_opts *o, crom_model *out, crom_dftrain_log *log);

/* Skinning eigenmodes of a tet mesh: H handles for material mat (and the
 * regions of other materials of materials, may be NULL) with the DOFs fixed
 * [3nv] (NULL: a free body) pinned. out gets an "eigen" skinning model on
 * that mesh; *solves (may be NULL) the factor solves. CROM_EUSAGE (handle
 * count; a bad region), CROM_EDATA (bad mesh), CROM_EINTERNAL. */
int crom_dfskin_eigen(const crom_mesh *mesh, const crom_material *mat, const crom_scenario *materials,
                      const unsigned char *fixed, int H, crom_model *out, long *solves);

/* Write what a skinning model records beyond its basis (after
 * crom_model_write): the body's mass and, for trained weights (log not
 * NULL), the options as attributes (training_steps, sigma as used,
 * ortho_weight, cubature_tets) and the training record
 * (training/objective, /energy, /penalty, /seconds). Returns 0 or an HDF5
 * error. */
int crom_dfskin_write_record(hid_t loc, const crom_dfskin_opts *o, const crom_dftrain_log *log, double mass);

#endif
