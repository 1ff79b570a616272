/* mderiv.h — modal derivatives (Barbič and James 2005, "Real-Time Subspace
 * Integration for St. Venant–Kirchhoff Deformable Models", §4.1): the
 * second-order companions of linear vibration modes that a subspace needs
 * to follow large deflections.
 *
 * A linear mode φ_i moves the body along a straight line; bent far, it
 * stretches what should only rotate (a beam's or a shell's membrane locks,
 * Sharp et al. 2023 Fig. 8 compare against them). Differentiating the
 * equilibrium K(u) u' = f along the modes at rest gives the modal
 * derivatives
 *
 *   K Ψ_ij = −(∂K/∂u · φ_j) φ_i,   i <= j,
 *
 * K the stiffness at rest with the pinned DOFs eliminated, symmetric in i
 * and j (the third derivatives of the energy are). For a cantilever bent by
 * z φ_1, ½ z² Ψ_11 is the in-plane shortening that keeps its length. The
 * directional derivative ∂K/∂u · φ_j is taken as the central difference
 * (H(X + ε φ_j) − H(X − ε φ_j)) / 2ε of the exact assembled Hessians (exact
 * up to round-off for the StVK membrane, whose Hessian is quadratic in u;
 * O(ε²) otherwise), with ε φ_j moving no vertex more than 1e-5 of the
 * bounding-box diagonal.
 *
 * The result, as Barbič and James use it, is a LINEAR basis: the k modes
 * followed by the k(k+1)/2 derivatives, made M-orthonormal (modified
 * Gram–Schmidt, twice), dropping derivatives that are dependent on those
 * before them (norm after projection below 1e-8 of before).
 */
#ifndef CROM_MDERIV_H
#define CROM_MDERIV_H

#include "phys/system.h"

/* Static lifts of moved pins (Craig–Bampton's constraint modes, the same
 * factor of K at rest): for each of nl displacements e [nl][n] of fixed
 * DOFs (their free entries ignored), u [nl][n] equal to e on the fixed
 * DOFs and solving K_ff u_f = −K_fp e_p on the free ones, the
 * small-displacement equilibrium of the body with its pins moved so (a
 * conditional map's start where a pin condition moves a pin,
 * lib/datafree/datafree.h). Returns 0, CROM_EDATA (K singular on the free
 * DOFs: the body is not held), CROM_EINTERNAL. */
int crom_mderiv_lift(const crom_system *s, const double *X, const unsigned char *fixed, int nl, const double *e,
                     double *u);

/* The modal derivatives themselves, psi [n][k(k+1)/2] (row-major; column
 * c for the pair (j, i >= j) in the order (0,0), (0,1) … (0,k−1), (1,1) …),
 * of the k modes phi [n][k] of system s at rest positions X [n] with fixed
 * [n] (may be NULL), zero at the fixed DOFs, unnormalized. Returns as
 * crom_mderiv_basis. */
int crom_mderiv_compute(const crom_system *s, const double *X, const unsigned char *fixed, const double *phi, int k,
                        double *psi);

/* The modal derivatives of the k modes phi [n][k] (M-orthonormal, zero at
 * the fixed DOFs) of system s at rest positions X [n], with fixed [n] (may
 * be NULL: then K must be nonsingular all the same), appended to them: *out [n][*kout] (malloc'ed)
 * holds the M-orthonormal basis [Φ, Ψ] (*kout <= k + k(k+1)/2) and
 * *freq [*kout] (malloc'ed) the Rayleigh frequency sqrt(ψᵀKψ)/2π of each of
 * its vectors (Hz). Returns 0, CROM_EUSAGE (k < 1), CROM_EDATA (K is not
 * positive definite on the free DOFs: a body the pins do not hold, or an
 * element that is not finite), or CROM_EINTERNAL. */
int crom_mderiv_basis(const crom_system *s, const double *X, const unsigned char *fixed, const double *phi, int k,
                      double **out, int *kout, double **freq);

#endif
