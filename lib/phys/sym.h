/* sym.h — symmetric sparse matrices, stored as their upper triangle in
 * compressed sparse columns: the layout of crom_fem's assembled Hessian,
 * which the solvers (chol.h) and eigensolvers (modes.h) take. */
#ifndef CROM_SYM_H
#define CROM_SYM_H

/* A symmetric matrix stored as its upper triangle in compressed sparse
 * columns (row <= col), int indices: the layout of crom_fem's Hessian. The
 * arrays are borrowed, not owned. */
typedef struct {
    int n;
    const int *colptr;   /* [n+1] */
    const int *rowind;   /* [nnz] */
    const double *val;   /* [nnz] */
} crom_sym;

/* y = A x for the full symmetric A. */
void crom_sym_matvec(const crom_sym *A, const double *x, double *y);

/* Clamp the negative eigenvalues of a small dense symmetric n×n matrix M
 * (row-major, n <= CROM_SYM_DENSE_MAX) to 0: an element Hessian projected to
 * positive semi-definite. A matrix that has a Cholesky factor is left as it
 * is (most are, and the factorization is far cheaper than the
 * eigensolver). Returns 0, or 1 when n is out of range or LAPACK fails. */
#define CROM_SYM_DENSE_MAX 24
int crom_sym_dense_project(double *M, int n);

#endif
