/* rigid.h — rigid bodies as a physical system of lumped masses (Sharp et al.
 * 2023 §5.1; issue 17): the element kernels of bodies held by penalties.
 *
 * State. Sharp et al. give each body the 12 unconstrained coefficients of
 * an affine map [R|t], x = R X + t for every body point X (rest, world
 * coordinates), with a potential ‖RᵀR − I‖²_F keeping R orthogonal. Here
 * those 12 coefficients are carried by the positions of 4 FRAME VERTICES
 * y_k = R Y_k + t (a linear bijection, the frame being a non-degenerate
 * tetrahedron), so a body is four vertices of crom's system interface
 * (DESIGN.md, "Physical systems"): a configuration, lumped masses, and
 * energies summed over elements.
 *
 * Mass. The kinetic energy of an affine velocity field ẋ = Ṙ X + ṫ over a
 * body of mass m, centre c and second moment S = ∫ρ (X − c)(X − c)ᵀ dV is
 * ½ m |ẋ(c)|² + ½ tr(Ṙ S Ṙᵀ). Four masses m/4 at Y_k = c + A e_k, with
 * A = (3S/m)^½ and e_k the unit vertices of a regular tetrahedron (Σ e_k =
 * 0, Σ e_k e_kᵀ = 4/3 I), have the same mass, centre and second moment
 * (Σ m/4 (Y_k − c)(Y_k − c)ᵀ = m/3 A² = S), so their lumped kinetic energy
 * is the body's EXACTLY for every affine motion: the frame is the body's
 * inertia, a diagonal mass matrix as every crom system has.
 *
 * Points. A body point X moves with the frame by its barycentric
 * coordinates β (Σ β_k = 1) in the rest frame: x = Σ β_k y_k.
 *
 * Elements (energies of frame vertices, gradients and Hessians for Newton,
 * FD-checked in tests/unit/test_rigid.c):
 *   - orthogonality: w ‖RᵀR − I‖²_F with R = D_y D_Y⁻¹ (D the edge
 *     matrices y_k − y_0): zero exactly for rigid motions;
 *   - a pinned point: ½ w |x − target|² (Sharp eq. 9, w_eq |C_eq|²);
 *   - a point-to-point joint between two bodies: ½ w |x_a − x_b|²;
 *   - a contact: a point of body a against the signed distance φ of body
 *     b's shape, ½ w min(φ, 0)² (Sharp eq. 9, w_ineq |min(C, 0)|²), φ
 *     taken at the point's shape coordinates in b, ℓ = R'ᵀ (x − ȳ_b) with
 *     ȳ_b the mean of b's frame vertices (its centre) and R' = D_y B Q b's
 *     affine map composed with its rest rotation Q: a cubic polynomial of
 *     the two frames, the body's own coordinates whenever b moves rigidly
 *     (R'ᵀ = R'⁻¹ then), as Sharp et al. test every vertex of one body
 *     against the analytic signed distance of the other.
 */
#ifndef CROM_RIGID_H
#define CROM_RIGID_H

#include "mesh/mesh.h"

/* A body's mass distribution at rest. */
typedef struct {
    double m;       /* mass (kg) */
    double c[3];    /* centre of mass (m) */
    double S[9];    /* second moment about c, ∫ρ (X − c)(X − c)ᵀ dV (kg m², symmetric) */
} crom_rigid_inertia;

/* The inertia of a tet mesh of density rho, integrated exactly over its
 * tets. CROM_EUSAGE for rho <= 0 or not finite, CROM_EDATA for a mesh of
 * no volume. */
int crom_rigid_inertia_tets(const crom_mesh *mesh, double rho, crom_rigid_inertia *in);

/* The inertia of a solid box of extents a[3] centred at c with density rho:
 * m = ρ a0 a1 a2, S = m/12 diag(a0², a1², a2²). */
void crom_rigid_inertia_box(const double a[3], const double c[3], double rho, crom_rigid_inertia *in);

/* The rest frame Y [4][3] of a body (masses m/4 each, see above).
 * CROM_EDATA when S is not positive definite (a body of no 3-D extent). */
int crom_rigid_frame(const crom_rigid_inertia *in, double Y[12]);

