/* dfloss.h — the pieces the data-free losses share (datafree.c, dffield.c,
 * dfskin.c).
 *
 * The random cubature: K tets drawn from the nt of the training mesh (with
 * repeats), each standing for nt/K of them, so that a sum over the drawn
 * tets is an unbiased estimate of the integral over the body; the lumped
 * masses of the drawn tets (ρ V_t / 4 to each corner, times nt/K) stand for
 * the mass matrix. The continuous subspaces evaluate their networks only at
 * the drawn tets' vertices, each given a row (in order of first appearance).
 *
 * The anchor: every data-free map is taken relative to its network's value
 * at z = 0 (lib/rom/map.h), N(z) − N(0), with z = 0 run as the last row of
 * the batch; the gradient then flows through it, dL/dN(0) = −Σ_b dL/dN(z_b).
 *
 * The pin mask of the continuous subspaces vanishes on the pinned part of
 * the training mesh: its vertices with a pinned DOF, and its boundary
 * triangles whose three vertices are pinned.
 */
#ifndef CROM_DFLOSS_H
#define CROM_DFLOSS_H

#include "datafree/dftrain.h"
#include "mesh/mesh.h"
#include "phys/fem.h"
#include "phys/scenario.h"

/* The drawn tets' vertices and their lumped masses. */
typedef struct {
    int nv, maxrows;
    int *loc;        /* [nv] a vertex's row among the drawn ones, -1 if not drawn */
    int *vs;         /* [maxrows] the drawn vertices, in order of first appearance */
    int ns;          /* drawn vertices */
    double *mloc;    /* [maxrows] their lumped masses (kg) */
    double mhat;     /* Σ mloc */
    double wK;       /* nt / K */
} crom_dfloss_cub;

/* Room for up to maxrows drawn vertices of a mesh of nv. CROM_EINTERNAL. */
int crom_dfloss_cub_init(crom_dfloss_cub *c, int nv, int maxrows);
void crom_dfloss_cub_free(crom_dfloss_cub *c);

/* Draw the K tets tets [K] of fem: their vertices, and their lumped masses
 * at density rho. Returns 0, or CROM_EUSAGE for a tet out of range or more
 * than maxrows vertices (then nothing stays drawn). */
int crom_dfloss_cub_draw(crom_dfloss_cub *c, const crom_fem *fem, double rho, int K, const int *tets);

/* Forget the drawn vertices (before the next draw). */
void crom_dfloss_cub_clear(crom_dfloss_cub *c);

/* The energy Σ_k wK E_k of the K tets tets [K] at the positions X + u (X
 * NULL: u holds the positions), with u and the gradient g indexed by a
 * vertex's row loc[v] (loc NULL: by v); the gradient is added to g, the
 * energy stored in *E. Returns 0, or 1 at a tet whose energy or gradient
 * is not finite, where it stops. */
int crom_dfloss_tets(const crom_fem *fem, int K, const int *tets, double wK, const double *X, const double *u,
                     const int *loc, double *E, double *g);

/* CROM_EDATA naming the first of the B samples ("sample", "pose") whose
 * energy could not be evaluated (bad) or is not finite; else 0. */
int crom_dfloss_check(int B, const int *bad, const double *E, const char *what);

/* Store the terms in t (may be NULL). Returns 0, or CROM_EDATA where the
 * objective obj is not finite ("the <what> objective is not finite"). */
int crom_dfloss_terms(crom_dftrain_terms *t, double obj, double energy, double penalty, double tangent,
                      const char *what);

/* The float gradient out [rows][n] of a network run on rows inputs whose
 * last is the anchor, from the gradient d [rows - 1][n] of the outputs
 * relative to it: out_b = d_b (0 where mask [n] is set; mask may be NULL),
 * out_anchor = −Σ_b out_b. */
void crom_dfloss_anchor_grad(int rows, int n, const double *d, const unsigned char *mask, float *out);

/* The collapse floor at rest, the mode-collapse measure of Neural Modes
 * §4.4 made a loss. G [r][r] is the Gram matrix of the map's secants from
 * rest along the r latent axes (at any common scale: G_kl = Y_kᵀ M Y_l
 * with Y_k = x(ε e_k) − X), μ_k the eigenvalues of r G / tr G. Returns
 * Σ_k h(μ_k), h(μ) = log²(μ / τ) below the floor tau and 0 above (C¹ at τ),
 * and A [r][r] = w dΣh/dG = w (r/T) [V diag(h'(μ)) Vᵀ − (Σ_k h'(μ_k) λ_k / T) I]
 * (T = tr G, λ_k the eigenvalues, V the eigenvectors). Only G's upper
 * triangle is read. work: [r r + r].
 * Returns NAN where tr G is not positive and finite or the eigensolve fails
 * (A then zero). */
double crom_dfloss_rest_floor(int r, const double *G, double tau, double w, double *A, double *work);

/* The thread's number inside a parallel region (0 without OpenMP). */
int crom_dfloss_thread(void);

/* Whether vertex v has a pinned DOF in fixed [3nv] (NULL: nothing pinned). */
int crom_dfloss_pinned(const unsigned char *fixed, int v);

/* The regions of other materials of scenario sc (--youngs REGION=E; NULL
 * or none: nothing to do) on the tets of fem, a solid of mesh m: *mats and
 * *tmat (malloc'ed, the caller frees them after fem) are lent to fem
 * (crom_fem_set_materials). Returns 0 or the errors of
 * crom_scenario_materials. */
int crom_dfloss_materials(crom_fem *fem, const crom_scenario *sc, const crom_mesh *m, crom_material **mats,
                          int **tmat);

/* The pinned part of mesh m under fixed: its vertices with a pinned DOF
 * (*pinX [npins][3]) and its boundary triangles whose three vertices are
 * pinned (*triX [ntri][3][3]), malloc'ed with room for extra_pins points
 * and extra_tris triangles more. CROM_EINTERNAL. */
int crom_dfloss_pinned_part(const crom_mesh *m, const unsigned char *fixed, int extra_pins, int extra_tris,
                            int *npins, double **pinX, int *ntri, double **triX);

#endif
