/* nlsim.h — implicit Euler in the latent space of a one-mesh subspace map
 * x(q) (lib/rom/map.h: data-free maps, or any linear basis laid on its mesh),
 * the nonlinear counterpart of rsim.h with the same scenario.
 *
 * Each step minimizes over q (Sharp et al. 2023 eq. 6, Fulton et al. 2019)
 *
 *   Φ(q) = 1/(2h²) ‖x(q) − x̂‖²_M + A/(2h) ‖x(q) − x_n‖²_M + E(x(q))
 *        − f_ext·(x(q) − x_n) + κ/2 Σ_bc Σ_v m_v ‖x_v(q) − X_v − ū_v(t)‖²
 *        + contact(x(q) at the surface vertices) + the rods' energy (rod.h),
 *
 *   x̂ = x_n + h v_n,  v_n = (x_n − x_{n−1}) / h,
 *
 * the full-space incremental potential restricted to the map: inertia with
 * the full-space velocity (so momentum is that of the body, not of q), the
 * elastic energy E over every energy element of the mesh's system (the tets
 * of a solid; the membrane triangles and hinges of a shell, system.h) or
 * over the weighted elements of a cubature (crom_nlsim_use_cubature; LiCROM eq. 8 on the map's features),
 * gravity and scheduled forces, pinned and prescribed-velocity regions as a
 * stiff mass-weighted penalty (a data-free map holds its training pins by
 * construction, so the penalty only matters for other regions), and the
 * frictional planes of the full simulator.
 *
 * Cost. The map is linear in its features a(q) (lib/rom/map.h): x = X + B a,
 * and so is the velocity, v = B va with va = (a_{n+1} − a_n)/h (at the
 * start, the features' share of the initial velocity). With δ = a − a_n,
 * every term but the elastic energy and contact is a quadratic in δ whose
 * matrix,
 *   A = (1/h² + A/h) BᵀMB + κ Σ_bc B_vᵀ m_v B_v,
 * is formed once, and whose linear term
 *   b = −(1/h) BᵀMB va − Bᵀf_ext + κ Σ_bc B_vᵀ m_v (B_v a_n − ū_v),
 *   Bᵀf_ext = BᵀM 1_c g_c + Σ_forces Σ_v B_vᵀ F m_v / m_region,
 * costs p² plus the rows of the loaded and penalized vertices per step. An
 * iteration adds the rows of B at the elastic (cubature) vertices and,
 * with contact, at the surface vertices. Nothing in a step is O(mesh):
 * full-space positions are formed only on request (crom_nlsim_positions).
 * Expanding about a_n keeps the quadratic's round-off at the scale of the
 * step's motion, not of the displacement.
 *
 * Solver: Gauss–Newton with line search. With J = ∂x/∂q (exact, from the
 * map in double precision) the gradient is Jᵀ ∇_xΦ and the matrix
 * H = Jᵀ (M (1/h² + A/h) + κ M_bc + K + C) J, with K the element Hessians
 * (true ones first, projected to SPD when H is not positive definite or
 * gives no descent, as rsim.c does) and C the contact Hessians; it omits the
 * curvature of the map, Σ_i (∇_xΦ)_i ∇²x_i, which vanishes for a linear
 * basis (then this is rsim.c's Newton on the same energy). Gauss–Newton
 * converges only linearly where that term matters (large forces along
 * curved or nearly collapsed latent directions), so from the third
 * iteration of a step on, a nonlinear map gets Newton steps with the
 * curvature added (by central differences of Tᵀ∇_aΦ: 2r evaluations of the
 * network's features) whenever that matrix is positive definite and gives
 * descent, and otherwise Newton on |H + C| (its eigenvalues by absolute
 * value: the curvature kept, its sign fixed). A step starts at the latent
 * predictor q_n + h q̇_n, or at q_n where the map curves so much that the
 * predictor's Φ is higher (a straight line in q is no straight line in x;
 * on the bench's energy map this took the worst step from 80 iterations
 * to 44). Converged when the
 * RMS displacement of the correction, ‖J d‖_M / sqrt(m), is below tol times
 * the bounding-box diagonal. Afterwards v = (x_{n+1} − x_n)/h and
 * q̇ = (q_{n+1} − q_n)/h.
 */
#ifndef CROM_NLSIM_H
#define CROM_NLSIM_H

#include "phys/fem.h"
#include "phys/system.h"
#include "phys/scenario.h"
#include "rom/map.h"
#include "rom/newton.h"
#include "rom/rsim.h"

typedef struct {
    int *idx;          /* vertices */
    int n;
    double mass;       /* Σ m_v */
    const crom_bc *bc; /* NULL for a pin */
} crom_nlsim_bc;

