/* cequil.h — constrained equilibria at given modal coordinates: the ground
 * truth a nonlinear modal subspace is measured against (Wang et al., Neural
 * Modes, eq. 9 and §4 "Performance Comparisons"):
 *
 *     x*(z) = argmin_x E(x)   subject to   Wᵀ M (x − X) / m = z,
 *
 * with E the elastic energy of a system (solid or shell, system.h), W the r
 * linear modes, M-orthonormal as crom-modes stores them (Wᵀ M W / m = I, so
 * z is in metres of RMS displacement) and zero on the pinned DOFs, which
 * stay at rest. A neural-modes map x(z) = X + W z + y(z) with Wᵀ M y = 0
 * reaches these configurations exactly when it is trained to convergence;
 * linear modes give X + W z, whose energy is higher.
 *
 * A body the pins leave free to move rigidly has its rigid motions R (the
 * translations and infinitesimal rotations about its centre of mass that the
 * modes are M-orthogonal to, crom_modes_rigid) held by Rᵀ M (x − X) = 0 as
 * well: the energy does not see them, and the equilibrium is defined up to a
 * rigid motion; this picks the one whose mean linearized rotation is zero.
 *
 * Newton's method on the KKT system of the linear constraints, staying
 * feasible: with g = ∇E, H the Hessian plus μM (μ > 0 keeps H definite
 * along the rigid motions) and B = [M W / m | M R],
 *     H Δ + B λ = −g,   Bᵀ Δ = 0,
 * solved by a Schur complement: a = −H⁻¹ g, Y = H⁻¹ B (one CHOLMOD factor,
 * r + 1 solves), (Bᵀ Y) λ = Bᵀ a, Δ = a − Y λ; then an Armijo line search
 * on E along Δ (lib/base/linesearch.h). Converged when ‖Δ‖∞ is below tol
 * times the bounding-box diagonal, as crom-fullsim's steps are, or when the
 * energy the step could still gain, −gᵀΔ, is below 1e-12 of E (a thin
 * shell's nearly isometric bendings are so flat that the configuration is
 * fixed only as far as the round-off of its energy resolves it). The
 * Hessian: the true one plus μM while its Cholesky factorization succeeds,
 * else shifted by τM with τ grown tenfold until it does and relaxed fourfold
 * per iteration after (Levenberg).
 */
#ifndef CROM_CEQUIL_H
#define CROM_CEQUIL_H

#include "phys/chol.h"
#include "phys/system.h"

typedef struct {
    int max_iter;   /* Newton iterations (default 200) */
    double tol;     /* ‖Δ‖∞ <= tol · L ends the solve (default 1e-8) */
    double mu;      /* μ of H + μM (1/s²); 0 (default): 1e-8 times the mean of K_ii / m_i at rest */
} crom_cequil_opts;

typedef struct {
    int newton;       /* Newton iterations */
    int cuts;         /* line-search halvings, summed */
    double residual;  /* last ‖Δ‖∞ / L */
    double energy;    /* E(x*) (J) */
} crom_cequil_stats;

typedef struct {
    const crom_system *sys;
    const unsigned char *fixed;
    const double *X;
    int n, r;
    int nc;           /* constraints: the r modes, then the rigid motions the pins leave free */
    double L, mu;
    crom_cequil_opts o;
    /* private */
    double *B, *V, *H, *g, *d, *a, *Y, *S, *xt, *work, *lam; /* V: the constrained motions, Bᵀ V = I */
    crom_chol *chol;
} crom_cequil;

void crom_cequil_defaults(crom_cequil_opts *o);

/* Set up the solver for the system sys (borrowed) of mesh (borrowed: its
 * rest positions and pieces), the pinned DOFs fixed[n] (or NULL) and the r
 * modes W[n][r] (row-major, borrowed). Returns CROM_OK, CROM_EUSAGE (r < 1,
 * a mode that moves a pinned DOF, modes that are not M-orthonormal to
 * 1e-6, bad options) or CROM_EINTERNAL. */
int crom_cequil_init(crom_cequil *c, const crom_system *sys, const crom_mesh *mesh, const unsigned char *fixed,
                     int r, const double *W, const crom_cequil_opts *o);

/* Solve at modal coordinates z[r]. x[n] holds a start on entry (any
 * configuration: it is first made feasible, x ← x + W (z − Wᵀ M (x − X) /
 * m) − R Rᵀ M (x − X), with pinned DOFs at rest; X + W z is a good one) and the equilibrium
 * on return; lambda[r] (may be NULL) the generalized forces −Wᵀ ∇E(x*)
 * (N) that hold the body at z (0 where z is itself at rest). Returns
 * CROM_OK, or CROM_EDATA when Newton does not converge within max_iter or
 * meets an undefined energy (an inverted element) at the start. */
int crom_cequil_solve(crom_cequil *c, const double *z, double *x, double *lambda, crom_cequil_stats *st);

void crom_cequil_free(crom_cequil *c);

/* The unbalanced nodal force of any configuration x with respect to the
 * modal constraint: the gradient g = ∇E(x) less its part held by modal
 * forces, f = g − M W Wᵀ g / m (the M⁻¹-orthogonal projection; 0 at a
 * constrained equilibrium), pinned DOFs excluded. Writes f[n] (may be NULL)
 * and returns the RMS over the free vertices of |f_v| (N), or NaN where the
 * energy is not defined. g is workspace of n. */
double crom_cequil_unbalanced(const crom_system *sys, const unsigned char *fixed, int r, const double *W,
                              const double *x, double *g, double *f);

#endif
