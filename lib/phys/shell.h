/* shell.h — thin shells and cloth (crom/shell): constant-strain St. Venant–
 * Kirchhoff membrane triangles and discrete-shell hinge bending, the surface
 * system of Sharp et al. 2023 §5.1 ("Cloth model": StVK stretching on faces,
 * the bending term of Grinspun et al. 2003 on edges) and of Wang et al.'s
 * square-shell benchmark.
 *
 * Conventions (as fem.h): element positions are double[3k] with x[3i + c]
 * coordinate c of the element's i-th vertex; Hessians are row-major and
 * symmetric; states are deformed positions.
 *
 * Membrane (per triangle, rest area A, thickness t): the Green strain of the
 * constant deformation gradient F = Ds Dm⁻¹ (3×2, Dm the rest edges in the
 * triangle's own orthonormal frame), E = ½(FᵀF − I), and the plane-stress
 * StVK energy  t A [μ tr(E²) + ½ λ̃ tr(E)²]  with μ = Y/(2(1+ν)) and
 * λ̃ = Yν/(1−ν²) (plane stress: σ = Y/(1−ν²) [(1−ν)ε + ν tr(ε) I] for
 * small strain). Its second Piola–Kirchhoff stress is S = 2μE + λ̃ tr(E) I.
 *
 * Bending (per interior edge e = (v0, v1) shared by the triangles
 * (v0, v1, v2) and (v1, v0, v3), consistently oriented): the hinge energy
 *   k_e (θ_e − θ̄_e)²,   k_e = ½ D |ē|² / (Ā1 + Ā2),   D = Y t³ / (12 (1 − ν²)),
 * θ the signed angle between the two triangles' normals (0 when flat) and
 * barred quantities at rest. This is Grinspun et al. 2003's
 * (θ − θ̄)² |ē| / h̄_e (h̄_e a sixth of the two heights' sum, so |ē|/h̄_e =
 * 3|ē|²/(Ā1 + Ā2)) with stiffness D/6. The calibration: on a triangulation
 * of equilateral triangles (side l, height h) the facets interpolating a
 * surface of curvature tensor K meet across an edge of in-plane normal m and
 * direction t at θ = h (mᵀKm − ⅓ tᵀKt) to leading order, and summed over the
 * three edge directions the hinges store ½ D (κ1² + κ2² − ⅔ κ1κ2) per unit
 * area: exactly the Kirchhoff plate energy ½ D κ² of a cylinder bent in any
 * direction (tests/unit/test_shell.c checks it under refinement), with the
 * two curvatures coupled as by ν = −1/3 whatever ν is (the hinge model's
 * known limit: a narrow free strip bends 11% more easily than Kirchhoff's at
 * ν = 0, a wide plate as it). θ is computed as atan2(U, V) with a = x1 − x0, b = x2 − x0,
 * c = x3 − x0, U = −|a| det(a, b, c), V = (a·b)(a·c) − |a|²(b·c) (= n1·n2 for
 * n1 = a×b, n2 = c×a), whose derivatives are polynomial but for |a|.
 */
#ifndef CROM_SHELL_H
#define CROM_SHELL_H

#include "phys/fem.h"

/* A shell material: Young's modulus Y (Pa), Poisson ratio nu in (-1, 0.5],
 * thickness t (m) and density rho (kg/m³), with the derived membrane Lamé
 * parameters and the bending stiffness. */
typedef struct {
    double E, nu, thickness, rho;
    double mu;        /* Y / (2 (1 + ν)) */
    double lambda_ps; /* plane stress: Y ν / (1 − ν²) */
    double D;         /* bending stiffness Y t³ / (12 (1 − ν²)) */
    int plane;        /* 1: a 2-D plane-strain solid instead (crom_shell_material_plane) */
    crom_material solid; /* plane: the stable neo-Hookean material of its plane-strain triangles */
    double kz;        /* plane: the spring (N/m) at each corner of a triangle that holds it in z = 0 */
} crom_shell_material;

/* Fill m. Returns CROM_OK, or CROM_EUSAGE naming the value that is not
 * finite, E <= 0, rho <= 0, thickness <= 0 or nu outside (-1, 0.5]. */
int crom_shell_material_init(crom_shell_material *m, double E, double nu, double thickness, double rho);

/* Make m a 2-D solid in PLANE STRAIN (issue 19 item 3; Sharp et al.'s
 * bistable and conditional bars): the triangles of a mesh in the plane
 * z = 0 are a body of thickness t (the out-of-plane depth) in plane
 * strain, F = [[F2, 0], [0, 1]] with F2 the in-plane deformation gradient
 * (F's rows x, y in the triangle's rest frame, oriented so that det F2 > 0
 * at rest: crom_shell_init flips the frame where the triangle runs
 * clockwise), and energy t A Ψ(F) with the stable neo-Hookean Ψ of fem.h,
 * so the plane-strain modulus E/(1 − ν²) is the 3-D material's. No hinge,
 * no bending beyond what the triangles carry. Every corner is held in its
 * plane by a spring kz = 100 E t / 6 (N/m) on z: the z DOFs have no load
 * and no coupling to x, y, so z stays 0 exactly, and their vibrations lie
 * far above the in-plane ones (ω² = 100 E / (ρ h²) for an element of size
 * h, against E / (ρ L²) for the body's size L). */
void crom_shell_material_plane(crom_shell_material *m);

/* ---- One membrane triangle --------------------------------------------- */

/* Rest data of a triangle with rest vertices X[9]: Dminv [2][2] (row-major)
 * and area *A. Returns CROM_OK, or CROM_EDATA (no message) when the triangle
 * is not finite or degenerate (area below 1e-12 of its longest edge
 * squared). */
