/* rsim.h — implicit Euler in a linear subspace u(X) = W(X) q (LiCROM §4–5,
 * eq. 5–8), the reduced counterpart of sim.h with the same scenario.
 *
 * Each step minimizes over q
 *   E(q) = 1/(2h²) (q − q̂)ᵀ M_r (q − q̂) + A/(2h) (q − q_n)ᵀ M_r (q − q_n)
 *        + Σ_e w_e V_e Ψ(F_e(X + W q)) − f_rᵀ q + κ/2 Σ_bc Σ_v m_v ‖W_v q − ū_v(t)‖²
 *        + contact(X + W q at the surface vertices),
 *   q̂ = q_n + h q̇_n,
 * with the exact reduced mass M_r = ρ WᵀVW (lumped volumes), the elastic
 * energy by cubature (weights w_e), reduced gravity and forces f_r, pinned and
 * prescribed-velocity regions as a stiff penalty of rate κ on the latent
 * directions that move them (their largest miss is reported), and the same frictional planes as the full simulator at
 * every surface vertex. Solvers:
 *   newton  exact reduced gradient and Hessian Σ w_e W_eᵀ H_e W_e (LiCROM §7),
 *           true element Hessians, projected to SPD when the sum is not
 *           positive definite, its factor reused across iterations and
 *           steps with quasi-Newton corrections (rsim.c, newton.h); started
 *           from q̂ plus the last step's correction; line search; converged
 *           when the RMS displacement of the correction is below tol times
 *           the size;
 *   gd      LiCROM §5: descent directions −G⁻¹∇E with G = Σ w_e Σ_a W_aᵀ W_a
 *           prefactored (the least-squares projection of full-space
 *           increments at the cubature points, eq. 10), scaled by ρ/h² and
 *           with the boundary penalty's κP added so that constraints hold;
 *           line search; the paper runs a fixed number of iterations:
 *           max_iter is that count. Slow where stiffness dominates inertia. */
#ifndef CROM_RSIM_H
#define CROM_RSIM_H

#include "phys/scenario.h"
#include "rom/cubature.h"
#include "rom/elastic.h"
#include "rom/newton.h"

enum { CROM_RSIM_NEWTON = 0, CROM_RSIM_GD = 1 };

typedef struct {
    int iterations;
    double residual;            /* last correction, RMS displacement / size */
    double constraint_residual; /* largest ‖W_v q − ū_v‖ over BC vertices (m): not filled by the step
                                 * (a pass over every BC vertex, which grows with the mesh); the caller
                                 * asks crom_rsim_constraint_residual when it reports it */
    double seconds;
    int converged;
    int vertex_evals;           /* vertex positions one evaluation of the step's objective decodes: 4 per
                                 * cubature tet (a map: its cubature's vertices), plus every surface vertex
                                 * per collision plane or sphere; whatever the size of the mesh */
} crom_rsim_stats;

typedef struct {
    int *idx;           /* vertices of the cubature mesh */
    int n;
    double mass;        /* Σ m_v */
    double *P;          /* [r][r] Σ m_v W_vᵀ W_v */
    double *S;          /* [r][3] Σ m_v W_vᵀ */
    const crom_bc *bc;  /* NULL for a pin */
} crom_rsim_bc;

/* A drag (crom-live, the cursor's spring): a spring of total stiffness k
 * (N/m) from the point c to region ref, spread over its vertices by mass,
 *   k/(2 m_R) Σ_{v∈R} m_v ‖x_v − (X_v + c − X̄_R)‖²,   X̄_R = Σ m_v X_v / m_R,
 * which pulls the region's rest centroid toward c (each vertex toward c plus
 * its rest offset from the centroid), integrated implicitly with the rest of
 * the step. With x_v = X_v + W_v q it is the quadratic
 *   k/(2 m_R) (qᵀP q − 2 qᵀS d + m_R |d|²),  d = c − X̄_R,
 * over the region's sums P, S (crom_rsim_bc). */
typedef struct {
    char ref[128];
    double c[3], k;
    double xbar[3];     /* X̄_R on the current cubature's mesh */
    crom_rsim_bc b;
} crom_rsim_drag;

/* A rod of the scenario (--rod, phys/rod.h) on the current cubature's
 * mesh: its gap d(q) = d0 + D q between the ends' centroids, with D =
 * S_Bᵀ/m_B − S_Aᵀ/m_A over the ends' region sums, exact in a linear
 * subspace. */
typedef struct {
    double d0[3];       /* the gap at rest (m) */
    double rest;        /* |d0| */
    double *D;          /* [3][r] */
} crom_rsim_rod;

