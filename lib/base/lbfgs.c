/* lbfgs.c — the L-BFGS two-loop recursion (see lbfgs.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/lbfgs.h"

void crom_lbfgs_free(crom_lbfgs *L)
{
    if (!L)
        return;
    free(L->s);
    free(L->y);
    free(L->rho);
    free(L->a);
    memset(L, 0, sizeof *L);
}

int crom_lbfgs_init(crom_lbfgs *L, size_t n, int m)
{
    memset(L, 0, sizeof *L);
    if (n < 1 || m < 1)
        return crom_err(CROM_EUSAGE, "L-BFGS of %zu unknowns with %d pairs", n, m);
    L->n = n;
    L->m = m;
    L->s = crom_malloc(sizeof(float) * n * (size_t)m);
    L->y = crom_malloc(sizeof(float) * n * (size_t)m);
    L->rho = crom_malloc(sizeof(double) * (size_t)m);
    L->a = crom_malloc(sizeof(double) * (size_t)m);
    if (!L->s || !L->y || !L->rho || !L->a) {
        crom_lbfgs_free(L);
        return CROM_EINTERNAL;
    }
    return 0;
}

void crom_lbfgs_reset(crom_lbfgs *L)
{
    L->k = 0;
    L->head = 0;
}

int crom_lbfgs_push(crom_lbfgs *L, const double *s, const double *y)
{
    double ys = 0, ss = 0, yy = 0;
    for (size_t i = 0; i < L->n; i++) {
        ys += y[i] * s[i];
        ss += s[i] * s[i];
        yy += y[i] * y[i];
    }
    if (!(ys > 1e-10 * sqrt(ss * yy)) || !isfinite(ys))
        return 0;
    float *sj = L->s + (size_t)L->head * L->n, *yj = L->y + (size_t)L->head * L->n;
    ys = 0; /* of the stored (float) pair, so that H stays positive definite */
    for (size_t i = 0; i < L->n; i++) {
        sj[i] = (float)s[i];
        yj[i] = (float)y[i];
        ys += (double)sj[i] * yj[i];
    }
    if (!(ys > 0)) /* lost to float rounding: do not keep it */
        return 0;
    L->rho[L->head] = 1 / ys;
    L->head = (L->head + 1) % L->m;
    if (L->k < L->m)
        L->k++;
    return 1;
}

void crom_lbfgs_direction(crom_lbfgs *L, const double *g, double *d)
{
    size_t n = L->n;
    for (size_t i = 0; i < n; i++)
        d[i] = -g[i];
    if (L->k == 0)
        return;
    /* newest to oldest: a_j = ρ_j s_jᵀ q, q −= a_j y_j (q = −d) */
    for (int t = 0; t < L->k; t++) {
        int j = (L->head - 1 - t + 2 * L->m) % L->m;
        const float *sj = L->s + (size_t)j * n, *yj = L->y + (size_t)j * n;
        double dot = 0;
        for (size_t i = 0; i < n; i++)
            dot += sj[i] * d[i];
        L->a[j] = L->rho[j] * dot;
        for (size_t i = 0; i < n; i++)
            d[i] -= L->a[j] * yj[i];
    }
    /* H_0 = γ I with the newest pair */
    int nw = (L->head - 1 + L->m) % L->m;
    const float *yn = L->y + (size_t)nw * n;
    double yy = 0;
    for (size_t i = 0; i < n; i++)
        yy += (double)yn[i] * yn[i];
    double gamma = 1 / (L->rho[nw] * yy);
    for (size_t i = 0; i < n; i++)
        d[i] *= gamma;
    /* oldest to newest: b = ρ_j y_jᵀ r, r += (a_j − b) s_j */
    for (int t = L->k - 1; t >= 0; t--) {
        int j = (L->head - 1 - t + 2 * L->m) % L->m;
        const float *sj = L->s + (size_t)j * n, *yj = L->y + (size_t)j * n;
        double dot = 0;
        for (size_t i = 0; i < n; i++)
            dot += yj[i] * d[i];
        double bcoef = L->rho[j] * dot;
        for (size_t i = 0; i < n; i++)
            d[i] += (L->a[j] - bcoef) * sj[i];
    }
}
