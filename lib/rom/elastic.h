/* elastic.h — the elastic energy of a linear subspace over a cubature,
 * evaluated in the space of deformation gradients (rom layer).
 *
 * In a linear subspace x_v = X_v + W_v q the deformation gradient of every
 * tet is affine in q: vec F_k(q) = F0_k + G_k q, with G_k = ∂ vec F_k / ∂q
 * the [9][r] matrix Σ_a ∇N_a ⊗ W_a (row 3c + j: Σ_a ∂N_a/∂X_j W_a[c][:]).
 * So over a cubature of K tets with weights w_k and rest volumes V_k
 * (LiCROM eq. 7–8):
 *
 *   E(q) = Σ_k w_k V_k Ψ(F_k),   g = Σ_k w_k V_k G_kᵀ vec P(F_k),
 *   H = Σ_k w_k V_k G_kᵀ (∂P/∂F)(F_k) G_k,
 *
 * with G_k computed once per cubature (9 r numbers per tet instead of the
 * 12 r of the basis at its corners), and H formed by one matrix product over
 * all tets (Gᵀ Y with G stacked [9K][r], Y = blockdiag(w V ∂P/∂F) G): 18 K r²
 * flops against 24 K r² for W_eᵀ H_e W_e per tet, in one BLAS call. The F of
 * all tets is one product G q and the gradient one product Gᵀ p (p the
 * stacked w V vec P), so that an evaluation without Hessian is two BLAS
 * calls and the per-tet material law.
 *
 * A basis that moves the three components by the same functions — W_v =
 * I₃ ⊗ ψ_vᵀ, r = 3S, as the orthonormal coordinates of a skinning subspace
 * (lib/rom/skin.h) — has G_k = I₃ ⊗ B_k with B_k = Σ_a ∇N_a ψ_aᵀ [3][S];
 * then only B_k is stored (3 S numbers per tet), F, g cost 9 S per tet (the
 * F of all tets one product [3K][S][3], the gradient one [3][3K][S]), and the
 * blocks (c, d ≥ c) of block row c of H are one product Bᵀ [Y_cc … Y_c2] of
 * [S][3K][(3 − c)S], Y_cd = blockdiag(w V ∂P/∂F[c rows][d cols]) B, the
 * blocks below the diagonal their transposes (36 K S² = 4 K r² flops in
 * all). The structure is detected exactly.
 */
#ifndef CROM_ELASTIC_H
#define CROM_ELASTIC_H

#include "phys/fem.h"
#include "rom/cubature.h"

typedef struct {
    int r, k;       /* latent dimension, cubature tets */
    int block;      /* 1: W_v = I₃ ⊗ ψ_vᵀ, S = r / 3 (see above) */
    int S;          /* block: functions per component */
    int m;          /* columns of G: S (block) or r */
    int rows;       /* rows of G per tet: 3 (block) or 9 */
    double *G;      /* [k][rows][m]: B_k (block) or G_k */
    double *F0;     /* [k][9] F_k(0), the rest (I up to round-off) */
    double *wV;     /* [k] w_k V_k */
    double *Y;      /* [k][rows][m] Hessian scratch (block: [k][3][3S]) */
    double *A;      /* [k][81] ∂P/∂F of the last Hessian evaluation */
    double *Hb;     /* block: [S][3S] scratch */
    double *Fq;     /* [k][9] G_k q of the last evaluation */
    double *Pm;     /* [k][9] w_k V_k vec P(F_k) of the last evaluation */
    const crom_material *const *kmat; /* [k] each tet's material (regions of other materials;
                                       * borrowed, set by the caller); NULL: eval's for all */
} crom_elastic;

/* Precompute G_k, F0_k and w_k V_k of every tet of cubature c (borrowed
 * only during the call). Returns 0 or CROM_EINTERNAL. */
int crom_elastic_init(crom_elastic *e, const crom_cubature *c);

/* Release what init allocated (safe on a zeroed struct). */
void crom_elastic_free(crom_elastic *e);

/* E(q) into *E; adds the gradient to g [r] and the Hessian (both triangles)
 * to H [r][r] when they are not NULL. project: SPD-projected ∂P/∂F
 * (crom_fem_dPdF). Returns 0, or CROM_EDATA naming the cubature tet where
 * the energy or a derivative is not finite. */
int crom_elastic_eval(crom_elastic *e, const crom_material *mat, const double *q, int project, double *E,
                      double *g, double *H);

#endif
