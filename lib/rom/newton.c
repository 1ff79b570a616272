/* newton.c — the latent step minimizer (see newton.h). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "base/err.h"
#include "base/linesearch.h"
#include "rom/newton.h"

void crom_newton_memory_free(crom_newton_memory *Q)
{
    if (!Q)
        return;
    free(Q->s);
    memset(Q, 0, sizeof *Q);
}

int crom_newton_memory_init(crom_newton_memory *Q, int r, int m)
{
    memset(Q, 0, sizeof *Q);
    if (r < 1 || m < 1)
        return crom_err(CROM_EUSAGE, "a quasi-Newton memory of %d pairs in %d unknowns", m, r);
    size_t n = (size_t)r, pairs = (size_t)m;
    Q->s = crom_malloc(sizeof(double) * (2 * pairs * n + 2 * pairs));
    if (!Q->s)
        return CROM_EINTERNAL;
    Q->r = r;
    Q->m = m;
    Q->y = Q->s + pairs * n;
    Q->rho = Q->y + pairs * n;
    Q->a = Q->rho + pairs;
    return 0;
}

void crom_newton_memory_reset(crom_newton_memory *Q)
{
    if (Q) {
        Q->k = 0;
        Q->head = 0;
    }
}

/* keep the pair s = q − qp, y = g − gp if its curvature yᵀs is positive
 * beyond round-off, dropping the oldest beyond m */
static void memory_push(crom_newton_memory *Q, const double *q, const double *qp, const double *g, const double *gp)
{
    int r = Q->r;
    double *sj = Q->s + (size_t)Q->head * r, *yj = Q->y + (size_t)Q->head * r;
    for (int i = 0; i < r; i++) {
        sj[i] = q[i] - qp[i];
        yj[i] = g[i] - gp[i];
    }
    double ys = cblas_ddot(r, sj, 1, yj, 1), ss = cblas_ddot(r, sj, 1, sj, 1), yy = cblas_ddot(r, yj, 1, yj, 1);
    if (!(ys > 1e-10 * sqrt(ss * yy)) || !isfinite(ys))
        return;
    Q->rho[Q->head] = 1 / ys;
    Q->head = (Q->head + 1) % Q->m;
    if (Q->k < Q->m)
        Q->k++;
}

/* d = −H_k g by the L-BFGS two-loop recursion (Nocedal & Wright 2006,
 * Algorithm 7.4) with the problem's direction on its reused factor as H_0
 * (d₀ = −H_0⁻¹ v) instead of a multiple of I; v [r] is scratch */
static int memory_direction(const crom_newton_problem *p, void *ctx, crom_newton_memory *Q, int it, int project,
                            const double *q, const double *g, double *v, double *d)
{
    int r = p->r;
    memcpy(v, g, sizeof(double) * (size_t)r);
    for (int t = 0; t < Q->k; t++) { /* newest to oldest: a_j = ρ_j s_jᵀ v, v −= a_j y_j */
        int j = (Q->head - 1 - t + 2 * Q->m) % Q->m;
        Q->a[j] = Q->rho[j] * cblas_ddot(r, Q->s + (size_t)j * r, 1, v, 1);
        cblas_daxpy(r, -Q->a[j], Q->y + (size_t)j * r, 1, v, 1);
    }
    int dr = p->direction(ctx, it, project, q, v, NULL, d);
    if (dr)
        return dr;
    for (int t = Q->k - 1; t >= 0; t--) { /* oldest to newest on −d: b = ρ_j y_jᵀ(−d), −d += (a_j − b) s_j */
        int j = (Q->head - 1 - t + 2 * Q->m) % Q->m;
        double b = -Q->rho[j] * cblas_ddot(r, Q->y + (size_t)j * r, 1, d, 1);
        cblas_daxpy(r, b - Q->a[j], Q->s + (size_t)j * r, 1, d, 1);
    }
    return 0;
}

/* the objective without Hessian, for the line search; with `keep` it also
 * computes the gradient and keeps value, gradient and point (the next
 * iteration starts from the accepted one) */
typedef struct {
    const crom_newton_problem *p;
    void *ctx;
    int project;
    int keep, valid;
    double E, *g, *x;
} ls_ctx;

static int ls_eval(void *ctx, const double *q, double *f, double *g)
{
    ls_ctx *c = ctx;
    if (!c->keep)
        return c->p->objective(c->ctx, q, f, g, NULL, c->project);
    int rc = c->p->objective(c->ctx, q, f, c->g, NULL, c->project);
    c->valid = rc == 0;
    c->E = *f;
    memcpy(c->x, q, sizeof(double) * (size_t)c->p->r);
    if (g && !rc)
        memcpy(g, c->g, sizeof(double) * (size_t)c->p->r);
    return rc;
}

int crom_newton_solve(const crom_newton_problem *p, void *ctx, const crom_newton_work *w, double *q, double tol,
                      int max_iter, long step, int *iterations, double *residual, int *converged)
{
    int r = p->r, rc = 0, project = 0, gd = p->descent;
    crom_newton_memory *Q = !gd && p->wants_hessian ? w->memory : NULL;
    /* the line search's gradient; the kept evaluation's gradient and point;
     * the previous iterate and gradient and the two-loop's scratch */
    double *gt = crom_malloc(sizeof(double) * 6 * (size_t)r);
    if (!gt)
        return CROM_EINTERNAL;
    double *qp = gt + 3 * (size_t)r, *gp = qp + r, *v = gp + r;
    int have_prev = 0;
    ls_ctx lc = {p, ctx, 0, p->ls_gradient, 0, 0, gt + r, gt + 2 * (size_t)r};
    *iterations = 0;
    *residual = INFINITY;
    *converged = 0;
    for (int it = 0; it < max_iter && !rc;) {
        double E;
        /* fresh: a Hessian computed at this iteration (not reused) */
        int fresh = !gd && (!p->wants_hessian || p->wants_hessian(ctx, it));
        if (!fresh && lc.valid && lc.project == project && !memcmp(lc.x, q, sizeof(double) * (size_t)r)) {
            E = lc.E; /* the line search's accepted evaluation */
            memcpy(w->g, lc.g, sizeof(double) * (size_t)r);
        } else if ((rc = p->objective(ctx, q, &E, w->g, fresh ? w->H : NULL, project))) {
            break;
        }
        lc.valid = 0;
        if (Q) {
            if (fresh)
                crom_newton_memory_reset(Q); /* the fresh Hessian holds the curvature */
            else if (have_prev)
                memory_push(Q, q, qp, w->g, gp);
        }
        have_prev = 0;
        int dr = Q && Q->k ? memory_direction(p, ctx, Q, it, project, q, w->g, v, w->d)
                           : p->direction(ctx, it, project, q, w->g, fresh ? w->H : NULL, w->d);
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
        lc.project = project;
        double alpha = crom_linesearch(ls_eval, &lc, (size_t)r, q, w->d, E, slope, 64 * DBL_EPSILON * scale,
                                       -slope < 1e-10 * scale, w->qt, gt, NULL);
        if (alpha == 0) {
            lc.valid = 0;
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
        if (Q) {
            memcpy(qp, q, sizeof(double) * (size_t)r);
            memcpy(gp, w->g, sizeof(double) * (size_t)r);
            have_prev = 1;
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
