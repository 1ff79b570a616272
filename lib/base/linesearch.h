/* linesearch.h — the backtracking (Armijo) line search shared by the time
 * steppers: full space (sim.c), cubature subspace (rsim.c) and nonlinear
 * latent map (nlsim.c). One rule for accepting a step everywhere.
 */
#ifndef CROM_LINESEARCH_H
#define CROM_LINESEARCH_H

#include <stddef.h>

/* The objective at x: its value in *f and, when g is not NULL, its gradient.
 * Returns 0, or non-zero where it is not defined (an inverted element): the
 * search then shortens the step. */
typedef int (*crom_linesearch_fn)(void *ctx, const double *x, double *f, double *g);

/* Search along the descent direction d from x, where f0 = f(x) and slope =
 * ∇f(x)·d < 0: halve α from 1 until the Armijo condition
 *     f(x + αd) <= f0 + 1e-4 α slope + noise
 * holds, noise being the round-off of f's value (without the allowance no
 * step could be accepted near convergence). When tiny is set, the predicted
 * decrease is below what f's value resolves, and a step is also accepted
 * when the directional derivative has fallen to half, |∇f(x+αd)·d| <=
 * ½|slope| (this uses g, workspace of n).
 * On return xt = x + αd. Returns α, or 0 when α fell below 1e-12 (no
 * acceptable step along d); *cuts (if not NULL) is increased by the number of
 * halvings. Errors of failed evaluations are cleared. */
double crom_linesearch(crom_linesearch_fn f, void *ctx, size_t n, const double *x, const double *d, double f0,
                       double slope, double noise, int tiny, double *xt, double *g, int *cuts);

#endif
