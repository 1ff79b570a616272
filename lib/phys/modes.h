/* modes.h — linear vibration modes of an elastic body at rest (crom-modes).
 *
 * The generalized eigenproblem K φ = ω² M φ with K the stiffness of the
 * stable neo-Hookean energy at the rest state (the unprojected Hessian at
 * x = X, positive semidefinite there) and M the lumped mass. Pinned degrees
 * of freedom are eliminated: the problem is set up on the free DOFs only (the
 * rows and columns of K and M that are not fixed), so no spurious eigenvalue
 * of a penalty or of the fixed identity block can appear. Vertices used by no
 * tet (mass 0) are eliminated too.
 *
 * The lowest pairs come from ARPACK's implicitly restarted Lanczos
 * iteration (dsaupd/dseupd) in its generalized shift-invert mode on the
 * operator A = (K − σM)⁻¹ M, which is self-adjoint in the M inner product:
 * its largest eigenvalues θ are the λ = ω² nearest above the shift,
 * λ = σ + 1/θ. σ < 0, so K − σM is symmetric positive definite even for a
 * free body (K singular) and one sparse Cholesky factor (CHOLMOD, METIS
 * block ordering; lib/phys/chol.h) serves every solve. A dense LAPACK solve
 * stands in when every deformation mode is asked for (ARPACK gives fewer).
 *
 * Rigid modes are built, not searched for: a single-vector Krylov space
 * holds one direction of each eigenspace, so the six-fold zero of a free
 * body would come out once, or any number of times. For each connected
 * piece of the mesh the translations and infinitesimal rotations about its
 * centre of mass that the pins allow (those vanishing on its fixed DOFs)
 * are M-orthonormalized, and ARPACK works in their M-orthogonal complement:
 * its start vector and every A x are projected with I − R Rᵀ M. A free body
 * has six, one pinned at a single vertex three, a body pinned along a line
 * one, several disconnected pieces six each. Repeated deformation
 * eigenvalues (a square beam's bending pairs) get max(2k + 1, k + 20)
 * Lanczos vectors, and after convergence the lowest pair of the complement
 * of all found ones is computed from another start vector: a copy ARPACK
 * missed lies below the largest found λ and takes its place.
 *
 * A computed ω² below rigid_tol times the mean eigenvalue of M⁻¹K
 * (Σ K_ii/m_i / n, a property of the mesh and material, not of how many
 * modes were asked for) is a zero-energy mode beyond the rigid motions
 * (say two pieces joined at one vertex) and counts as rigid too.
 *
 * ARPACK keeps its state in Fortran SAVE variables: one computation at a
 * time per process.
 */
#ifndef CROM_MODES_H
#define CROM_MODES_H

#include <stdint.h>

#include "mesh/mesh.h"
#include "phys/fem.h"
#include "phys/chol.h"
#include "phys/scenario.h"
#include "phys/system.h"

typedef struct {
    int count;         /* modes wanted in the result (>= 1); see keep_rigid */
    int keep_rigid;    /* 1: the rigid modes found lead the result and count
                          towards `count`; 0 (default): they are dropped and
                          `count` deformation modes are returned */
    double shift;      /* σ (rad²/s², < 0); 0 picks −0.01·E/(ρ D²), D the
                          bounding-box diagonal */
    double tol;        /* Ritz residual tolerance relative to θ (default 1e-10) */
    double rigid_tol;  /* ω² <= rigid_tol·λ_mean is rigid (default 1e-12) */
    int basis;         /* Lanczos vectors, ARPACK's ncv (0 or fewer than
                          the automatic max(2k + 1, k + 20): automatic) */
    long max_solves;   /* limit on solves with the factor (0: 200·(k + 6) + 2000) */
    uint64_t seed;     /* start vector (default 1) */
    int nthreads;      /* assembly threads (0: OpenMP default) */
    const crom_scenario *materials; /* its regions of other materials (--youngs REGION=E;
                                       crom_system_set_materials), or NULL: mat everywhere */
} crom_modes_opts;

/* Defaults as documented above, count = 20. */
void crom_modes_defaults(crom_modes_opts *o);

typedef struct {
    int n;             /* 3 nv degrees of freedom */
    int nfree;         /* free degrees of freedom (not fixed, on some tet) */
    int k;             /* modes returned */
    int nrigid;        /* rigid modes: the rigid motions the pins allow,
                          and zero-energy modes found beyond them */
    int rigid_kept;    /* 1: the first nrigid modes returned are the rigid
                          ones; 0: none of the returned modes is rigid */
    double *omega2;    /* [k] ω² (rad²/s²), ascending (rigid motions 0;
                          zero-energy modes found beyond them ~0, maybe
                          slightly negative from round-off) */
    double *freq;      /* [k] f = sqrt(max(ω², 0)) / 2π (Hz) */
    double *phi;       /* [n][k] row-major mode shapes: ΦᵀMΦ = I, zero on
                          eliminated DOFs; sign: largest entry positive. Kept
                          rigid modes are re-expressed in their span as
                          translations x, y, z then rotations about x, y, z
                          (about the centre of mass), as far as they lie in
                          it, M-orthonormalized in that order */
    double *residual;  /* [k] ‖Kφ − ω²Mφ‖ / ‖Kφ‖ (rigid: / (λ_mean ‖Mφ‖)) */
    double sigma;      /* the shift used (rad²/s²) */
    double lambda_mean;      /* mean eigenvalue of M⁻¹K on the free DOFs */
    double rigid_threshold;  /* rigid_tol · lambda_mean */
    double next_omega2;      /* the next eigenvalue ω² above the returned
                                ones (computed with them; NAN if none) */
    /* statistics */
    long solves;       /* solves with the factor (operator applications) */
    int restarts;      /* ARPACK's implicit restarts (dsaupd iterations) */
    int basis_max;     /* Lanczos vectors (ncv; the dense size if dense) */
    double t_assemble, t_analyze, t_factor, t_lanczos; /* seconds */
    double t_solve;    /* the part of t_lanczos spent in solves */
} crom_modes;

