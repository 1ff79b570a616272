/* sym.c — symmetric sparse matrices stored as their upper triangle, and
 * the SPD projection of small dense element matrices (see sym.h). */
#include <lapacke.h>
#include <string.h>

#include "phys/sym.h"

void crom_sym_matvec(const crom_sym *A, const double *x, double *y)
{
    int n = A->n;
    memset(y, 0, sizeof(double) * (size_t)n);
    for (int j = 0; j < n; j++) {
        double xj = x[j], yj = 0;
        for (int k = A->colptr[j]; k < A->colptr[j + 1]; k++) {
            int i = A->rowind[k];
            double a = A->val[k];
            y[i] += a * xj;
            if (i != j)
                yj += a * x[i];
        }
        y[j] += yj;
    }
}

int crom_sym_dense_project(double *M, int n)
{
    double w[CROM_SYM_DENSE_MAX], Q[CROM_SYM_DENSE_MAX * CROM_SYM_DENSE_MAX];
    if (n < 1 || n > CROM_SYM_DENSE_MAX)
        return 1;
    memcpy(Q, M, sizeof(double) * (size_t)n * n);
    if (LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'U', n, Q, n) == 0)
        return 0;
    memcpy(Q, M, sizeof(double) * (size_t)n * n);
    if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', n, Q, n, w) != 0)
        return 1;
    if (w[0] >= 0)
        return 0;
    memset(M, 0, sizeof(double) * (size_t)n * n);
    for (int k = 0; k < n; k++) {
        if (w[k] <= 0)
            continue;
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++)
                M[i * n + j] += w[k] * Q[i * n + k] * Q[j * n + k];
    }
    return 0;
}
