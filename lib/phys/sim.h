/* sim.h — full-space implicit Euler for stable neo-Hookean solids and thin
 * shells (a surface mesh: StVK membrane and hinge bending, shell.h).
 *
 * Each step minimizes the incremental potential (LiCROM eq. 5 in full space)
 *   IP(x) = 1/(2h²) ‖x − x̂‖²_M + A/(2h) ‖x − x_n‖²_M + E(x) − f_ext·x + C(x),
 *   x̂ = x_n + h v_n,
 * with M the lumped mass, A the damping rate, E the elastic energy plus
 * the rods' (rod.h: their Hessian, which joins the two ends of each rod
 * densely, is applied as a product inside CG and left out of the sparse
 * factor), C the collision/friction energy (contact.h); pinned and prescribed vertices are
 * eliminated (Dirichlet DOFs set to their targets). Newton with per-element
 * SPD-projected Hessians; the linear systems are solved by CG preconditioned
 * with a sparse Cholesky factor that is reused across iterations and steps
 * and refreshed only when CG slows down (analysis once per mesh); Armijo
 * backtracking line search; the step ends when the Newton correction
 * ‖Δx‖∞ is below tol times the bounding-box diagonal (a measure that holds
 * for any time step, static ones included). Then v = (x − x_n)/h. */
#ifndef CROM_SIM_H
#define CROM_SIM_H

#include "phys/scenario.h"
#include "phys/system.h"
#include "phys/chol.h"
#include "phys/rod.h"

typedef struct {
    int newton;           /* Newton iterations of the step */
    int cg;               /* CG iterations, summed */
    int factorizations;   /* numeric factorizations in the step */
    int cuts;             /* line-search halvings, summed */
    double residual;      /* last Newton correction ‖Δx‖∞ / L */
    double t_assemble, t_factor, t_solve, t_linesearch, t_total; /* s */
} crom_sim_stats;

typedef struct {
    const crom_scenario *sc;
    const crom_mesh *mesh;
    crom_system sys;      /* a solid (tet mesh) or a shell (surface mesh): its masses, pattern, energy */
    int nv, n;
    double L;             /* bounding-box diagonal (m) */
    double t;             /* time of the current state (s) */
    long step;            /* steps done */
    double *x, *v;        /* state: positions and velocities [nv][3] */
    /* private */
    double *xn, *xhat, *g, *d, *xt, *m3, *fext, *H, *work, *lam;
    unsigned char *fixed;
    int *pin, npin;
    int nvel, *vel_ptr, *vel_idx;     /* CSR lists of vertices per BC */
    int nforce, *force_ptr, *force_idx;
    double *force_mass;               /* total mass of each force region */
    crom_chol *chol;
    int have_factor, refactor;
    crom_rod_set rods;                   /* the scenario's rods (--rod) on the mesh */
    double *rod_H;                    /* [nrod][9] their Hessians in their gaps, at the last assembly */
    double t1;                        /* the time the step in progress ends at */
} crom_sim;

/* Set up a simulation of mesh under scenario sc (both borrowed): material,
 * regions (CROM_EUSAGE naming an unknown or empty region), masses, initial
 * state (rest, initial velocity and spin); the symbolic factorization is
 * done at the first step. */
int crom_sim_init(crom_sim *s, const crom_mesh *mesh, const crom_scenario *sc);

/* Advance one time step. Returns 0, or CROM_EDATA when Newton does not
 * converge within max_iter (message with the residual) or the state goes
 * non-finite. */
int crom_sim_step(crom_sim *s, crom_sim_stats *st);

/* The a-posteriori error indicator of a state reached by other means
 * (issue 18; a reduced run decoded onto this mesh): the step from positions
 * xprev and velocities vprev to positions x at time t1. Its residual is the
 * gradient g of the incremental potential at x over the free DOFs, ∇E(x) +
 * M((x − x̂)/h² + damping (x − x_n)/h) − f_ext − f_contact, zero at the full
 * step's solution; the indicator is the displacement that force stands
 * for, e = K₀⁻¹ g with K₀ the stiffness at rest (projected to SPD, factored
 * once; plus M/h² for a body with no pinned or prescribed DOF, whose rigid
 * motions it would not resist). *err = |e|_M / √m, the mass-weighted RMS of
 * e over the vertices (m); *urms the same of the displacement x − X; *bc
 * the largest distance of a pinned or prescribed DOF from its target (m).
 * The simulation, one of its own that is never stepped (CROM_EINTERNAL
 * otherwise: a stepped one's factor is no rest stiffness), is left at (x,
 * (x − xprev)/h) at t1. Returns 0, CROM_EDATA (a state not finite, a
 * stiffness at rest not positive definite), or CROM_EINTERNAL. */
int crom_sim_residual(crom_sim *s, double t1, const double *xprev, const double *vprev, const double *x,
                      double *err, double *urms, double *bc);

/* Kinetic ½vᵀMv, elastic E(x) and external −f_ext(t)·(x − X) energies;
 * the rods' energy at time t counts as external (the actuators' work). */
int crom_sim_energies(crom_sim *s, double *kinetic, double *elastic, double *external);

/* Displacement u = x − X into u[3nv]. */
void crom_sim_displacement(const crom_sim *s, double *u);

void crom_sim_free(crom_sim *s);

#endif
