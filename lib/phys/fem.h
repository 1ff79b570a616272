/* fem.h — finite-element physics of crom (crom/fem): the stable
 * neo-Hookean material point (its parameters: material.h), linear-
 * tetrahedron element energy / gradient / Hessian with an analytic SPD
 * projection, lumped mass, and sparse assembly over a mesh.
 *
 * Conventions
 *   - 3×3 matrices are row-major double[9]: F[3*a + b] = F_ab.
 *   - The 9×9 tangent is row-major: dPdF[9*(3a+b) + (3c+d)] = ∂P_ab/∂F_cd
 *     (= ∂²Ψ/∂F_ab∂F_cd, symmetric).
 *   - Element positions are double[12]: x[3k + c] = coordinate c of the
 *     tet's k-th vertex; element gradients use the same index and element
 *     Hessians are row-major 12×12.
 *   - Mesh DOFs are 3v + c for vertex v and coordinate c; states are deformed
 *     positions x [nv][3] (not displacements).
 *
 * Energy (Smith, de Goes, Kim 2018, "Stable Neo-Hookean Flesh Simulation",
 * eq. 14, shifted by a constant so that Ψ(I) = 0):
 *   Ψ(F) = μ/2 (Ic − 3) − μ/2 log((Ic + 1)/4) + λ/2 [(J − α)² − (1 − α)²],
 *   Ic = tr(FᵀF), J = det F, α = 1 + 3μ/(4λ).
 * It is finite for every F, inverted ones included (no log J).
 */
#ifndef CROM_FEM_H
#define CROM_FEM_H

#include "mesh/mesh.h"
#include "phys/material.h"

/* ---- Material point (stress–strain) ---------------------------------- */

/* Energy density Ψ(F) (J/m³, shifted so Ψ(I) = 0). Never fails; NaN in F
 * gives NaN. */
double crom_fem_psi(const crom_material *m, const double F[9]);

/* First Piola–Kirchhoff stress P = ∂Ψ/∂F (Pa). */
void crom_fem_pk1(const crom_material *m, const double F[9], double P[9]);

/* The 9×9 tangent dP/dF = ∂²Ψ/∂F²; if project is nonzero, its projection onto
 * the positive semidefinite cone (negative eigenvalues clamped to 0) computed
 * with the analytic eigensystem (no dense eigensolver). */
void crom_fem_dPdF(const crom_material *m, const double F[9], int project,
                   double dPdF[81]);

/* The analytic eigensystem of dP/dF (Smith, de Goes, Kim 2019): eigenvalues
 * lam[9] and orthonormal eigenvectors as rows Q[9*i .. 9*i+8] (each a
 * row-major 3×3 matrix), so dPdF = Σ lam[i] Q_i Q_iᵀ. Order: 3 scaling modes,
 * then twist, flip for the singular-value pairs (1,2), (0,2), (0,1). */
void crom_fem_dPdF_eig(const crom_material *m, const double F[9],
                       double lam[9], double Q[81]);

/* Rotation-variant SVD F = U diag(sigma) Vᵀ: U and V proper rotations,
 * sigma[0] >= sigma[1] >= |sigma[2]|, and sigma[2] < 0 exactly when
 * det F < 0. Handles repeated and zero singular values. Returns CROM_OK, or
 * CROM_EDATA (no message, hot path) if F is not finite (U = V = I then). */
int crom_fem_svd3(const double F[9], double U[9], double sigma[3], double V[9]);

/* ---- One tetrahedron (also for reduced / cubature code) -------------- */

/* Rest-shape data of a tet with rest vertices X[12]: Dminv = Dm⁻¹ with
 * Dm = [X1−X0, X2−X0, X3−X0], and rest volume *V = det(Dm)/6. Returns
 * CROM_OK, or CROM_EDATA when the tet is not finite, degenerate or inverted
 * (V <= 0 or ill-conditioned beyond 1e-12 relative). */
int crom_fem_tet_rest(const double X[12], double Dminv[9], double *V);

/* Deformation gradient F = Ds Dm⁻¹ of a tet with deformed positions x[12]. */
void crom_fem_tet_F(const double x[12], const double Dminv[9], double F[9]);

/* Elastic energy V·Ψ(F) of one tet. NaN/Inf in x give a non-finite value. */
double crom_fem_tet_energy(const crom_material *m, const double x[12],
                           const double Dminv[9], double V);

/* Energy V·Ψ, gradient g[12] = ∂(VΨ)/∂x and Hessian H[144] of one tet; any of
 * E, g, H may be NULL. project != 0 projects the Hessian to SPD (analytic,
 * per element). Returns CROM_OK, or CROM_EDATA (with a message) if a
 * requested result is not finite. */
int crom_fem_tet_eval(const crom_material *m, const double x[12],
                      const double Dminv[9], double V, int project, double *E,
                      double g[12], double H[144]);

/* Per-tet measures of the mesh displaced by u ([nv][3]; NULL: at rest), for
 * output (cell data): the signed rest volume vol[t] = det(Dm)/6 (m³) and
 * J[t] = det F; with a material m (may be NULL) also the strain-energy
 * density psi[t] = Ψ(F) (J/m³, the same Ψ as the element kernel) and the von
 * Mises equivalent of the Cauchy stress σ = P Fᵀ / J (Pa) in mises[t]:
 * sqrt(3/2 s:s) with s the deviator of σ. A degenerate or inverted rest tet
 * gets NaN for J, psi and mises, and mises is NaN where J <= 0 (σ is not
 * defined for an inverted tet). Any output may be NULL. Returns the number
 * of degenerate or inverted rest tets (never fails). */
int crom_fem_tet_measures(const crom_mesh *mesh, const double *u, const crom_material *m,
                          double *vol, double *J, double *psi, double *mises);