/* The inverse edge matrix B = D_Y⁻¹ of a rest frame (row-major [3][3]; the
 * columns of D_Y are Y_k − Y_0, k = 1..3): crom_fem_tet_rest's, the frame
 * being a positively oriented tetrahedron. CROM_EDATA for a degenerate or
 * inverted frame. */
int crom_rigid_frame_inverse(const double Y[12], double B[9]);

/* Barycentric coordinates beta[4] of the rest point X in the rest frame
 * with inverse edge matrix B: X = Σ β_k Y_k. */
void crom_rigid_coords(const double Y[12], const double B[9], const double X[3], double beta[4]);

/* The affine map of frame y [12] from its rest frame: R [9] (row-major)
 * and t [3] with x = R X + t for every body point. */
void crom_rigid_affine(const double Y[12], const double B[9], const double y[12], double R[9], double t[3]);

/* The orthogonality element of frame y (rest inverse edges B): E = w
 * ‖RᵀR − I‖²_F, gradient g [12] and Hessian H [12][12] (row-major) with
 * respect to y; any of E, g, H may be NULL; project: H projected to
 * positive semi-definite. Returns 0, or 1 when the projection fails. */
int crom_rigid_ortho(const double B[9], double w, const double y[12], int project, double *E, double *g,
                     double *H);

/* A point of coordinates beta [4] in frame y pinned at target [3]: E =
 * ½ w |Σ β_k y_k − target|², g [12], H [12][12] (constant, PSD); any
 * output may be NULL. */
void crom_rigid_pin(const double beta[4], double w, const double y[12], const double target[3], double *E,
                    double *g, double *H);

/* A joint holding point beta [4] of frame ya to point gamma [4] of frame yb:
 * E = ½ w |Σ β_k ya_k − Σ γ_k yb_k|², gradient g [24] (ya then yb) and
 * Hessian H [24][24] (constant, PSD); any output may be NULL. */
void crom_rigid_joint(const double beta[4], const double gamma[4], double w, const double ya[12],
                      const double yb[12], double *E, double *g, double *H);

/* A point-on-axis (slider) joint: point gamma [4] of frame yb held on the
 * line through point beta [4] of frame ya along ya's axis u = R_a a0 (a0
 * a unit rest direction; u = Σ_k c_k ya_k with c_k the axis weights of
 * crom_rigid_axis_weights): E = ½ w |d − (u·d) u|², d = x_b − x_a (the
 * component of d across the axis, taking |u| = 1, which the orthogonality
 * potential keeps), gradient g [24] (ya then yb) and Hessian H [24][24],
 * exact (the energy is a polynomial of the frames); any output may be
 * NULL; project: H projected to PSD. Returns 0, or 1 when the projection
 * fails. */
int crom_rigid_slider(const double beta[4], const double gamma[4], const double c[4], double w, const double ya[12],
                      const double yb[12], int project, double *E, double *g, double *H);

/* The weights c [4] with R a0 = Σ_k c_k y_k for frame y of rest inverse
 * edges B (c_k = b_k · a0; Σ c_k = 0). */
void crom_rigid_axis_weights(const double B[9], const double a0[3], double c[4]);

/* The signed distance φ of a scene shape (mesh/scene.h: shape code and
 * size) at shape coordinates q, its gradient g [3] and Hessian H [3][3]
 * (either may be NULL): exact where φ < 0 (a box's Hessian is 0 inside,
 * its faces' planes); outside, φ > 0 (a box's exact distance). */
void crom_rigid_sdf(int shape, const double size[3], const double q[3], double *phi, double *g, double *H);

/* The contact element: point beta [4] of frame ya against the shape of the
 * body whose frame is yb, with Bq = B Q (its rest inverse edge matrix times
 * its rest rotation, row-major). E = ½ w min(φ, 0)², gradient g [24] (ya
 * then yb) and Hessian H [24][24]; any output may be NULL; project: H
 * projected to PSD. Zero (all outputs) where φ >= 0. Returns 0, or 1 when
 * the projection fails. */
int crom_rigid_contact(const double beta[4], const double Bq[9], int shape, const double size[3], double w,
                       const double ya[12], const double yb[12], int project, double *E, double *g, double *H);

#endif