int crom_shell_tri_rest(const double X[9], double Dminv[4], double *A);

/* Deformation gradient F [3][2] (row-major: F[2i + a]) of positions x[9]. */
void crom_shell_tri_F(const double x[9], const double Dminv[4], double F[6]);

/* Energy, gradient g[9] and Hessian H[81] of one membrane triangle (any of
 * E, g, H may be NULL). project != 0 projects the Hessian to SPD through
 * its 6×6 tangent in F (negative eigenvalues clamped to 0). Returns
 * CROM_OK, or CROM_EDATA (no message) when a result is not finite. */
int crom_shell_tri_eval(const crom_shell_material *m, const double x[9], const double Dminv[4], double A,
                        int project, double *E, double g[9], double H[81]);

/* The membrane's stress at positions x[9]: the second Piola–Kirchhoff
 * stress S pushed forward to the deformed triangle, σ = F S Fᵀ / J with J
 * the area ratio (plane stress; the change of thickness neglected), and
 * its von Mises equivalent sqrt(σ1² − σ1σ2 + σ2²) in Pa (NaN for a
 * collapsed triangle). The bending stresses (± 6 M / t² at the faces) are
 * not included. */
double crom_shell_tri_mises(const crom_shell_material *m, const double x[9], const double Dminv[4]);

/* ---- One bending hinge ------------------------------------------------- */

/* The signed angle between the normals of (x0, x1, x2) and (x1, x0, x3) at
 * positions x[12], in (−π, π]; with its gradient g[12] and Hessian H[144]
 * when not NULL. Returns CROM_OK, or CROM_EDATA when the edge or a triangle
 * is degenerate (U = V = 0) or a value is not finite. */
int crom_shell_hinge_angle(const double x[12], double *theta, double g[12], double H[144]);

/* Rest data of a hinge with rest positions X[12]: rest angle *theta0 and the
 * geometric weight *w = |ē|² / (Ā1 + Ā2) (the stiffness is ½ D w). Returns
 * CROM_OK or CROM_EDATA (no message) for a degenerate hinge. */
int crom_shell_hinge_rest(const double X[12], double *theta0, double *w);

/* Energy k (θ − θ0)² with k = ½ D w, gradient g[12] and Hessian H[144] (any
 * may be NULL): H = 2k (∇θ∇θᵀ + (θ − θ0) ∇²θ). project != 0 keeps only the
 * Gauss–Newton part 2k ∇θ∇θᵀ, positive semidefinite, which is the whole
 * Hessian at θ = θ0 (the dropped term is indefinite and vanishes at rest).
 * The angle difference is wrapped to (−π, π]. Returns CROM_OK or CROM_EDATA
 * (no message). */
int crom_shell_hinge_eval(double k, double theta0, const double x[12], int project, double *E, double g[12],
                          double H[144]);

/* ---- A shell mesh ------------------------------------------------------ */

/* The elastic operator of a triangle mesh: membrane triangles and interior
 * edges as hinges; lumped mass ρ t A / 3 per triangle corner. The Hessian
 * pattern is the upper triangle in CSC over 3 nv DOFs (as crom_fem): 3×3
 * blocks for every pair of vertices sharing a triangle or a hinge. */
typedef struct {
    int nv, nt, nh;
    crom_shell_material mat;
    int *tris;       /* [nt][3] */
    double *Dminv;   /* [nt][4] */
    double *area;    /* [nt] rest areas (m²) */
    int *hinges;     /* [nh][4]: v0, v1 (the edge), v2, v3 (opposite) */
    double *theta0;  /* [nh] rest angles */
    double *hk;      /* [nh] stiffnesses k_e = ½ D |ē|²/(Ā1 + Ā2) */
    double *mass;    /* [nv] lumped masses (kg) */
    double total_area, total_mass;
    int boundary_edges; /* edges with one triangle */
    int n, nnz;
    int *colptr, *rowind;
    int *tscatter;   /* [nt][45] value index of each triangle upper entry */
    int *hscatter;   /* [nh][78] value index of each hinge upper entry */
} crom_shell;

/* Build the operator from nv rest positions X[nv][3] and nt triangles
 * tris[nt][3]. Returns CROM_OK, CROM_EDATA naming the problem (an index out
 * of range, a repeated vertex, a degenerate triangle, an edge shared by more
 * than two triangles (non-manifold), or two triangles that share an edge
 * with opposite orientations (the mesh is not consistently oriented)), or
 * CROM_EINTERNAL. On failure *s holds nothing to free. */
int crom_shell_init(crom_shell *s, int nv, const double *X, int nt, const int *tris,
                    const crom_shell_material *mat);

/* Release what crom_shell_init allocated (NULL-safe, idempotent). */
void crom_shell_free(crom_shell *s);

/* Assemble at positions x[nv][3]: total energy *E, gradient grad[3nv] and
 * upper-CSC Hessian values Hval[nnz] (any may be NULL; overwritten, not
 * accumulated), with the options of crom_fem_assemble (fem.h; NULL: none):
 * SPD-projected element Hessians, mass_scale·m_v added to the diagonal,
 * fixed DOFs with zero gradient, zero off-diagonal entries and a diagonal
 * of 1 (serial: nthreads is ignored). Returns CROM_OK or CROM_EDATA naming
 * the first element with a non-finite result. */
int crom_shell_assemble(const crom_shell *s, const double *x, const crom_fem_opts *opt, double *E, double *grad,
                        double *Hval);

#endif