/* ---- Mesh-level operator --------------------------------------------- */

/* Per-mesh data, read-only after crom_fem_init (so one crom_fem can be used
 * from several threads). The Hessian pattern is compressed sparse column,
 * upper triangle (row <= col), rows sorted in each column with the diagonal
 * last: a packed, sorted, symmetric (stype = 1) CHOLMOD matrix of size
 * n = 3 nv with colptr/rowind as its p/i arrays (int indices). The pattern
 * holds 3×3 blocks for each pair of vertices sharing a tet, and every
 * vertex's diagonal block (a vertex used by no tet has mass 0 and a zero
 * diagonal unless fixed). Memory: about 400 bytes per tet (the scatter map
 * is 312 of them) plus 12 bytes per Hessian entry. */
typedef struct {
    int nv, nt;
    crom_material mat;
    const crom_material *mats; /* regions of other materials (crom_fem_set_materials; borrowed): */
    const int *tmat;           /* [nt] tet t's material is mats[tmat[t]]; NULL: mat for all */
    int *tets;       /* [nt][4] copy of the mesh's tets */
    double *Dminv;   /* [nt][9] rest-shape inverses */
    double *vol;     /* [nt] rest volumes (m³) */
    double *mass;    /* [nv] lumped vertex masses m_v = Σ ρV/4 (kg) */
    double volume;   /* total rest volume (m³) */
    double total_mass; /* ρ · volume (kg) */
    int n;           /* 3 nv */
    int nnz;         /* stored entries of the upper triangle */
    int *colptr;     /* [n+1] */
    int *rowind;     /* [nnz] */
    int *scatter;    /* [nt][78] value index of each element upper entry */
    int ncolors;     /* tet colouring for threaded assembly: */
    int *color_ptr;  /* [ncolors+1] offsets into color_tets */
    int *color_tets; /* tets sharing no vertex within one colour; tets
                        beyond color_ptr[ncolors] are done serially */
} crom_fem;

/* Assembly options; all-zero (or a NULL pointer) means: no projection, no
 * mass term, no fixed DOFs, OpenMP's default thread count. With one thread
 * tets are visited in index order (deterministic); with k >= 2 threads they
 * are visited colour by colour, so gradient and Hessian are bitwise
 * identical for every k >= 2 and equal to the 1-thread result up to
 * round-off; the energy is summed per thread (deterministic for a given
 * k). */
typedef struct {
    int project;              /* project each element Hessian to SPD */
    double mass_scale;        /* add mass_scale·m_v to the 3 diagonal entries
                                 of vertex v (e.g. 1/h² for implicit Euler);
                                 Hessian only, not energy or gradient */
    const unsigned char *fixed; /* [3nv] nonzero = Dirichlet DOF, or NULL */
    int nthreads;             /* 0: OpenMP default, 1: serial, k: k threads */
} crom_fem_opts;

/* The material of tet t. */
static inline const crom_material *crom_fem_tet_material(const crom_fem *fem, int t)
{
    return fem->tmat ? &fem->mats[fem->tmat[t]] : &fem->mat;
}

/* Regions of other materials (scenario.h crom_scenario_materials): tet t
 * takes mats[tmat[t]] (both borrowed, kept until the operator is freed;
 * NULL tmat: the material of init for all), its density too: the lumped
 * masses become Σ ρ_t V_t / 4 over each vertex's tets. Returns 0 or
 * CROM_EUSAGE. */
int crom_fem_set_materials(crom_fem *fem, const crom_material *mats, int nmat, const int *tmat);

/* Build the operator from a mesh and a material: rest shapes, volumes,
 * lumped masses, Hessian pattern, scatter map and colouring. Returns
 * CROM_OK, CROM_EDATA (bad index, non-finite position, or a degenerate or
 * inverted tet, naming the tet), or CROM_EINTERNAL (out of memory). On
 * failure *fem holds nothing to free. */
int crom_fem_init(crom_fem *fem, const crom_mesh *mesh, const crom_material *mat);

/* Release what crom_fem_init allocated (NULL-safe, idempotent). */
void crom_fem_free(crom_fem *fem);

/* Assemble at deformed positions x[nv][3]: total elastic energy *E, gradient
 * grad[3nv] and upper-CSC Hessian values Hval[nnz] (any may be NULL; the
 * outputs are overwritten, not accumulated). Fixed DOFs get zero gradient,
 * zero off-diagonal Hessian entries and a diagonal of 1 (the energy is not
 * changed). Inverted tets are fine (finite energy). Returns CROM_OK, or
 * CROM_EDATA naming the first tet with a non-finite result (outputs are then
 * unspecified), or CROM_EUSAGE for NULL fem or x. */
int crom_fem_assemble(const crom_fem *fem, const double *x,
                      const crom_fem_opts *opt, double *E, double *grad,
                      double *Hval);

/* Total elastic energy at x (J). Returns as crom_fem_assemble. */
int crom_fem_energy(const crom_fem *fem, const double *x, double *E);

/* Energies V·Ψ of the tets idx[0..n-1] (all nt tets in order if idx is
 * NULL) at x into out[n]. Returns CROM_OK, CROM_EUSAGE for an index out of
 * range, or CROM_EDATA for a non-finite energy (naming the tet). */
int crom_fem_tet_energies(const crom_fem *fem, const double *x, const int *idx,
                          int n, double *out);

/* Gather the 4 vertex positions of tet t from x[nv][3] into xe[12]. */
void crom_fem_tet_positions(const crom_fem *fem, const double *x, int t,
                            double xe[12]);

/* The lumped mass as a diagonal over DOFs: m3[3v + c] = m_v. */
void crom_fem_mass_diag(const crom_fem *fem, double *m3);

#endif
