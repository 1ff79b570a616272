/* dffield.h — a CONTINUOUS data-free subspace (crom-fitfield --objective
 * field; beyond both papers; crom/model basis "energy-field"):
 *
 *   x(X, z) = X + W(X) (φ(z) − φ(0))
 *
 * with W a neural field 3 -> 3p over the body (LiCROM's representation,
 * laid on any mesh) and φ an ELU MLP r -> p, trained on the energy loss of
 * datafree.h with the integrals over the body replaced by a random cubature
 * drawn afresh each step: K tets, each standing for nt/K of them (an
 * unbiased estimate of E and of the gravity potential, lumped masses of the
 * drawn tets for M), so W is evaluated only at their vertices:
 *
 *   L = 1/B Σ_b Ê_pot(X + ρ W Φ_b) / (E V)
 *     + λ · mean over pairs ( log( D̂_bc / (σ ‖z_b − z_c‖) ) )² + λ_0 · (as in datafree.h),
 *
 *   Φ_b = φ(z_b) − φ(0),  D̂²_bc = ΔΦᵀ Ĝ ΔΦ / m̂,  Ĝ = Σ_v m̂_v W(X_v)ᵀ W(X_v),
 *
 * with z ~ N(0, I) and ρ ramped as in datafree.h. Pins are built in as a
 * mask over space: W(X) = s(d(X)/ℓ) W̃(X), s the smoothstep 3t² − 2t³ (1
 * for t >= 1) and d the distance to the pinned part of the training mesh:
 * its boundary triangles with three pinned vertices, and its pinned
 * vertices (for pins off the boundary), stored in the model with ℓ; so the
 * field is exactly zero on a pinned face of the body on ANY mesh of it, and
 * the reduced simulation's own penalty holds whatever else a region pins.
 * (A penalty on the pins instead competes with the energy, which is weak
 * in units of E V, and the trained map then barely moves under gravity.)
 *
 * The problem and the options are those of datafree.h (crom_datafree_problem,
 * crom_datafree_opts with objective CROM_DATAFREE_FIELD); training is Adam
 * on the loop of the data-free trainers (dftrain.h).
 */
#ifndef CROM_DFFIELD_H
#define CROM_DFFIELD_H

#include "datafree/datafree.h"
#include "datafree/dfloss.h"
#include "nn/nn.h"
#include "phys/fem.h"
#include "rom/model.h"

typedef struct {
    crom_datafree_problem P;
    crom_datafree_opts o;
    const crom_nn_mlp *W, *phi; /* 3 -> 3p (NULL over a fixed basis) and r -> p */
    const double *basis;     /* a fixed basis [nv][3][p] in place of W(X_v), or NULL */
    crom_fem fem;
    crom_material *mats;     /* the problem's regions of other materials (dfloss.h), lent to fem */
    int *tmat;
    crom_nn_ws wsW, wsP;
    int r, p, maxbatch, maxtets, maxrows, nthreads, npins;
    int B0;                  /* tangent samples after the batch (0: none) */
    double mass, Eref, pin_length;
    crom_dfloss_cub cub;     /* the drawn tets */
    int *bad;
    float *xf, *zf, *dFf, *dPf;
    double *pinX;            /* [npins][3] pinned vertices' positions */
    int ntri;                /* pinned boundary triangles */
    double *triX;            /* [ntri][3][3] their corners */
    double *mask;            /* [nv] s(d(X_v)/ℓ) */
    double *F, *Phi, *gu, *dF, *dPhi, *E, *G, *S, *tmp, *xb;
    double *tg;              /* [3 r r + r] the collapse floor's Gram matrix, gradient, scratch */
} crom_dffield_ctx;

/* Set up the loss of the continuous field (objective field: o->sigma,
 * lambda, pin_length, threads) for networks W (3 -> 3p, unmasked) and phi
 * (r -> p), batches of up to maxbatch samples over up to maxtets tets; or,
 * with W NULL, for phi over the fixed basis [nv][3][p] (borrowed; it holds
 * the pins itself: no mask).
 * Returns 0, CROM_EUSAGE (bad sizes), CROM_EDATA (bad mesh),
 * CROM_EINTERNAL (out of memory). */
int crom_dffield_ctx_init(crom_dffield_ctx *c, const crom_datafree_problem *p, const crom_datafree_opts *o,
                          const crom_nn_mlp *W, const double *basis, const crom_nn_mlp *phi, int maxbatch,
                          int maxtets);
void crom_dffield_ctx_free(crom_dffield_ctx *c);

/* The loss L of B samples at blend rho over the K tets tets [K] (repeats
 * allowed): z holds [B + c->B0][r], the batch then the tangent samples. If
 * gW, gP != NULL, its gradients with respect to the parameters of W and
 * phi (overwritten). t->penalty is the isometry term, t->tangent the one
 * at rest. Returns 0, CROM_EUSAGE (sizes), CROM_EDATA (a non-finite
 * energy). */
int crom_dffield_loss(crom_dffield_ctx *c, int B, const double *z, double rho, int K, const int *tets,
                      crom_dftrain_terms *t, float *gW, float *gP);

/* Train the continuous field on problem p with options o (crom_datafree_train
 * calls it for CROM_DATAFREE_FIELD); out gets a model of kind "energy-field"
 * and log the record. Returns 0, CROM_EUSAGE (bad options, a free body
 * under gravity), CROM_EDATA (training diverged) or CROM_EINTERNAL. */
int crom_dffield_train(const crom_datafree_problem *p, const crom_datafree_opts *o, crom_model *out,
                       crom_dftrain_log *log);

/* The defaults of φ over a fixed basis, on top of the field's
 * (crom_datafree_defaults): a weak isometry λ = 0.03 with the isometry at
 * rest λ_0 = 0.1 (as the energy map), and sigma 0, which
 * crom_dffield_train_latent takes as 0.15 times the bounding-box diagonal:
 * measured on the soft bar of issue 14 (README, "Benchmarks"), λ = 1 left
 * the static sag 80 % off, σ = 0.05 diag 35 %, against 11 % here. */
void crom_dffield_latent_defaults(crom_datafree_opts *o);

/* Train φ alone over a FIXED linear basis of the body (basis [nv][3][pdim]
 * at the vertices of p->mesh, e.g. skinning eigenmodes: crom-fitfield
 * --objective field --handles H; crom/model basis "skin-field"), with the
 * loss and the schedule of the field: x(X, z) = X + W(X) (φ(z) − φ(0)) with
 * W the basis. o->features is not used. phi gets the network r -> pdim
 * (freed by the caller) and log the record. Returns as crom_dffield_train. */
int crom_dffield_train_latent(const crom_datafree_problem *p, const crom_datafree_opts *o, const double *basis,
                              int pdim, crom_nn_mlp *phi, crom_dftrain_log *log);

#endif
