/* skin.h — the skinning-handle subspace (crom/model basis "skinning"):
 * linear blend skinning with H affine handles (Simplicits, Modi et al.
 * 2024; skinning eigenmodes, Benchekroun et al. 2023) written as a LINEAR
 * subspace u(X) = W(X) q, so that everything built for LiCROM's linear
 * bases (cubature, hard pins, contact, mesh swaps, decoding) runs it.
 *
 * Coordinates. The body frame F [3][4] maps a rest position to normalized
 * coordinates X̂ = F [X; 1] = P (X − c): c the centre of mass and P = Σ^−½
 * the symmetric inverse square root of the mass covariance Σ = ∫(X − c)(X −
 * c)ᵀ dm / m of the training geometry, so X̂ has zero mean and identity
 * covariance over the body (for a 1 x 0.2 x 0.2 bar, X̂ = ((x − c_x)/0.289,
 * (y − c_y)/0.058, (z − c_z)/0.058)). Handle h has the 12 coordinates
 * q[12h .. 12h + 11] = Q_h, a 3 x 4 matrix row by row, in metres, and
 *
 *     u_c(X) = Σ_h w_h(X) ( Σ_{j<3} Q_h[c][j] X̂_j + Q_h[c][3] ),
 *     i.e.  W(X)[c][12h + 4c + j] = w_h(X) [X̂; 1]_j,
 *
 * the displacement form of linear blend skinning x = X + Σ_h w_h (T_h −
 * [I|0]) [X; 1] with the affine handle transforms T_h = [I|0] + Q_h F̄,
 * F̄ = [F; 0 0 0 1] (crom_skin_handles). When the weights sum to one this is
 * x = Σ_h w_h T_h [X; 1] exactly. q = 0 is the rest shape exactly; the
 * normalized frame keeps the columns of W of comparable size.
 *
 * Orthonormal coordinates (the default of crom-fitfield). With smooth
 * weights the 4H scalar functions φ_(4h+j) = w_h [X̂; 1]_j are far from
 * independent (on a bar, x w_k is nearly a combination of the w's: with 8
 * eigen handles, 21 of the 96 columns of W above have normalized Gram
 * eigenvalues below 0.01, the smallest 5e-6), which makes the reduced mass and
 * Hessian ill-conditioned and those latent directions collapsed. So a model
 * may store coefficients C [4H][S] of S mass-orthonormal functions
 * ψ_s = Σ_a C[a][s] φ_a of the same span (over the training geometry:
 * Σ_v m_v ψ_s ψ_t = m δ_st), and then
 *
 *     W(X)[c][cS + s] = ψ_s(X),   rank 3S,   Q_h[c][j] = Σ_s C[4h + j][s] q[cS + s],
 *
 * component-major (the x displacements' S coordinates, then y's, then z's),
 * so WᵀMW = m I on the training geometry, q is in metres of RMS
 * displacement, and the rows of W of one component are nonzero in one
 * contiguous block of columns (crom_cubature_tet assembles W_eᵀ H_e W_e by blocks,
 * a third of the dense work). On a free body ψ_0..3 = X̂_0, X̂_1, X̂_2, 1
 * (the constant handle's functions, orthonormal by the choice of frame), so
 * the affine motions are q[cS + 0..3], c = 0, 1, 2, exactly; the other ψ span the rest of the φ's, made
 * M-orthogonal to those, from the eigenvectors of their Gram matrix with
 * eigenvalue above tol times the largest (directions below that are
 * numerically dependent and dropped: S <= 4H), largest first. Without C
 * the latent is the handle coordinates above (rank 12H).
 *
 * Rigid motions. A free body (no pins) has a constant handle: w_0 ≡ 1, so
 * every affine map of the body, rigid motions included, is in the subspace
 * exactly (Q_0 = (R − I) F̄⁻¹ restricted to its first three rows). A pinned
 * body has none: every weight vanishes on the pinned part (below), so pinned
 * vertices never move, on any mesh of the body.
 *
 * Weights (the `skin_weights` attribute):
 *   trained  an MLP 3 -> H' (H' = H − 1 after a constant handle, else H)
 *            with its input normalization, like the "mlp" kind, trained
 *            data-free (lib/datafree/dfskin.h), times the pin mask s(d(X)/ℓ):
 *            s(t) = t (2 − t) for t < 1 and 1 beyond (slope 2 at the pins,
 *            so the strain there can be anything), d the distance to the
 *            pinned part of the training geometry: its pinned boundary
 *            triangles and pinned points, stored with ℓ;
 *   eigen    a piecewise-linear field on the stored training mesh, w [nv][H]
 *            (interpolated as the "modes" kind is; outside the mesh extended
 *            from the nearest tet), the lowest eigenvectors of the scalar
 *            stiffness (lib/datafree/dfskin.h); pinned vertices were eliminated, so
 *            their weights are 0.
 *
 * Digest (model_id, model.h): after the basis string and rank, the handle
 * count H (int64), the constant flag (int64), the frame (12 float64), S
 * (int64, 0 without C) and C (float64); then, trained: the MLP as for "mlp" (widths int32, activation name with
 * its NUL, input shift and scale float64, parameters float32), the pin point
 * count (int64) and points, the pin triangle count (int64) and corners, and
 * ℓ (float64); eigen: nv and nt (int64), vertices (float64), tets (int32)
 * and weights (float64).
 */
