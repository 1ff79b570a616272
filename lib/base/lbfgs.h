/* lbfgs.h — the limited-memory BFGS direction (Nocedal & Wright 2006,
 * Algorithm 7.4, the two-loop recursion): the descent direction
 * d = −H g of a quasi-Newton inverse Hessian H built from the last m
 * pairs s_i = x_{i+1} − x_i, y_i = g_{i+1} − g_i, with H_0 = γ I,
 * γ = sᵀy / yᵀy of the newest pair (eq. 7.20). What the Neural Modes paper
 * trains with (Wang et al. 2024, §5: L-BFGS with line search); the line
 * search is the caller's, on its own objective. Its pairs are network
 * parameters (up to millions), kept in float. The reduced Newton solver
 * keeps its own memory (lib/rom/newton.c): a few hundred latent unknowns in
 * double, multiplied by BLAS, with the factored reduced Hessian as H_0
 * instead of γ I — the same recursion, other storage and H_0.
 */
#ifndef CROM_LBFGS_H
#define CROM_LBFGS_H

#include <stddef.h>

typedef struct {
    size_t n;          /* unknowns */
    int m;             /* pairs kept */
    int k;             /* pairs stored (<= m) */
    int head;          /* slot of the next pair */
    float *s, *y;      /* [m][n] the pairs (float: they only shape the step) */
    double *rho, *a;   /* [m] 1 / yᵀs and the first loop's coefficients */
} crom_lbfgs;

/* Memory for n unknowns and m pairs (m >= 1). CROM_EUSAGE, CROM_EINTERNAL. */
int crom_lbfgs_init(crom_lbfgs *L, size_t n, int m);

void crom_lbfgs_free(crom_lbfgs *L);

/* Forget every pair (the next direction is −g). */
void crom_lbfgs_reset(crom_lbfgs *L);

/* Keep the pair s = x_new − x_old, y = g_new − g_old when its curvature
 * yᵀs is positive beyond round-off (yᵀs > 1e-10 |y| |s|), dropping the
 * oldest beyond m. Returns 1 if kept, 0 if skipped. */
int crom_lbfgs_push(crom_lbfgs *L, const double *s, const double *y);

/* d [n] = −H g [n] by the two-loop recursion; −g with no pair stored. */
void crom_lbfgs_direction(crom_lbfgs *L, const double *g, double *d);

#endif