/* The lowest modes of the mesh with material mat (its density gives M) and
 * the DOFs marked in fixed[3nv] eliminated (NULL: a free body). Returns 0,
 * CROM_EUSAGE when more modes are asked for than the free DOFs allow (the
 * message says how many there are) or every DOF is fixed, CROM_EDATA for a
 * bad mesh or a stiffness that is not positive semidefinite, CROM_EINTERNAL
 * when ARPACK fails or does not converge within max_solves, or memory runs
 * out. On failure *out holds nothing to free. */
int crom_modes_compute(const crom_mesh *mesh, const crom_material *mat,
                       const unsigned char *fixed, const crom_modes_opts *o,
                       crom_modes *out);

/* Release the arrays of a result (NULL-safe, idempotent). */
void crom_modes_free(crom_modes *m);

/* The DOF mask fixed[3nv] (malloc'ed) of the vertices of n pin references
 * (region names or predicates, crom_mesh_select), and how many vertices it
 * holds; on a 2-D solid (m->plane) every z DOF too, not counted. CROM_EUSAGE
 * for an unknown region or an empty selection. */
int crom_modes_pins(const crom_mesh *m, int n, const char *const *refs,
                    unsigned char **fixed, int *npinned);

/* The same for the --pin regions of a scenario. */
int crom_modes_scenario_pins(const crom_mesh *m, const crom_scenario *sc, unsigned char **fixed, int *npinned);

/* M-orthonormalize the ncol columns of V [ncol][n] (each column contiguous)
 * in place, masses m [n], by modified Gram–Schmidt, twice. A column whose
 * M-norm falls below 1e-8 of its norm before (dependent on those before) is
 * dropped, unless it is one of the first keep. Returns the number of
 * columns kept (moved to the front), or -1 when one of the first keep
 * vanished. */
int crom_modes_orthonormalize(double *V, int n, int ncol, const double *m, int keep);

/* The rigid motions the pins leave free (those crom_modes_compute keeps
 * its modes M-orthogonal to): *nr M-orthonormal columns (RᵀMR = I, M the
 * lumped masses of sys) in *R [3nv][nr] row-major (malloc'ed; NULL when nr
 * is 0), zero on fixed DOFs and on vertices without mass. sys must be the
 * system of mesh. Returns 0 or CROM_EINTERNAL. */
int crom_modes_rigid(const crom_mesh *mesh, const crom_system *sys, const unsigned char *fixed, double **R,
                     int *nr);

/* The nev lowest eigenpairs of another generalized problem K y = λ M y by
 * the same machinery: K symmetric positive semidefinite (upper CSC over n
 * unknowns, the diagonal last in each column, as crom_fem's Hessian), M =
 * diag(m), m > 0, in the M-orthogonal complement of nr M-orthonormal vectors
 * R [nr][n] (NULL if nr = 0; e.g. the null space of K, built by the caller).
 * One CHOLMOD factor of K − σM (σ < 0, moved further out if round-off
 * makes it indefinite), ARPACK shift-invert Lanczos with the check for
 * missed copies of repeated eigenvalues, or a dense solve when nev is the
 * whole complement. lam [nev] gets λ ascending, Y [nev][n] M-orthonormal
 * vectors (sign as ARPACK leaves it), *solves (may be NULL) the solves with
 * the factor. o (may be NULL) gives tol, basis, max_solves and seed; count
 * is nev. CROM_EUSAGE when nev is not in 1..n − nr or σ >= 0, CROM_EDATA
 * when K − σM is not positive definite, CROM_EINTERNAL when ARPACK fails. */
int crom_modes_lowest(const crom_sym *K, const double *m, int nr, const double *R, int nev, double sigma,
                      const crom_modes_opts *o, double *lam, double *Y, long *solves);

/* The half-width of modal coordinate k in a box scaled by frequency (the
 * neural modes' training box with --box-scaling frequency, and the samples
 * crom-metrics and crom-cubature draw from it): A f_1 / f_k, f_1 the lowest
 * positive of freq[0..r-1], so that every mode's edge has the same linear
 * energy; A where f_k is not positive, or none is. */
double crom_modes_box_half(const double *freq, int r, double A, int k);

#endif