typedef struct {
    const crom_scenario *sc;
    const crom_cubature *cub;
    crom_material mat;
    crom_material *mats;              /* regions of other materials (--youngs REGION=E): [nmat] */
    const crom_material **kmat;       /* [cubature tets] each one's material; NULL: mat for all */
    int r, solver;
    double kappa;       /* BC penalty rate (1/s²) */
    double bc_threshold;/* constrained directions: μ >= threshold × BC mass fraction */
    int nconstrained;   /* how many latent directions the BCs constrain */
    double t;
    long step;
    double *q, *qd;     /* state (m, m/s) */
    double *corr;       /* the last step's q − q̂, added to Newton's start (rsim.c) */
    /* private, rebuilt per cubature */
    double *Mr, *fg, *G, *Gfac, L;
    int nbc, nforce;
    crom_rsim_bc *bc, *force;
    double *lam;        /* [nplanes][nsurf] lagged normal forces */
    double *qn, *qhat, *g, *H, *d, *qt, *gt, *fext;
    /* the objective's quadratic part ½aᵀQa + lᵀa + c₀ in a = q − q̂ (rsim.c,
     * crom_rsim_begin_step): Q [r][r] per cubature, κ Σ P_b [r][r], l [r]
     * and c₀ per step */
    double *Q, *Pk, *lin, c0;
    /* the factored reduced Hessian reused across iterations and steps (see
     * rsim.c, step_direction) */
    int lagged;         /* 1: reuse it (the default); 0: a fresh Hessian every iteration */
    double *Hfac;       /* [r][r] its Cholesky factor */
    int fac_ok;         /* Hfac holds a factor */
    int fac_iters;      /* iterations of this step since it was made */
    int fac_slow;       /* the last step needed more than its share: refresh (rsim.c) */
    double *vm;         /* [nv] lumped vertex masses of the cubature's mesh (kg) */
    int dense;          /* 1: regions of other densities set vm (M_r and gravity are summed from it) */
    int nrod;           /* the scenario's rods, rebuilt per cubature */
    crom_rsim_rod *rod;
    int ndrag;          /* drags (crom_rsim_drag_set), kept across cubatures */
    crom_rsim_drag *drag;
    crom_elastic el;    /* the elastic energy over the cubature (rebuilt per cubature) */
    crom_newton_memory mem; /* quasi-Newton pairs that correct the reused factor (newton.h) */
} crom_rsim;

/* Set up on a cubature (borrowed) with a scenario (borrowed); q = q0 and
 * q̇ = qd0 (NULL: rest). Regions resolve against the cubature's mesh: an
 * unknown or empty one is CROM_EUSAGE. kappa <= 0 picks 1e4/h². The penalty
 * acts only on the latent directions that move the BC vertices (see
 * rsim.c, constrain_directions: threshold 0.1 of the BC mass fraction);
 * set s->bc_threshold and call crom_rsim_set_cubature to change it. */
int crom_rsim_init(crom_rsim *s, const crom_cubature *cub, const crom_scenario *sc, int solver,
                   double kappa, const double *q0, const double *qd0);

/* Switch to another cubature (a remeshed body, LiCROM §4): the state q, q̇
 * carries over unchanged. CROM_EDATA if its model_id or rank differs. */
int crom_rsim_set_cubature(crom_rsim *s, const crom_cubature *cub);

/* Pull region ref toward c with a spring of stiffness k (N/m; see
 * crom_rsim_drag), from the next step on; a region dragged already has its
 * point and stiffness replaced. A new stiffness changes the step's Hessian
 * (its reused factor is dropped); a new point only its linear part.
 * CROM_EUSAGE for an unknown or empty region, a non-finite point or a
 * stiffness not positive. */
int crom_rsim_drag_set(crom_rsim *s, const char *ref, const double c[3], double k);

/* Release the drag of region ref (NULL: every drag). Returns the number
 * released. */
int crom_rsim_drag_release(crom_rsim *s, const char *ref);

/* The scenario (s->sc) has grown forces since the last call, init or
 * cubature switch (its nforce): take the new ones into the step's loads,
 * leaving everything else of the step as it was, so that a force appended
 * at time t with the window [t, T1] gives the run that has it from the
 * start (crom-live). CROM_EUSAGE for an unknown or empty region. */
int crom_rsim_sync_forces(crom_rsim *s);

/* Advance one step. CROM_EDATA when Newton does not converge in max_iter
 * iterations (gd never fails that way: its count is fixed). */
int crom_rsim_step(crom_rsim *s, crom_rsim_stats *st);

/* Reduced energy E(q) of the current step and its gradient (for tests). */
int crom_rsim_objective(crom_rsim *s, const double *q, double *E, double *g, double *H, int project);

/* Prepare the step's predictor and loads without solving (for tests). */
void crom_rsim_begin_step(crom_rsim *s);

/* Kinetic ½q̇ᵀM_r q̇, elastic (by cubature) and external −f_r·q energies. */
int crom_rsim_energies(crom_rsim *s, double *kinetic, double *elastic, double *external);

/* Largest ‖W_v q − ū_v(t)‖ over BC vertices at the current state (m). */
double crom_rsim_constraint_residual(const crom_rsim *s);

void crom_rsim_free(crom_rsim *s);

#endif
