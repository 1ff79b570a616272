/* newton.h — the one minimizer of a latent step's incremental potential
 * (LiCROM eq. 5 restricted to the subspace: eq. 6-8), shared by the linear
 * subspace stepper (rsim.c) and the nonlinear map stepper (nlsim.c).
 *
 * It runs damped Newton iterations on E(q), q in R^r: a direction d from the
 * problem (usually H d = -g), a check that d descends, a stop when the
 * correction's size falls to the tolerance, and otherwise the shared
 * backtracking line search (lib/base/linesearch.h). Where H is indefinite or the
 * direction fails, it switches once to SPD-projected element Hessians
 * ("project") and tries again. With `descent` set it is the projected
 * gradient descent of the paper's reference code instead: it never projects,
 * never stops on a full correction, and stops when the accepted step is
 * within the tolerance.
 *
 * A problem may reuse a factored Hessian across iterations and steps (the
 * chord or "lagged" Newton method): it says through wants_hessian when the
 * objective must compute H, and its direction then uses the last factor.
 * When such a direction fails (no direction, no descent, no acceptable
 * step), the driver asks for a fresh Hessian (stale) before it switches to
 * projected Hessians. With a quasi-Newton memory (crom_newton_work.memory)
 * the reused factor is corrected by the curvature the iterations have seen
 * since it was made: L-BFGS (Nocedal & Wright 2006, Algorithm 7.4) with the
 * factor as its initial matrix H_0, over the pairs s = q_{k+1} − q_k,
 * y = g_{k+1} − g_k of accepted steps, kept across solves (steps) until the
 * next fresh Hessian. The pairs of earlier steps stay exact secants of the
 * current objective as long as the steps' objectives differ only by terms
 * linear in q (the predictor, loads and prescribed motions of an implicit
 * Euler step do). The chord method converges linearly at the rate of
 * ‖I − H_0⁻¹H‖; the corrections speed it up where H has drifted from H_0.
 *
 * A problem whose gradient costs little beyond its value (ls_gradient) has
 * the line search evaluate both, and the next iteration starts from the
 * accepted point's value and gradient instead of evaluating them again.
 */
#ifndef CROM_NEWTON_H
#define CROM_NEWTON_H

/* What the driver needs from a stepper; ctx is passed back to each call. */
typedef struct {
    int r;              /* latent dimension */
    /* E(q), its gradient g [r] and (H not NULL) Hessian H [r][r]; project:
     * SPD-projected element Hessians. Returns 0 or an error (recorded). */
    int (*objective)(void *ctx, const double *q, double *E, double *g, double *H, int project);
    /* The direction d [r] at iteration it, at q, from g and H (H is NULL
     * in descent mode and when the problem reuses its last Hessian). Returns 0 with d set, 1 when no direction exists here
     * (a singular or indefinite matrix), or an error code > 1 (recorded). */
    int (*direction)(void *ctx, int it, int project, const double *q, const double *g, const double *H,
                     double *d);
    /* The size of a correction d, in the units of the tolerance. */
    double (*size)(void *ctx, const double *d);
    /* Optional (NULL: a Hessian at every iteration): 1 if iteration it
     * needs a fresh Hessian, 0 if the direction may reuse the last one. */
    int (*wants_hessian)(void *ctx, int it);
    /* Optional, with wants_hessian: the reused Hessian failed; the next
     * iteration must compute a fresh one. */
    void (*stale)(void *ctx);
    int descent;        /* 1: gradient descent (see above), no Hessian */
    const char *method; /* "Newton", "Gauss-Newton": for messages */
    const char *singular; /* what failed when no direction exists, for messages */
    int ls_gradient;    /* 1: the line search computes gradients too (see above) */
} crom_newton_problem;

/* The quasi-Newton memory of a lagged problem: up to m pairs (s, y) in r
 * unknowns, owned by the stepper and kept across its steps. */
typedef struct {
    int r, m, k, head;  /* unknowns, capacity, pairs stored, next slot */
    double *s, *y;      /* [m][r] */
    double *rho, *a;    /* [m] 1/yᵀs and the two-loop's coefficients */
} crom_newton_memory;

/* Memory for m >= 1 pairs in r >= 1 unknowns (CROM_EUSAGE, CROM_EINTERNAL). */
int crom_newton_memory_init(crom_newton_memory *Q, int r, int m);

/* Forget every pair (a new cubature, a restarted run). */
void crom_newton_memory_reset(crom_newton_memory *Q);

/* Release it (safe on a zeroed struct). */
void crom_newton_memory_free(crom_newton_memory *Q);

/* Buffers of crom_newton_solve, owned by the stepper and free for it to
 * use between steps: g, d, qt [r], H [r][r] (unused in descent mode); the
 * quasi-Newton memory of a lagged problem (NULL: the plain chord method). */
typedef struct {
    double *g, *H, *d, *qt;
    crom_newton_memory *memory;
} crom_newton_work;

/* Minimize from q (in: the predictor; out: the minimizer) with at most
 * max_iter iterations to the tolerance tol. *iterations, *residual (the
 * size of the last correction) and *converged report how it went. Returns
 * 0; CROM_EDATA when no direction exists even with projected Hessians
 * ("step STEP: <singular>"), or when Newton has not converged after
 * max_iter iterations ("step STEP did not converge: ..."); or the
 * objective's and direction's errors; CROM_EINTERNAL when out of memory. */
int crom_newton_solve(const crom_newton_problem *p, void *ctx, const crom_newton_work *w, double *q, double tol,
                      int max_iter, long step, int *iterations, double *residual, int *converged);

#endif
