/* chol.h — sparse Cholesky (CHOLMOD, supernodal, with a METIS
 * nested-dissection ordering of the vertex graph expanded to 3×3 DOF
 * blocks, analyzed once per pattern), and preconditioned conjugate
 * gradients that reuse a stale factorization as preconditioner. */
#ifndef CROM_CHOL_H
#define CROM_CHOL_H

#include <stddef.h>

#include "phys/sym.h"

/* Sparse Cholesky factorization A = L Lᵀ of matrices sharing one pattern. */
typedef struct crom_chol crom_chol;

/* Analyze the pattern (ordering + symbolic factorization, once per mesh).
 * block = 3 orders the n/3 vertices with METIS_NodeND and expands to their
 * 3 DOFs (block = 1 orders DOFs directly). Returns NULL with an error
 * recorded on failure. */
crom_chol *crom_chol_analyze(int n, const int *colptr, const int *rowind, int block);

/* Numeric factorization of values val (same pattern). Returns 0, or
 * CROM_EDATA if the matrix is not positive definite. */
int crom_chol_factor(crom_chol *c, const double *val);

/* Solve A x = b with the last factorization (x may alias b). */
int crom_chol_solve(crom_chol *c, const double *b, double *x);

/* Solve A X = B for nrhs right-hand sides at once, B and X n x nrhs
 * column-major (X may alias B): cheaper per column than one at a time. */
int crom_chol_solve_many(crom_chol *c, int nrhs, const double *b, double *x);

/* Seconds spent so far in analysis, factorizations and solves, and counts. */
void crom_chol_stats(const crom_chol *c, double *t_analyze, double *t_factor,
                     double *t_solve, long *nfactor, long *nsolve);

void crom_chol_free(crom_chol *c);

/* Preconditioned conjugate gradients for A x = b with M⁻¹ = the factor c
 * (of some earlier matrix of the same pattern). x holds the initial guess
 * (zero is fine). Stops when ‖b − A x‖ <= rtol ‖b‖ or after maxit
 * iterations. Returns the iteration count (>= 0) when converged, -1 when it
 * did not converge within maxit or met non-positive curvature (A not SPD),
 * or -CROM_E* on an error. work holds 4n doubles. */
int crom_chol_pcg(const crom_sym *A, crom_chol *c, const double *b, double *x,
                  double rtol, int maxit, double *work);

/* The same for an operator given by its product: apply(ctx, x, y) sets
 * y = A x (A symmetric, n × n). */
int crom_chol_pcg_op(int n, void (*apply)(void *ctx, const double *x, double *y), void *ctx, crom_chol *c,
                     const double *b, double *x, double rtol, int maxit, double *work);

#endif
