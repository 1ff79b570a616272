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

/* The upper-CSC pattern of a matrix of 3×3 blocks over nv vertices: a full
 * block for every pair of vertices that share one of nelem elements (the
 * vertices of element e are given by verts(ctx, e, v), returning their
 * count, at most 8), and every diagonal block's upper half; rows sorted in
 * each column, the diagonal last. *colptr [3 nv + 1] and *rowind [*nnz]
 * are malloc'ed. Returns 0, or CROM_EINTERNAL (out of memory, or more than
 * 2^31 entries). */
int crom_sym_block_pattern(int nv, int nelem, int (*verts)(const void *ctx, int e, int *v), const void *ctx,
                           int **colptr, int **rowind, int *nnz);

/* Finish an assembled gradient g [n] and upper-CSC Hessian H (either may
 * be NULL) of lumped masses mass [n/3]: the Dirichlet DOFs fixed [n] (may be
 * NULL) eliminated (g_i = 0; their rows and columns of H the identity's),
 * and mass_scale m_v added to the diagonal of every free DOF of vertex v
 * (implicit Euler's M/h²). */
void crom_sym_dirichlet_mass(int n, const int *colptr, const int *rowind, const unsigned char *fixed,
                             const double *mass, double mass_scale, double *g, double *H);

/* The index of entry (r, c), r <= c, in an upper-CSC pattern that has it. */
int crom_sym_entry(const int *colptr, const int *rowind, int r, int c);

#endif
