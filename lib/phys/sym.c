/* sym.c — symmetric sparse matrices stored as their upper triangle (see
 * sym.h). */
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