typedef struct {
    const crom_scenario *sc;
    crom_map *map;      /* borrowed */
    crom_system sys;    /* the map's mesh (a solid or a shell) with the scenario's material */
    int r, n, p, nthreads;
    double L, kappa;
    double t;
    long step;
    double *q, *qd;     /* latent state and velocity */
    double *an, *va;    /* features a(q) of the state and their velocity (v = B va): full-space
                         * positions and velocities on demand, crom_nlsim_positions */
    /* the elastic energy: ne energy elements (every one, or a cubature) with
     * weights, over ncv vertices (cv NULL: all of them, in order); eloc
     * [ne][4] their vertices' places in that list, −1 after a triangle's
     * three */
    int ne, ncv, *eidx, *cv, *eloc;
    double *ew;
    /* private */
    double *qn, *xt, *wd, *gx, *J, *Jt, *g, *H, *d, *qt, *Gm, *lam, *zero, *tw, *tH, *tg, *tE;
    double *a, *T, *ga, *A0, *Aq, *bq, *AT, *xc, *Jc, *gc, *ge, *Bc, *Xc, *Bg, *fa, c0;
    int nbc, nforce, nsurf, *surf;
    double *xs;         /* [nsurf][3] the surface vertices at the step's start */
    /* a linear basis (map->nonlinear 0): its Gauss–Newton matrix factored
     * and reused across iterations and steps with quasi-Newton pairs, as
     * crom_rsim does (nlsim.c) */
    int lagged, fac_ok, fac_iters, fac_slow;
    double *Hfac;
    crom_newton_memory mem;
    crom_nlsim_bc *bc, *force;
    /* the scenario's rods (--rod): gap d = d0 + Drod a in the features */
    int nrod;
    double *rod_d0;     /* [nrod][3] the gaps at rest */
    double *rod_rest;   /* [nrod] their lengths */
    double *rod_D;      /* [nrod][3][p] Σ_v w_v B_v over both ends (w_v = ±m_v / m_end) */
    /* a map in a rigid frame (map.h, crom_map_add_frame): its features'
     * mass Gram is I3 ⊗ G over the three rotation blocks of 3 pb features
     * (pb = p' + 1) plus the translation's, so Tᵀ A0 T is formed block by
     * block (nlsim.c) */
    int frame_pb;       /* pb, or 0: no frame */
} crom_nlsim;

/* Set up on map (borrowed; its mesh's regions resolve the scenario's) with
 * scenario sc (borrowed); q = q0 (NULL: 0, where every map is exactly at
 * rest, x(0) = X, lib/map.h), q̇ = qd0 (NULL: from the
 * scenario's initial velocity and spin, projected: q̇ minimizes
 * ‖J q̇ − v‖_M). kappa <= 0 picks 1e4/h². nthreads splits the passes over
 * tets (deterministic for a given count). CROM_EUSAGE for an unknown or
 * empty region, CROM_EDATA for a bad mesh or state. */
int crom_nlsim_init(crom_nlsim *s, crom_map *map, const crom_scenario *sc, double kappa, const double *q0,
                    const double *qd0, int nthreads);

/* A conditional map (map.h, crom_map_set_condition) at condition c [nc],
 * the values of conds [nc] (the model's conditions, in order): sc, the
 * scenario s borrows, gets them (crom_scenario_cond_apply: a ratio's
 * region material, a gravity component), the map its c, and the body's
 * materials follow. The state q, q̇ is kept: x(q) moves to the map at the
 * new c (at q = 0 it stays at rest). Call before crom_nlsim_init (s
 * zeroed: only sc and the map change) or between steps. Returns 0 or the
 * errors of the calls. */
int crom_nlsim_set_condition(crom_nlsim *s, crom_map *map, crom_scenario *sc, const crom_scenario_cond *conds,
                             const double *c);

/* Integrate the elastic energy over k energy elements elem [k] (indices
 * into the system of the map's mesh: tets, or a shell's triangles then
 * hinges) with weights weight [k] instead of every element (a crom/cubature
 * of the map, lib/rom/cubature.h). Call after init, before stepping.
 * CROM_EDATA for an index out of range or a weight not finite and >= 0. */
int crom_nlsim_use_cubature(crom_nlsim *s, int k, const int *elem, const double *weight);

/* Advance one step. CROM_EDATA when the iteration does not converge in
 * max_iter iterations or the state goes non-finite. */
int crom_nlsim_step(crom_nlsim *s, crom_rsim_stats *st);

/* Prepare the step's predictor, loads and lagged contact forces (for tests). */
void crom_nlsim_begin_step(crom_nlsim *s);

/* Φ(q) of the current step, its gradient g [r] and the Gauss–Newton matrix
 * H [r][r] (either may be NULL); project: SPD-projected element Hessians. */
int crom_nlsim_objective(crom_nlsim *s, const double *q, double *E, double *g, double *H, int project);

/* The map's curvature term C [r][r] of the Hessian of Φ at q,
 * Σ_i (∇_xΦ)_i ∂²x_i/∂q∂q (central differences of Jᵀ∇_xΦ), so that
 * H + C is the exact Hessian (true element Hessians). Call right after
 * crom_nlsim_objective at the same q with H requested. */
int crom_nlsim_curvature(crom_nlsim *s, const double *q, double *C);

/* Full-space positions x [n] = X + B a and velocities v [n] = B va of the
 * current state (either may be NULL): O(n p), which a step never pays. */
void crom_nlsim_positions(const crom_nlsim *s, double *x, double *v);

/* Kinetic ½vᵀMv, elastic E(x) and external −f_ext(t)·(x − X) energies of
 * the current state. */
int crom_nlsim_energies(crom_nlsim *s, double *kinetic, double *elastic, double *external);

/* Largest ‖x_v − X_v − ū_v(t)‖ over BC vertices (m). */
double crom_nlsim_constraint_residual(const crom_nlsim *s);

void crom_nlsim_free(crom_nlsim *s);

#endif
