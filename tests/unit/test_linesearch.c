/* test_linesearch.c — the shared Armijo backtracking: full steps accepted on
 * a quadratic, the first halving that satisfies the condition (and not one
 * before), undefined regions avoided, ascent refused, and the
 * directional-derivative test where the objective's value cannot resolve the
 * decrease. */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "base/err.h"
#include "base/linesearch.h"

/* f = off + ½ Σ a_i (x_i − c)², undefined for x_0 > lim; evaluated away
 * from x_0 = start it comes out `bump` larger (a stand-in for round-off) */
typedef struct {
    double off, c, lim;
    double a[3];
    double bump, start;
} quad;

static int f_quad(void *ctx, const double *x, double *f, double *g)
{
    const quad *q = ctx;
    if (x[0] > q->lim)
        return crom_err(CROM_EDATA, "outside the domain");
    *f = q->off + (x[0] != q->start ? q->bump : 0);
    for (int i = 0; i < 3; i++) {
        *f += 0.5 * q->a[i] * (x[i] - q->c) * (x[i] - q->c);
        if (g)
            g[i] = q->a[i] * (x[i] - q->c);
    }
    return 0;
}

static double armijo_gap(quad *q, const double *x, const double *d, double alpha, double f0, double slope)
{
    double xt[3], ft;
    for (int i = 0; i < 3; i++)
        xt[i] = x[i] + alpha * d[i];
    if (f_quad(q, xt, &ft, NULL))
        return INFINITY;
    return ft - (f0 + 1e-4 * alpha * slope);
}

int main(void)
{
    check_begin("test_linesearch");
    quad q = {0, 0, INFINITY, {1, 10, 100}, 0, 0};
    double x[3] = {1, -2, 0.5}, g[3], d[3], xt[3], gt[3], f0;
    int cuts = 0;

    /* the Newton step on a quadratic: α = 1, no cuts, xt the minimum */
    f_quad(&q, x, &f0, g);
    double slope = 0;
    for (int i = 0; i < 3; i++) {
        d[i] = -g[i] / q.a[i];
        slope += g[i] * d[i];
    }
    double a = crom_linesearch(f_quad, &q, 3, x, d, f0, slope, 0, 0, xt, gt, &cuts);
    CHECK_NEAR(a, 1, 0);
    CHECK(cuts == 0);
    CHECK_NEAR(xt[0] * xt[0] + xt[1] * xt[1] + xt[2] * xt[2], 0, 1e-28);

    /* steepest descent, too long for the stiff direction: the first halving
     * that satisfies Armijo, and the one before it does not */
    slope = 0;
    for (int i = 0; i < 3; i++) {
        d[i] = -g[i];
        slope += g[i] * d[i];
    }
    cuts = 0;
    a = crom_linesearch(f_quad, &q, 3, x, d, f0, slope, 0, 0, xt, gt, &cuts);
    fprintf(stderr, "steepest descent: alpha %g after %d halvings\n", a, cuts);
    CHECK(a > 0 && a < 1);
    CHECK_NEAR(a, ldexp(1, -cuts), 0);
    CHECK(armijo_gap(&q, x, d, a, f0, slope) <= 0);
    CHECK(armijo_gap(&q, x, d, 2 * a, f0, slope) > 0);

    /* an objective undefined beyond x_0 = 1.2: the search stays inside */
    quad qd = {0, 0.9, 1.2, {1, 1, 1}, 0, 0};
    double x0[3] = {0, 0.9, 0.9}, d0[3] = {4, 0, 0};
    f_quad(&qd, x0, &f0, g);
    slope = g[0] * d0[0];
    a = crom_linesearch(f_quad, &qd, 3, x0, d0, f0, slope, 0, 0, xt, gt, NULL);
    CHECK(a > 0 && xt[0] <= 1.2);
    CHECK(crom_errcode() == 0); /* failed evaluations leave no error behind */

    /* an ascent direction passed off as descent: no acceptable step */
    f_quad(&q, x, &f0, g);
    slope = 0;
    for (int i = 0; i < 3; i++) {
        d[i] = g[i];
        slope += g[i] * d[i];
    }
    CHECK(crom_linesearch(f_quad, &q, 3, x, d, f0, -slope, 0, 0, xt, gt, NULL) == 0);

    /* below the value's resolution: f = 1e8 + ½|x − 1|² one micrometre from
     * its minimum, where the decrease 5e-13 is far below one ulp of f (1.5e-8)
     * and round-off makes f(x + αd) one ulp larger: Armijo alone fails, the
     * round-off allowance or the directional derivative accept the full step */
    double x1[3] = {1 + 1e-6, 1, 1}, d1[3] = {-1e-6, 0, 0};
    quad qt = {1e8, 1, INFINITY, {1, 1, 1}, 1.5e-8, x1[0]};
    f_quad(&qt, x1, &f0, g);
    slope = g[0] * d1[0];
    a = crom_linesearch(f_quad, &qt, 3, x1, d1, f0, slope, 0, 0, xt, gt, NULL);
    CHECK(a < 1e-9 && xt[0] == x1[0]);
    a = crom_linesearch(f_quad, &qt, 3, x1, d1, f0, slope, 0, 1, xt, gt, NULL);
    CHECK_NEAR(a, 1, 0);
    CHECK_NEAR(xt[0], 1, 1e-15);
    CHECK_NEAR(crom_linesearch(f_quad, &qt, 3, x1, d1, f0, slope, 2e-8, 0, xt, gt, NULL), 1, 0);
    return check_done();
}