#ifndef CROM_SKIN_H
#define CROM_SKIN_H

#include <stddef.h>
#include <stdint.h>

#include <hdf5.h>

#include "mesh/mesh.h"
#include "nn/nn.h"
#include "rom/model.h"

/* The body frame F [3][4] of n points X [n][3] with masses (or volumes) m [n]
 * (see above). A direction of (almost) no extent, below 1e-6 of the largest,
 * is scaled as if it had 1e-6 of it. CROM_EDATA if there is no mass or a
 * value is not finite. */
int crom_skin_frame(size_t n, const double *X, const double *m, double F[12]);

/* W [n][3][r] at n points X [n][3] from their weights w [n][H] in frame F:
 * handle coordinates (C NULL, r = 12H) or orthonormal ones (C [4H][S],
 * r = 3S). CROM_EINTERNAL when out of memory. */
int crom_skin_basis(int H, const double F[12], const double *C, int S, size_t n, const double *X, const double *w,
                    double *W);

/* The orthonormal coordinates (above) of the weights w [n][H] at n points X
 * with masses m [n] (the training geometry; constant: handle 0 is the
 * constant 1): *C [4H][*S] (malloc'ed). tol: relative eigenvalue below
 * which a direction is dropped. CROM_EDATA if the weights are zero or not
 * finite, CROM_EINTERNAL. */
int crom_skin_coordinates(int H, int constant, const double F[12], size_t n, const double *X, const double *m,
                          const double *w, double tol, double **C, int *S);

/* The pin mask s(d/len) at X (1 when there are no pins), d the distance to
 * the nearest of npin points pinX [npin][3] and ntri triangles triX
 * [ntri][3][3]. */
double crom_skin_mask_at(const double X[3], int npin, const double *pinX, int ntri, const double *triX,
                         double len);

/* The weights w [n][H] of a skinning model at n points X [n][3]
 * (mask and constant handle included). *noutside (may be NULL) gets how many
 * points lay outside an eigen model's mesh. CROM_EINTERNAL when out of
 * memory, CROM_EUSAGE for another kind of model. */
int crom_skin_weights(const crom_model *m, size_t n, const double *X, double *w, size_t *noutside);

/* The width of the skinning basis: 3S in orthonormal coordinates, else 12H
 * (the rank of a linear skinning model; the features of a skin-field). */
int crom_skin_width(const crom_model *m);

/* W [n][3][width] of a skinning model at n points (crom_model_eval's work
 * for a linear one; a skin-field's features). Errors as crom_skin_weights. */
int crom_skin_eval(const crom_model *m, size_t n, const double *X, double *W, size_t *noutside);

/* The affine handle transforms T [H][3][4] (T_h = [I|0] + Q_h F̄) of the
 * latent q [rank] of a skinning model (Q = C q in orthonormal coordinates). */
void crom_skin_handles(const crom_model *m, const double *q, double *T);

/* Make a trained skinning model: weights net (copied; 3 -> H − constant,
 * with its input normalization), constant handle flag, frame F and pin mask
 * (npin points pinX, ntri triangles triX, width len; copied), in handle
 * coordinates. CROM_EUSAGE on mismatched widths, CROM_EINTERNAL when out of
 * memory. */
int crom_skin_model_mlp(crom_model *m, const crom_nn_mlp *net, int H, int constant, const double F[12], int npin,
                        const double *pinX, int ntri, const double *triX, double len);

/* Make an eigen skinning model: weights w [nv][H] on mesh (both copied,
 * regions dropped), constant flag, frame F and eigenvalues eig [H] (copied;
 * may be NULL), in handle coordinates. Builds the point locator. Errors as
 * crom_locate_init. */
int crom_skin_model_mesh(crom_model *m, const crom_mesh *mesh, const double *w, int H, int constant,
                         const double F[12], const double *eig);

/* Switch a skinning model to orthonormal coordinates C [4H][S] (copied;
 * NULL: back to handle coordinates): rank and model_id change. */
int crom_skin_set_coordinates(crom_model *m, const double *C, int S);

/* Orthonormal coordinates for a skinning model from its own weights at n
 * points X [n][3] with masses m [n] (its training geometry), tol as for
 * crom_skin_coordinates. */
int crom_skin_orthonormalize(crom_model *m, size_t n, const double *X, const double *mass, double tol);

/* The FNV-1a digest state h continued over a skinning model's basis (see
 * above). */
uint64_t crom_skin_digest(const crom_model *m, uint64_t h);

/* Write the datasets and attributes of a skinning model under loc (after
 * the common attributes crom_model_write writes). Returns 0 or an HDF5
 * error. */
int crom_skin_write(hid_t loc, const crom_model *m);

/* Read them (m->basis and m->rank set, act: the activation attribute or
 * NULL) and check shapes and values. CROM_EDATA naming the problem. */
int crom_skin_read(hid_t h, crom_model *m, const char *act);

#endif
