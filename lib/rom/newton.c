/* newton.c — the latent step minimizer (see newton.h). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/linesearch.h"
#include "rom/newton.h"

/* the objective without Hessian, for the line search */
typedef struct {
    const crom_newton_problem *p;
    void *ctx;
    int project;
} ls_ctx;

static int ls_eval(void *ctx, const double *q, double *f, double *g)
{
    ls_ctx *c = ctx;
    return c->p->objective(c->ctx, q, f, g, NULL, c->project);
}

int crom_newton_solve(const crom_newton_problem *p, void *ctx, const crom_newton_work *w, double *q, double tol,
                      int max_iter, long step, int *iterations, double *residual, int *converged)
{
    int r = p->r, rc = 0, project = 0, gd = p->descent;
    double *gt = crom_malloc(sizeof(double) * (size_t)r); /* the line search's gradient */
    if (!gt)
        return CROM_EINTERNAL;
    *iterations = 0;
    *residual = INFINITY;
    *converged = 0;
    for (int it = 0; it < max_iter && !rc;) {
        double E;
        /* fresh: a Hessian computed at this iteration (not reused) */
        int fresh = !gd && (!p->wants_hessian || p->wants_hessian(ctx, it));
        if ((rc = p->objective(ctx, q, &E, w->g, fresh ? w->H : NULL, project)))
            break;
        int dr = p->direction(ctx, it, project, q, w->g, fresh ? w->H : NULL, w->d);
        if (dr > 1) {
            rc = dr;
            break;
        }
        if (dr == 1) {
            if (!gd && !fresh) {
                p->stale(ctx); /* a reused Hessian: try a fresh one first */
                continue;
            }
            if (!gd && !project) {
                project = 1; /* indefinite: project element Hessians from now on */
                continue;
            }
            rc = crom_err(CROM_EDATA, "step %ld: %s", step + 1, p->singular);
            break;
        }
        double slope = 0;
        for (int i = 0; i < r; i++)
            slope += w->g[i] * w->d[i];
        if (!(slope < 0)) {
            if (!gd && !fresh) {
                p->stale(ctx);
                continue;
            }
            if (!gd && !project) {
                project = 1;
                continue;
            }
            *residual = p->size(ctx, w->d);
            *converged = 1; /* no descent left: a stationary point */
            break;
        }
        it++;
        *iterations = it;
        *residual = p->size(ctx, w->d);
        if (*residual <= tol && !gd) {
            for (int i = 0; i < r; i++)
                q[i] += w->d[i];
            *converged = 1;
            break;
        }
        /* Armijo line search; below the energy's resolution the directional
         * derivative decides */
        double scale = fabs(E) + 1e-300;
        ls_ctx lc = {p, ctx, project};
        double alpha = crom_linesearch(ls_eval, &lc, (size_t)r, q, w->d, E, slope, 64 * DBL_EPSILON * scale,
                                       -slope < 1e-10 * scale, w->qt, gt, NULL);
        if (alpha == 0) {
            if (!gd && !fresh) {
                p->stale(ctx);
                continue;
            }
            if (!gd && !project) {
                project = 1;
                continue;
            }
            *converged = 1; /* no decrease possible: as converged as it gets */
            break;
        }
        memcpy(q, w->qt, sizeof(double) * (size_t)r);
        if (gd && alpha * *residual <= tol) {
            *converged = 1;
            break;
        }
    }
    free(gt);
    if (!rc && !*converged && !gd)
        rc = crom_err(CROM_EDATA,
                      "step %ld did not converge: correction %.3g > --tol %.3g after %d %s iterations "
                      "(try a smaller --dt or a larger --max-iter)",
                      step + 1, *residual, tol, max_iter, p->method);
    return rc;
}
