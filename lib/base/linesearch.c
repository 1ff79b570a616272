/* linesearch.c — backtracking Armijo line search (see linesearch.h). */
#include <math.h>

#include "base/err.h"
#include "base/linesearch.h"

double crom_linesearch(crom_linesearch_fn f, void *ctx, size_t n, const double *x, const double *d, double f0,
                       double slope, double noise, int tiny, double *xt, double *g, int *cuts)
{
    double alpha = 1;
    for (;;) {
        double ft;
        for (size_t i = 0; i < n; i++)
            xt[i] = x[i] + alpha * d[i];
        int rc = f(ctx, xt, &ft, NULL);
        if (rc == 0 && ft <= f0 + 1e-4 * alpha * slope + noise)
            break;
        if (rc == 0 && tiny && f(ctx, xt, &ft, g) == 0) {
            double dphi = 0;
            for (size_t i = 0; i < n; i++)
                dphi += g[i] * d[i];
            if (fabs(dphi) <= 0.5 * fabs(slope))
                break;
        }
        alpha *= 0.5;
        if (cuts)
            (*cuts)++;
        if (alpha < 1e-12) {
            alpha = 0;
            break;
        }
    }
    crom_err_clear();
    return alpha;
}
